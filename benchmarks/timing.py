"""Timing helper shared by the benchmark scripts (run as ``python benchmarks/<script>.py``)."""
import time


def best_of(fn, repeat=3):
    """Best wall time of ``repeat`` calls of ``fn`` (the machine is shared: the minimum is
    the least disturbed run) and the result of the last call: ``(seconds, result)``."""
    times, res = [], None
    for _ in range(max(1, repeat)):
        t = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t)
    return min(times), res


def best_seconds(fn, repeat=3):
    """Best wall time of ``repeat`` calls of ``fn``, in seconds."""
    return best_of(fn, repeat)[0]


def annotate_words(words, lengths, model, *, keyframes=None):
    """Segments of concatenated documents, in memory: the keyframe preselection on an index of
    just these documents when the model preselects (``keyframes``), then the annotation chain."""
    from mocapdb.annotation import annotate, preselection_for

    pre = preselection_for(words, lengths, model, keyframes)
    return annotate(words, model, doc_lengths=lengths, preselection=pre, keep_hits=False).segments


def stored_words(con):
    """(words, lengths) of every motion of a database, in motion-id order."""
    from mocapdb.storage.motions import motion_documents

    docs = motion_documents(con)
    return docs.words, docs.lengths


def model_dir(path, name=None):
    """A model exported as Parquet files (benchmarks/train_default_model.py's format), renamed if ``name``."""
    import dataclasses
    from pathlib import Path

    import pyarrow.parquet as pq

    from mocapdb.storage.model_store import MODEL_TABLES, model_from_tables

    model = model_from_tables({p.stem: pq.read_table(p) for p in Path(path).glob("*.parquet")})
    return model if name is None else dataclasses.replace(model, name=name)


def model_at(rev, name=None):
    """The shipped default model as committed at git revision ``rev`` (e.g. the previous default)."""
    import dataclasses
    import io
    import subprocess
    from pathlib import Path

    import pyarrow.parquet as pq

    from mocapdb.storage.model_store import MODEL_TABLES, model_from_tables

    repo = Path(__file__).resolve().parents[1]
    # the shipped models lived in mocapdb/models/ before they moved to mocapdb/shipped_models/
    folder = next(f for f in ("mocapdb/shipped_models", "mocapdb/models")
                  if subprocess.run(["git", "-C", str(repo), "cat-file", "-e", f"{rev}:{f}/default"],
                                    capture_output=True).returncode == 0)
    tables = {}
    for table in MODEL_TABLES:
        blob = subprocess.run(["git", "-C", str(repo), "show", f"{rev}:{folder}/default/{table}.parquet"],
                              capture_output=True)
        if blob.returncode == 0:  # a table newer than the revision (confidence_maps) is absent there
            tables[table] = pq.read_table(io.BytesIO(blob.stdout))
    model = model_from_tables(tables)
    return model if name is None else dataclasses.replace(model, name=name)
