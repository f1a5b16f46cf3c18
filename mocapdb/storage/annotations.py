"""Annotating stored motions (with the stored keyframe index) and storing the results.

:func:`annotate_documents` is the one annotation path of the database: the
Python API (``mocapdb.api.annotate``, ``evaluate``) and the SQL function
``annotate()`` both call it, with models and the index from the connection's
:class:`~mocapdb.storage.cache.ConnectionCache`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa

from mocapdb.annotation import SEGMENT_DTYPE, annotate, annotate_sweep, uses_keyframes, write_eaf
from mocapdb.errors import ParameterError
from mocapdb.storage.cache import UNKNOWN
from mocapdb.storage.names import file_in, file_stems
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction


def stored_preselection(cache, key, model, motion_ids, lengths, *, keyframes=None, index_version=UNKNOWN):
    """The ``preselection`` for stored motions: from the stored index when the model preselects, else None."""
    if not uses_keyframes(model, keyframes):
        return None
    return cache.preselection(key, model, motion_ids, lengths, version=index_version)


#: feature frames per piece when annotation reports progress (about a second of work each)
PROGRESS_FRAMES = 300_000


def annotate_documents(cache, key, model, words, lengths, motion_ids, *, tau=None, keyframes=None,
                       index_version=UNKNOWN, taus=None, progress=None, min_length=None, min_won=None,
                       margin=None):
    """Segments of stored motions (0-based inclusive, ``doc`` indexing ``motion_ids``).

    Parameters
    ----------
    cache : ConnectionCache
    key, model
        From :meth:`ConnectionCache.model`.
    words : (N,) uint64
        The motions' words, concatenated in the order of ``motion_ids``.
    lengths : (n,) int
    motion_ids : (n,) int
    tau : float, optional
        One hit threshold for every class (default: each class's τ).
    keyframes : bool, optional
        Keyframe preselection (default: when the model has keyframe queries).
    taus : sequence of float, optional
        Annotate once per τ instead (paper Fig. 8): returns a list.
    progress : callable, optional
        ``progress(n_motions_done, n_motions)``: the motions are then
        annotated in pieces of about :data:`PROGRESS_FRAMES` frames (whole
        motions; the segments are the same).
    min_length, min_won, margin : optional
        The segment filters (:func:`mocapdb.annotation.annotate`; default the model's).

    Returns
    -------
    ndarray of SEGMENT_DTYPE, or a list of them with ``taus``
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    if progress is not None:
        return _annotate_in_pieces(cache, key, model, words, lengths, motion_ids, tau=tau, keyframes=keyframes,
                                   index_version=index_version, taus=taus, progress=progress,
                                   min_length=min_length, min_won=min_won, margin=margin)
    pre = stored_preselection(cache, key, model, motion_ids, lengths, keyframes=keyframes,
                              index_version=index_version)
    if taus is not None:
        return annotate_sweep(words, model, taus, doc_lengths=lengths, preselection=pre, min_length=min_length,
                              min_won=min_won, margin=margin)
    return annotate(words, model, doc_lengths=lengths, preselection=pre, tau=tau, keep_hits=False,
                    min_length=min_length, min_won=min_won, margin=margin).segments


def _annotate_in_pieces(cache, key, model, words, lengths, motion_ids, *, progress, taus, **kwargs):
    """:func:`annotate_documents` piece by piece (whole documents), reporting progress."""
    ends = np.cumsum(lengths)
    n = len(lengths)
    progress(0, n)
    parts = []
    first = 0
    while first < n:
        base = ends[first - 1] if first else 0
        last = max(first + 1, int(np.searchsorted(ends, base + PROGRESS_FRAMES, side="right")))
        segs = annotate_documents(cache, key, model, words[base:ends[last - 1]], lengths[first:last],
                                  np.asarray(motion_ids)[first:last], taus=taus, **kwargs)
        for s in segs if taus is not None else [segs]:
            s["doc"] += first
        parts.append(segs)
        first = last
        progress(first, n)
    if taus is not None:
        return [np.concatenate([p[k] for p in parts]) if parts else np.empty(0, SEGMENT_DTYPE)
                for k in range(len(taus))]
    return np.concatenate(parts) if parts else np.empty(0, SEGMENT_DTYPE)


def store_annotations(con, table, motion_ids, *, model, tau, keyframes) -> None:
    """Replace the stored annotations of ``motion_ids`` under ``model`` (one transaction).

    ``table`` has the columns of :data:`mocapdb.annotation.SEGMENT_COLUMNS`.
    """
    with transaction(con):
        con.execute(statement("annotations.sql", "delete"), {"model": model, "ids": [int(i) for i in motion_ids]})
        with registered(con, mocap_new_annotations=table):
            con.execute(statement("annotations.sql", "insert"), {"model": model, "tau": tau, "keyframes": keyframes})


def motion_sources(con, motion_ids=None):
    """Name, absolute source path and native rate of motions, in motion-id order.

    Parameters
    ----------
    motion_ids : sequence of int, optional
        Default: every motion.

    Returns
    -------
    list of dict
        Keys ``motion_id``, ``name``, ``source_path``, ``source_fps``, ``n_source_frames``.
    """
    ids = None if motion_ids is None else [int(i) for i in motion_ids]
    cur = con.execute(statement("annotations.sql", "sources"), {"ids": ids})
    cols = [d[0] for d in cur.description]
    return [dict(zip(cols, r)) for r in cur.fetchall()]


#: file formats of :func:`export_segments`
EXPORT_FORMATS = ("parquet", "eaf")


def export_segments(con, table, out, *, format, motion_ids):
    """Write annotation segments as Parquet (one file) or ELAN (one ``.eaf`` per motion).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    table : pyarrow.Table
        Columns :data:`mocapdb.annotation.SEGMENT_COLUMNS`.
    out : str or Path
        Parquet: the file. ELAN: a ``.eaf`` file when one motion was
        annotated, else a directory (created) receiving ``<motion name>.eaf``
        per motion (the name made a safe file name, ``<name>_<motion_id>.eaf``
        where names repeat: :func:`mocapdb.storage.names.file_stems`).
    format : {"parquet", "eaf"}
    motion_ids : sequence of int
        The motions annotated (an ELAN file is written for each, also
        without segments).

    Returns
    -------
    list of Path
        The files written.
    """
    import pyarrow.parquet as pq

    if format not in EXPORT_FORMATS:
        raise ParameterError(f"format must be one of {', '.join(EXPORT_FORMATS)}, got {format!r}")
    out = Path(out)
    if format == "parquet":
        pq.write_table(table, out)
        return [out]
    sources = motion_sources(con, motion_ids)
    single = len(sources) == 1 and out.suffix.lower() == ".eaf"
    if not single:
        if out.suffix.lower() == ".eaf":
            raise ParameterError(f"out: {len(sources)} motions give one ELAN file each; give a directory, "
                                 f"not {out.name}")
        out.mkdir(parents=True, exist_ok=True)
    ids = table.column("motion_id").to_numpy()
    written = []
    for s, stem in zip(sources, file_stems(sources)):
        rows = table.filter(pa.array(ids == s["motion_id"]))
        path = out if single else file_in(out, stem, ".eaf")
        # the last 30 Hz frame may cover fewer native frames than 4: end at the recording's end
        end = np.minimum(rows.column("end_s").to_numpy(), s["n_source_frames"] / s["source_fps"])
        write_eaf(path, rows.column("label").to_pylist(), rows.column("start_s").to_numpy(), end,
                  media=s["source_path"], fps=s["source_fps"])
        written.append(path)
    return written


__all__ = ["annotate_documents", "stored_preselection", "store_annotations", "motion_sources", "export_segments",
           "EXPORT_FORMATS", "PROGRESS_FRAMES"]
