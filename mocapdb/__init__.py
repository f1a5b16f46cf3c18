"""mocapdb: annotate and retrieve motion capture data with SQL.

Implements Müller, Baak & Seidel, "Efficient and Robust Annotation of Motion
Capture Data" (SCA 2009) on DuckDB. The Python API mirrors the command line:

- :func:`connect` — open a database (tables + SQL functions)
- :func:`ingest` / :func:`delete_motions` — add and remove recordings
- :func:`read_motion` / :func:`motion_features` — a file to 24 joints to packed 30 Hz feature words
"""
from .database import connect
from .errors import MocapdbError, ParameterError, ParseError, SchemaError
from .features import motion_features, relational_features
from .ingest import delete_motions, ingest
from .readers import read_motion

__version__ = "0.1.0"

__all__ = [
    "connect", "ingest", "delete_motions", "read_motion", "motion_features", "relational_features",
    "MocapdbError", "ParameterError", "ParseError", "SchemaError",
]
