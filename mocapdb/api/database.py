"""The database and its recordings: open, ingest, delete, the keyframe index, Parquet in and out,
the canonical joints out, archives in place, moved files, other projects' label files."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from mocapdb.annotation import write_labels
from mocapdb.annotation.foreign_labels import read_label_file
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.readers import ReaderOptions
from mocapdb.readers import joint_map_template as readers_joint_map_template
from mocapdb.extension import connect as connect_database
from mocapdb.extension.native import extension_path as native_extension_path
from mocapdb.storage import attached, parquet, postings
from mocapdb.storage.ingest import IngestReport, delete_motions, ingest_files
from mocapdb.storage.joint_export import JointsExport
from mocapdb.storage.joint_export import export_joints as storage_export_joints
from mocapdb.storage.motions import documents_by_name, motions_to_delete, relocate_sources
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.schema import require_own_tables
from mocapdb.warmup import sample_files


#: seconds a read-write open waits while another process holds the file: a reader such as `mocapdb serve`
#: holds it only while it answers a request, so a writer starting then gets in a moment later instead of
#: failing; a writer still holding it after the wait is an error naming it (MOCAPDB_LOCK_WAIT overrides)
LOCK_WAIT = 5.0
LOCK_WAIT_ENV = "MOCAPDB_LOCK_WAIT"


def _lock_wait(lock_wait, read_only):
    if lock_wait is None:
        if read_only:  # a reader waiting for a writer would mostly wait for minutes (an ingest): no wait
            return 0.0
        lock_wait = os.environ.get(LOCK_WAIT_ENV) or LOCK_WAIT
    try:
        wait = float(lock_wait)
    except (TypeError, ValueError):
        wait = -1.0
    if not wait >= 0:
        raise ParameterError(f"lock_wait (or ${LOCK_WAIT_ENV}) must be a number of seconds >= 0, got {lock_wait!r}")
    return wait


def connect(path=":memory:", *, read_only: bool = False, create: bool = True, memory_limit=None, lock_wait=None):
    """Open (or create) a mocap database with the mocapdb SQL functions registered.

    Parameters
    ----------
    path : str or Path
        Database file; created with the schema, the keyframe index and the
        shipped models if it does not exist. ``":memory:"`` gives a
        throw-away database.
    read_only : bool, keyword-only
        Open the file read-only; the SQL functions work all the same (the
        shipped models then come from the package if the file lacks them).
    create : bool, keyword-only, default True
        False: a missing file is an error instead of a new, empty database
        (the commands that only read an archive use it, so a mistyped
        ``--db`` is caught).
    memory_limit : str, optional, keyword-only
        DuckDB's memory limit, e.g. ``"4GB"`` (default ``$MOCAPDB_MEMORY_LIMIT``
        or 512MB: mocapdb's own work runs a batch of motions at a time, and
        DuckDB spills to disk beyond its limit; see
        :data:`mocapdb.storage.schema.DEFAULT_MEMORY_LIMIT`).
    lock_wait : float, optional, keyword-only
        Seconds to wait while another process holds the file (DuckDB lets one
        process write it, and none open it meanwhile); default
        :data:`LOCK_WAIT` (``$MOCAPDB_LOCK_WAIT``) for a read-write open, so a
        writer waits for a reader such as ``mocapdb serve`` to finish its
        request, and none for a read-only open.

    Returns
    -------
    mocapdb.extension.Connection
        A ``duckdb.DuckDBPyConnection`` (every method works on it; the
        DuckDB object itself is its ``.duckdb``) on which ``annotate``,
        ``mt_distance``, ``keyframe_search`` and ``keyframe_search_words``
        are available, and on each of its cursors. A file may be opened any
        number of times in one process. Close it when done.

    Raises
    ------
    mocapdb.storage.schema.DatabaseLockedError
        Another process still holds the file after ``lock_wait`` seconds.
    SchemaError
        ``create=False`` (or ``read_only``) and the file does not exist.

    Examples
    --------
    >>> con = mocapdb.connect("archive.duckdb")
    >>> con.sql("SELECT name, n_frames FROM motions").fetchall()
    """
    if not create and str(path) != ":memory:" and not Path(path).exists():
        raise SchemaError(f"{path}: no such database file (a mistyped --db? `mocapdb ingest` or "
                          "`mocapdb import-features` create one)")
    return connect_database(path, read_only=read_only, memory_limit=memory_limit,
                            wait=_lock_wait(lock_wait, read_only))


def ingest(con, paths=(), *, sample=False, asf=None, joint_map=None, marker_map=None, marker_rules=None,
           body_model=None, progress=None, replace=False, max_decompressed=None, report=None) -> IngestReport:
    """Read recordings (files or folders, recursively), compute their features and store them.

    A broken file changes nothing and the others still go in; files already
    stored (same bytes) are skipped. See :func:`mocapdb.storage.ingest.ingest_files`.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    paths : iterable of str or Path
    sample : bool, keyword-only
        Also ingest the real recordings shipped with mocapdb
        (:func:`mocapdb.warmup.sample_files`; README "Data and credits").
    asf, joint_map, marker_map, marker_rules, body_model, max_decompressed : optional, keyword-only
        How files are read: the fields of one :class:`mocapdb.readers.ReaderOptions`
        value, checked here, before any file is read — the ASF of every AMC
        (default: found by the dataset conventions), a BVH joint map and a C3D
        marker map (TOML/JSON file or dict; docs/READING_FILES.md "Mapping files", "C3D marker
        maps"), the C3D marker rules (``"toolbox"``, the reference, or
        ``"anatomical"``), the SMPL-H/SMPL-X body model of AMASS ``.npz`` takes
        (a model file or a folder of them, chosen by family and gender;
        default: the generic rest skeleton shipped with mocapdb; docs/READING_FILES.md
        "AMASS"), the bytes a compressed file or zip member may decompress to
        (``"2GiB"``; default ``MOCAPDB_MAX_DECOMPRESSED``, else 512 MiB).
        ``ray_annotate`` takes the same and reads the same.
    progress : callable, optional, keyword-only
        ``progress(n_files_done, n_files, path)`` once per file.
    replace : bool, keyword-only
        Read files already stored (same bytes) again and replace their
        motions, e.g. after correcting ``joint_map``; default: skip them.
    report : str or Path, optional, keyword-only
        Write the call's rows of the ``ingest_log`` table to this file as CSV
        (``path, member, outcome, reason, notes, motion_id, logged_at, run_id,
        command``; NULL as an empty field), also when the call fails.

    Returns
    -------
    IngestReport
        Ingested, skipped, failed and unsupported files, unreadable folder
        entries, and the readers' notes on what they decided per file;
        ``failed`` lists every file that was not stored, with the reason
        (the command exits 1 when it is not empty). Every file's row is in
        the table ``ingest_log`` (``run_id`` = the report's ``run_id``).
    """
    require_own_tables(con, "ingest")
    paths = [*paths, *(sample_files() if sample else [])]
    options = ReaderOptions(asf=asf, joint_map=joint_map, marker_map=marker_map, marker_rules=marker_rules,
                            body_model=body_model, max_decompressed=max_decompressed)
    return ingest_files(con, paths, options=options, progress=progress, replace=replace, log_csv=report)


def extension_path() -> Path:
    """The absolute path of the native DuckDB extension ``mocapdb.duckdb_extension``, which any DuckDB
    client loads with ``LOAD 'PATH'`` (unsigned: ``duckdb -unsigned``; docs/EXTENSION.md).

    Raises
    ------
    mocapdb.errors.MocapdbError
        When this install has no native extension, saying why (no C compiler at install time, …).
    """
    return native_extension_path()


def joint_map_template(path) -> str:
    """A ready-to-edit TOML joint map for a BVH file (``ingest(joint_map=…)``, ``--joint-map``).

    The canonical joints the automatic mapping places are filled in; the
    others are left as comments to fill, and the file's joints are listed.
    See :func:`mocapdb.readers.joint_map_template`.
    """
    return readers_joint_map_template(path)


@dataclasses.dataclass
class DeleteReport:
    """What :func:`delete` did: ``deleted`` ``(motion_id, name, format, source_path)`` per motion removed,
    ``absent`` the ids and names that were not in the database (nothing to delete, no error)."""

    deleted: list
    absent: list


def delete(con, motions, *, all_named=False) -> DeleteReport:
    """Delete motions (ids or names) with their features, postings and annotations (one transaction).

    Deleting what is not there is no error (a delete run again after it
    committed): it is reported in ``absent``.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : iterable of int or str
        Motion ids or names.
    all_named : bool, keyword-only
        A name that names several motions (an AMC and a C3D of one take)
        deletes all of them; without it that is an error listing them, and
        nothing is deleted.

    Returns
    -------
    DeleteReport
    """
    require_own_tables(con, "delete")
    rows, absent = motions_to_delete(con, motions, all_named=all_named)
    delete_motions(con, [r[0] for r in rows])
    return DeleteReport(rows, absent)


def create_index(con) -> int:
    """(Re)build the keyframe index (schema ``mocap_index``) from the features.

    Returns
    -------
    int
        The number of postings.
    """
    require_own_tables(con, "create-index")
    return postings.create_index(con)


def drop_index(con) -> None:
    """Remove the keyframe index (ingest and delete then stop maintaining it)."""
    require_own_tables(con, "drop-index")
    postings.drop_index(con)


def export_features(con, directory, *, overwrite=False) -> int:
    """Write motions and features to Parquet, partitioned by motion (``DIR/features/motion_id=N/``).

    Returns
    -------
    int
        The number of motions written.
    """
    return parquet.export_features(con, directory, overwrite=overwrite)


def export_joints(con, motions, out, *, all=False, format="npz", where=None, label=None, model=DEFAULT_MODEL,
                  unit=None, scale=None, progress=None) -> JointsExport:
    """Write the 24 canonical joints of motions as files for other tools (fairmotion, Blender, aitviewer).

    Each motion's source is re-read with the options it was ingested with
    (as the viewer does): its joints at the recording's own rate, in metres,
    Y up, in ``JOINT_NAMES`` order. A BVH file declares no unit: the reader
    takes the one giving the legs an adult's length (or CMU's 1/0.45 inch
    for CMU-named bones when none does), which ``unit`` or ``scale``
    overrides. See :func:`mocapdb.storage.joint_export.export_joints`,
    :mod:`mocapdb.writers.joints_write` and :mod:`mocapdb.bodies.units`.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : iterable of int or str, or None
        Motion ids or names; None (or empty) with ``all``, ``where`` or
        ``label``: every motion they keep.
    out : str or Path
        The file (one motion, ``out`` ending in ``.<format>``; its folder is
        created), else a directory (created) of ``<motion name>.<format>``
        files and ``units.json`` (each file's source unit and how it was known).
    format : {"npz", "csv", "bvh"}, keyword-only
        ``npz``: ``joints`` (frames × 24 × 3), ``fps``, ``joint_names``,
        ``source_unit``, ``metres_per_source_unit``; ``csv``: a row per
        frame (``frame``, ``time``, ``<joint>_x/_y/_z``); ``bvh``: a skeleton
        of the canonical joints that mocapdb (and other tools) read back.
    all : bool, keyword-only
        Every motion (that ``where`` and ``label`` keep): said, so that no
        motions given by mistake never exports a whole archive.
    where : str, optional, keyword-only
        A SQL condition over ``motions``' columns (``"format = 'bvh'"``).
    label : str, optional, keyword-only
        Motions with a stored segment of this label (of ``model``).
    model : str, keyword-only
    unit : {"m", "cm", "mm", "inch", "cmu"}, optional, keyword-only
    scale : float, optional, keyword-only
        Metres per unit of BVH sources (instead of ``unit``).
    progress : callable, optional, keyword-only
        ``progress(n_done, n_motions, name)`` once per motion.

    Returns
    -------
    mocapdb.storage.joint_export.JointsExport
        ``written`` ``(motion_id, name, path, source unit)``, ``failed``
        ``(motion_id, name, reason)``.
    """
    motions = list(motions or ()) or None
    if motions is None and not all and where is None and label is None:
        raise ParameterError("give motions (ids or names), all=True, where or label")
    if motions is not None and all:
        raise ParameterError("give motions or all=True, not both")
    return storage_export_joints(con, motions, out, format=format, where=where, label=label, model=model, unit=unit,
                                 scale=scale, progress=progress)


def import_features(con, directory):
    """Load motions and features written by :func:`export_features` or :func:`ray_annotate` (motions
    already present are kept).

    A batch of motions at a time, each checked to be exactly its frames 1 … n:
    an incomplete motion is refused and named, the others are imported; an
    unfinished archive (an export or a Ray run that was stopped) is refused.
    See :func:`mocapdb.storage.parquet.import_features`.

    Returns
    -------
    mocapdb.storage.parquet.ImportReport
        ``imported`` maps archive motion ids to the new ones; ``failed`` names the refused motions;
        ``run_id`` names the call's rows of the ``ingest_log`` table (one per motion, under its
        source file, and one per file of a ``ray_annotate`` archive's ``errors`` dataset).
    """
    require_own_tables(con, "import-features")
    return parquet.import_features(con, directory)


def attach(con, directory) -> int:
    """Make a new database a set of views over a ``ray_annotate`` archive: queryable in place.

    ``motions``, ``features``, ``annotations`` and the keyframe index become
    views of the archive's Parquet (nothing is copied); every SQL function
    (``annotate()``, ``keyframe_search()``, ``mt_distance()``, …) and every
    reading command works on them, a batch of motions at a time. The views
    name the archive by its absolute path. See :func:`mocapdb.storage.attached.attach`.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
        A database without motions of its own (a new one), or one attached before.
    directory : str or Path
        A finished ``ray_annotate`` archive (with its ``manifest.json``).

    Returns
    -------
    int
        The number of motions attached.
    """
    return attached.attach(con, directory)


def relocate(con, old_prefix, new_prefix):
    """Repoint stored source paths after the recordings moved (``view`` and figures re-read them).

    Every motion whose source file (or ASF skeleton) lies under
    ``old_prefix`` is repointed to the same place under ``new_prefix``,
    when the file there has the bytes that were ingested. See
    :func:`mocapdb.storage.motions.relocate_sources`.

    Returns
    -------
    moved : list of (motion_id, old path, new path)
    refused : list of (motion_id, new path, reason)
    """
    return relocate_sources(con, old_prefix, new_prefix)


def convert_labels(con, path, *, out=None, document=None, document_column="document", label_column="label",
                   start_column="start_frame", end_column="end_frame", names=None, frames_per_label=None,
                   fps=None):
    """Read another project's label file as label rows, and write them as a label CSV.

    Two shapes (:mod:`mocapdb.annotation.foreign_labels`): a segment table
    whose columns have other names (the CMU 86_09 segmentation:
    ``document_column="trial"``), or per-frame label ids, one per
    ``frames_per_label`` frames, named by a ``names`` file (mocap6:
    ``frames_per_label=12``, ``names="action_names.txt"``). The result is
    what ``train(labels=…)``, ``evaluate(truth=…)`` and ``view(truth=…)`` read.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection or None
        When the document is ingested, per-frame labels end at its last frame
        (the last block may be partial). Optional.
    path : str or Path
    out : str or Path, optional, keyword-only
        Write the rows here as a label CSV.
    document : str, optional, keyword-only
        Per-frame labels: the document (default: the file's stem). A segment
        table: keep only this document's rows.
    document_column, label_column, start_column, end_column : str, keyword-only
        A segment table's header names of the four values.
    names : str or Path, optional, keyword-only
        Per-frame labels: the file naming the ids (``<id> <name>`` lines).
    frames_per_label : int, optional, keyword-only
        Per-frame labels: frames per id (1: one per frame). Giving this or
        ``names`` reads per-frame labels.
    fps : float, optional, keyword-only
        The rate of the file's frames when it is not the recording's own
        (written as the ``fps`` column, :func:`mocapdb.annotation.read_labels`).

    Returns
    -------
    ndarray of mocapdb.annotation.LABEL_DTYPE
        Frames 1-based inclusive, at the file's rate.
    """
    per_frame = frames_per_label is not None or names is not None
    length = None
    if per_frame and con is not None:
        try:  # an ingested document: the labels end at its last frame
            docs = documents_by_name(con, [Path(path).stem if document is None else document])
            length = (int(docs.n_source_frames[0]), float(docs.source_fps[0]))
        except SchemaError:
            pass
    rows = read_label_file(path, document=document, document_column=document_column, label_column=label_column,
                           start_column=start_column, end_column=end_column, names=names,
                           frames_per_label=frames_per_label, fps=fps, length=length)
    if out is not None:
        write_labels(out, rows, fps=fps)
    return rows
