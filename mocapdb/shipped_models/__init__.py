"""Package data, no code: the models shipped with mocapdb (``default/`` and ``toolbox/``, the rows of
the model tables as Parquet, read by :mod:`mocapdb.storage.model_store`), the designed class and keyframe
definitions (``classes/*.toml``) and the class → label mappings (``*_labels.csv``)."""
