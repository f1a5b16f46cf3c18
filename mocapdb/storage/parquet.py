"""Moving features between a mocap database and Parquet files.

Layout written by :func:`export_features` (DuckDB reads it in place)::

    DIR/motions.parquet                       one row per motion (the motions table)
    DIR/features/motion_id=<id>/*.parquet     frame, bits of that motion (hive partitioning)

:func:`import_features` also reads the archives that ``mocapdb.distributed``
writes on a Ray cluster, whose datasets have the columns of the tables
(:func:`table_schemas`)::

    DIR/motions/*.parquet                              the motions table
    DIR/features/motion_bucket=<k>/*.parquet           motion_id, frame, bits
    DIR/annotations/motion_bucket=<k>/*.parquet        the annotations table (imported too)
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mocapdb.errors import ParameterError
from mocapdb.storage.names import check_motion_names
from mocapdb.storage.postings import index_motions
from mocapdb.storage.schema import open_database
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction


def _sql(name):
    return statement("parquet.sql", name)


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
    return con.execute(statement("motions.sql", "count")).fetchall()[0][0]


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


#: the DuckDB table each Parquet dataset of an archive mirrors (:func:`table_schemas`)
ARCHIVE_TABLES = ("motions", "features", "postings", "annotations")


def table_schemas() -> dict:
    """The Arrow schemas of the tables an archive on Parquet mirrors, read from DuckDB.

    Returns
    -------
    dict of str to pyarrow.Schema
        For each of :data:`ARCHIVE_TABLES`: the columns and types of the table
        (``postings``: ``mocap_index.postings``) as ``sql/schema.sql`` and
        ``sql/index.sql`` create it.
    """
    con = open_database(":memory:")
    try:
        return {t: con.sql(_sql(f"empty_{t}")).to_arrow_table().schema for t in ARCHIVE_TABLES}
    finally:
        con.close()


def _motions_file(d: Path):
    """The motions of an export (one file) or of a Ray archive (a folder of parts)."""
    for f in (d / "motions.parquet", d / "motions"):
        if f.exists():
            return f
    raise ParameterError(f"directory: {str(d)!r} has no motions.parquet or motions/ (written by "
                         "export_features or ray_annotate)")


def import_features(con, directory) -> dict[int, int]:
    """Load an export, or an archive written by ``ray_annotate``, back (one transaction):
    motions not yet present (by sha256) get new ids.

    The features of the new motions are imported (and indexed, when the
    keyframe index exists) and, from a ``ray_annotate`` archive, their
    annotations.

    Returns
    -------
    dict
        Exported motion id → motion id in this database, for the motions added.
    """
    d = Path(directory)
    motions = pq.read_table(_motions_file(d))
    check_motion_names(motions.column("name").to_pylist(), source=d)
    stored = {(a, b) for _, a, b in con.execute(statement("motions.sql", "stored_keys")).fetchall()}
    keys = zip(motions.column("sha256").to_pylist(), motions.column("skeleton_sha256").to_pylist())
    new = motions.filter(pa.array([k not in stored for k in keys], pa.bool_()))
    if new.num_rows == 0:
        return {}
    new = new.append_column("ord", pa.array(np.arange(new.num_rows, dtype=np.int32)))
    old_ids = new.column("motion_id").to_pylist()
    with transaction(con):
        with registered(con, mocap_new_motions=new):
            new_ids = [r[0] for r in con.execute(_sql("import_motions")).fetchall()]
        mapping = dict(zip(old_ids, new_ids))
        id_map = pa.table({"old": pa.array(old_ids, pa.int32()), "new": pa.array(new_ids, pa.int32())})
        with registered(con, mocap_id_map=id_map):
            con.execute(_sql("import_features"), {"features": str(d / "features" / "*" / "*.parquet")})
            if (d / "annotations").is_dir():
                con.execute(_sql("import_annotations"), {"annotations": str(d / "annotations" / "*" / "*.parquet")})
        rows = con.execute(_sql("words_of_motions"), {"ids": new_ids}).fetchnumpy()
        ids, starts = np.unique(rows["motion_id"], return_index=True)
        index_motions(con, dict(zip(ids.tolist(), np.split(np.asarray(rows["bits"], np.uint64), starts[1:]))))
    return mapping


__all__ = ["export_features", "import_features", "features_sql", "table_schemas", "ARCHIVE_TABLES"]
