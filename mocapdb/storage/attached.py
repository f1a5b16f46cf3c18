"""A database whose motions, features, annotations and keyframe index are views over a Ray archive.

``ray_annotate`` writes an archive as Parquet datasets with the columns of the
database tables (:mod:`mocapdb.distributed.layout`). :func:`attach` turns an
empty mocapdb database into views over such an archive: ``motions``,
``features``, ``annotations`` and ``mocap_index.postings`` read the Parquet
files in place, and ``mocap_index.state.version`` is a hash of the archive's
manifest (a new run of the archive is a new version). Every SQL function then
works as on an imported database — it reads a batch of motions at a time
through the same statements — without copying the archive; the models stay
ordinary tables (a model can be trained or defined in the view database).
The views name the archive by its absolute path, so any DuckDB client can
open the file and query them. Writing motions (ingest, import, delete,
stored annotations, the index) needs a database of its own: the API's
functions that would say so (:func:`mocapdb.storage.schema.require_own_tables`).
"""
from __future__ import annotations

import re
from pathlib import Path

from mocapdb.errors import ParameterError
from mocapdb.storage.parquet import MANIFEST, Archive, check_frames_per_motion
from mocapdb.storage.schema import attached_archive, require_own_tables
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import transaction

#: characters DuckDB's file globs would read as patterns: an archive path must not hold them
_GLOB = re.compile(r"[*?\[\]{}]")


def _sql(name, **literals):
    return statement("attached.sql", name, literals=literals or None)


def attach(con, directory) -> int:
    """Make an empty mocapdb database a set of views over a finished ``ray_annotate`` archive.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
        A mocapdb database without motions or annotations (a new one), or one
        attached before (it is attached to ``directory`` instead).
    directory : str or Path
        The archive (``ray_annotate --out``): finished, i.e. with its manifest.

    Returns
    -------
    int
        The number of motions of the archive.

    Raises
    ------
    ParameterError
        Not a finished ``ray_annotate`` archive, one whose parts differ from its
        manifest or do not hold each motion's frames 1 … n (named, in one line),
        a path DuckDB would read as a glob pattern, or a database that holds
        motions of its own.
    """
    root = Path(directory).resolve()
    # refuses exports, unfinished runs and parts missing, extra, changed or unreadable, naming why
    archive = Archive.open(root, whole=True)
    if archive.kind != "ray":
        raise ParameterError(f"directory: {str(root)!r} is an export-features folder; attach reads a ray-annotate "
                             "archive (with motions/, features/, postings/, annotations/ and its manifest); load an "
                             "export with import-features")
    if _GLOB.search(str(root)):
        raise ParameterError(f"directory: {str(root)!r} holds a character DuckDB reads as a file pattern "
                             "(* ? [ ] { }); move or link the archive to a plain path")
    check_frames_per_motion(con, archive)   # the views will read the parts as they are
    with transaction(con):
        if attached_archive(con) is None:
            own = con.execute(_sql("own_rows")).fetchall()[0][0]
            if own:
                raise ParameterError(f"this database holds {own} motion and annotation rows of its own; attach an "
                                     "archive to a new database (mocapdb --db NEW.duckdb attach DIR)")
            con.execute(_sql("drop_tables"))
        con.execute(_sql("views", archive=str(root)))
    return archive.motions.num_rows


__all__ = ["attach", "attached_archive", "require_own_tables", "MANIFEST"]
