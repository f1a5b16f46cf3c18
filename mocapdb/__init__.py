"""mocapdb: annotate and retrieve motion capture data with SQL.

Implements Müller, Baak & Seidel, "Efficient and Robust Annotation of Motion
Capture Data" (SCA 2009) on DuckDB. The sub-packages follow the pipeline
(docs/ARCHITECTURE.md): :mod:`~mocapdb.bodies` → :mod:`~mocapdb.readers` → :mod:`~mocapdb.features`
→ :mod:`~mocapdb.templates` → :mod:`~mocapdb.keyframes` →
:mod:`~mocapdb.annotation` → :mod:`~mocapdb.learning` →
:mod:`~mocapdb.retrieval` → :mod:`~mocapdb.evaluation`; :mod:`~mocapdb.storage` and
:mod:`~mocapdb.extension` (the SQL functions) and :mod:`~mocapdb.viewer` (HTML
pages) below :mod:`~mocapdb.api`, which the command line mirrors one to one. The most used functions are here:

- :func:`connect` — open a database (tables, shipped models, SQL functions)
- :func:`ingest` / :func:`delete` — add and remove recordings
- :func:`annotate` — label motions with a model
- :func:`view` — a motion's skeleton and labels as a self-contained HTML page
- :func:`similar` — the stretches of the archive most like a stretch of a motion
- :func:`export_joints` — motions' 24 joints as npz, csv or bvh files for other tools
- :func:`read_motion` / :func:`motion_features` — a file to 24 joints to packed 30 Hz feature words
"""
import os as _os

# pip installs the top-level extension/ and sql/ of the repository as
# mocapdb.extension and mocapdb.sql; a source checkout on sys.path (a Ray worker
# started from it, ``python -m mocapdb.cli`` run there) finds them beside the package
if not _os.path.isdir(_os.path.join(__path__[0], "extension")):
    _root = _os.path.dirname(_os.path.abspath(__path__[0]))
    if _os.path.isfile(_os.path.join(_root, "extension", "__init__.py")):
        __path__.append(_root)

#: the public names and the modules that hold them, imported on first use (PEP 562): ``import mocapdb``
#: stays light (a client that only wants ``read_motion`` or the errors does not load the database, the
#: SQL functions and the annotation kernels), as scipy and scikit-image load their parts lazily
_LAZY = {
    **dict.fromkeys(["annotate", "connect", "delete", "evaluate", "export_joints", "ingest", "similar", "train",
                     "view"], "mocapdb.api"),
    **dict.fromkeys(["MocapdbError", "ParameterError", "ParseError", "SchemaError"], "mocapdb.errors"),
    **dict.fromkeys(["motion_features", "relational_features"], "mocapdb.features"),
    "read_motion": "mocapdb.readers",
}


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'mocapdb' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__():
    return sorted({*globals(), *_LAZY})


__version__ = "0.3.0"

__all__ = [
    "connect", "ingest", "delete", "annotate", "train", "evaluate", "view", "similar", "export_joints", "read_motion",
    "motion_features",
    "relational_features", "MocapdbError", "ParameterError", "ParseError", "SchemaError",
]
