"""Where the native DuckDB extension is: ``mocapdb.duckdb_extension``, the SQL functions written
in C against DuckDB's stable C extension API (``extension/src``, docs/EXTENSION.md).

``pip install .`` compiles it with the system C compiler into this package
(``extension/native_build.py``, run by setup.py); where that failed — no C compiler, another
platform — the reason is written beside it instead, and :func:`extension_path` says so.
"""
from __future__ import annotations

from pathlib import Path

from mocapdb.errors import MocapdbError

HERE = Path(__file__).resolve().parent
#: the binary's name (LOAD derives its entry point, mocapdb_init_c_api, from it) and the file
#: that says why it was not built; as in extension/native_build.py
BINARY_NAME = "mocapdb.duckdb_extension"
MISSING_NAME = "mocapdb.duckdb_extension.missing"


class NativeExtensionMissing(MocapdbError):
    """The native extension was not built with this install (the message says why)."""


def extension_path() -> Path:
    """The absolute path of ``mocapdb.duckdb_extension``.

    Raises
    ------
    NativeExtensionMissing
        When the install did not build it, with the reason the build gave.
    """
    path = HERE / BINARY_NAME
    if path.is_file():
        return path
    missing = HERE / MISSING_NAME
    why = missing.read_text().strip() if missing.is_file() else (
        "it was not built with this install; reinstall with `pip install .` (or `pip install -e .`) on a "
        "machine with gcc")
    raise NativeExtensionMissing(f"the native DuckDB extension is missing: {why}")


__all__ = ["BINARY_NAME", "MISSING_NAME", "NativeExtensionMissing", "extension_path"]
