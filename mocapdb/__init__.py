"""mocapdb: annotate and retrieve motion capture data with SQL.

Implements Müller, Baak & Seidel, "Efficient and Robust Annotation of Motion
Capture Data" (SCA 2009) on DuckDB. The Python API mirrors the command line:

- :func:`connect` — open a database (tables + SQL functions)
- :func:`ingest` / :func:`delete_motions` — add and remove recordings
- :func:`read_motion` / :func:`motion_features` — a file to 24 joints to packed 30 Hz feature words
"""
import os as _os

# extension/ and sql/ sit at the top of the repository (the product layout) and
# install as the subpackages mocapdb.extension and mocapdb.sql. When mocapdb is
# imported from a source checkout instead (e.g. `python -m pytest` in the repo
# root puts the checkout first on sys.path), find them beside this package.
_top = _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
if _os.path.isfile(_os.path.join(_top, "extension", "udfs.py")) and \
        _os.path.isfile(_os.path.join(_top, "sql", "schema.sql")):
    __path__.append(_top)

from .database import connect  # noqa: E402
from .errors import MocapdbError, ParameterError, ParseError, SchemaError  # noqa: E402
from .features import motion_features, relational_features  # noqa: E402
from .ingest import delete_motions, ingest  # noqa: E402
from .readers import read_motion  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "connect", "ingest", "delete_motions", "read_motion", "motion_features", "relational_features",
    "MocapdbError", "ParameterError", "ParseError", "SchemaError",
]
