"""Moving features between a mocap database and Parquet files.

Layout written by :func:`export_features` (DuckDB reads it in place)::

    DIR/motions.parquet                       one row per motion (the motions table)
    DIR/features/motion_id=<id>/*.parquet     frame, bits of that motion (hive partitioning)
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa

from .errors import ParameterError


def _quote(path: Path) -> str:
    return "'" + str(path).replace("'", "''") + "'"


def export_features(con, directory, *, overwrite: bool = False) -> int:
    """Write ``motions`` and ``features`` to Parquet, partitioned by motion.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    directory : str or Path
        Target folder; must be empty or absent unless ``overwrite``.
    overwrite : bool, keyword-only

    Returns
    -------
    int
        Number of motions written.
    """
    d = Path(directory)
    if d.exists() and any(d.iterdir()) and not overwrite:
        raise ParameterError(f"directory: {str(d)!r} is not empty; pass overwrite=True (--overwrite)")
    d.mkdir(parents=True, exist_ok=True)
    con.execute(f"COPY (SELECT * FROM motions ORDER BY motion_id) TO {_quote(d / 'motions.parquet')} (FORMAT parquet)")
    con.execute(
        f"COPY (SELECT motion_id, frame, bits FROM features ORDER BY motion_id, frame) "
        f"TO {_quote(d / 'features')} (FORMAT parquet, PARTITION_BY (motion_id), OVERWRITE_OR_IGNORE)")
    return con.execute("SELECT count(*) FROM motions").fetchall()[0][0]


def features_sql(directory) -> str:
    """SQL text of a query over exported features in place: ``(motion_id, frame, bits)``.

    Usable as a subquery or view, e.g.
    ``CREATE VIEW archive AS <features_sql(DIR)>``: DuckDB reads the Parquet
    files without loading them.
    """
    d = Path(directory)
    if not (d / "features").is_dir():
        raise ParameterError(f"directory: {str(d)!r} has no features/ folder (written by export_features)")
    return (f"SELECT motion_id::INTEGER AS motion_id, frame, bits "
            f"FROM read_parquet({_quote(d / 'features' / '*' / '*.parquet')}, hive_partitioning = true)")


def import_features(con, directory) -> dict[int, int]:
    """Load an export back: motions not yet present (by sha256) get new ids.

    Returns
    -------
    dict
        Exported motion id → motion id in this database, for the motions added.
    """
    d = Path(directory)
    if not (d / "motions.parquet").is_file():
        raise ParameterError(f"directory: {str(d)!r} has no motions.parquet (written by export_features)")
    from .postings import index_exists, insert_postings

    mapping = {}
    motions = con.sql(f"SELECT * FROM read_parquet({_quote(d / 'motions.parquet')})")
    cols = motions.columns
    rows = motions.fetchall()
    feats = features_sql(d)
    con.begin()
    try:
        for row in rows:
            rec = dict(zip(cols, row))
            hit = con.execute(
                "SELECT motion_id FROM motions WHERE sha256 = ? AND skeleton_sha256 IS NOT DISTINCT FROM ?",
                [rec["sha256"], rec["skeleton_sha256"]]).fetchall()
            if hit:
                continue
            old = rec.pop("motion_id")
            names = ", ".join(rec)
            new = con.execute(
                f"INSERT INTO motions ({names}) VALUES ({', '.join('?' * len(rec))}) RETURNING motion_id",
                list(rec.values())).fetchall()[0][0]
            mapping[old] = new
        if mapping:
            con.register("_mocapdb_id_map", pa.table({"old": list(mapping), "new": list(mapping.values())}))
            try:
                con.execute(
                    f"INSERT INTO features SELECT m.new, f.frame, f.bits FROM ({feats}) f "
                    "JOIN _mocapdb_id_map m ON f.motion_id = m.old ORDER BY m.new, f.frame")
            finally:
                con.unregister("_mocapdb_id_map")
            if index_exists(con):
                words = {}
                for mid in mapping.values():
                    w = con.execute("SELECT bits FROM features WHERE motion_id = ? ORDER BY frame", [mid]).fetchnumpy()
                    words[mid] = np.asarray(w["bits"], dtype=np.uint64)
                insert_postings(con, words)
        con.commit()
    except BaseException:
        con.rollback()
        raise
    return mapping


__all__ = ["export_features", "import_features", "features_sql"]
