"""The keyframe index as DuckDB tables (schema ``mocap_index``), kept in step with ``features``."""
from __future__ import annotations

INDEX_SCHEMA = "mocap_index"


def index_exists(con) -> bool:
    """Whether the database has the keyframe index tables."""
    return bool(con.execute(
        "SELECT count(*) FROM duckdb_tables() WHERE schema_name = ? AND table_name = 'postings'",
        [INDEX_SCHEMA]).fetchall()[0][0])


def insert_postings(con, words_by_motion) -> None:
    raise NotImplementedError
