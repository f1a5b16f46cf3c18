"""Annotating stored motions (with the stored keyframe index) and storing the results.

:func:`annotate_documents` is the one annotation path of the database, with
models and the keyframe index from the connection's
:class:`~mocapdb.storage.cache.ConnectionCache`; :func:`annotate_motions`
runs it over stored motions a batch at a time, so that the memory of the
Python API (``mocapdb.api.annotate``) and of the SQL function ``annotate()``
does not grow with the archive, and a motion that fails is reported on its
own.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa

from mocapdb.annotation import SEGMENT_DTYPE, annotate, annotate_sweep, uses_keyframes, write_eaf
from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.features import FEATURE_RATE
from mocapdb.storage.cache import UNKNOWN
from mocapdb.storage.names import file_in, file_stems
from mocapdb.storage.motions import BATCH_FRAMES, iter_documents
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction


def stored_preselection(cache, key, model, motion_ids, lengths, *, keyframes=None, index_version=UNKNOWN):
    """The ``preselection`` for stored motions: from the stored index when the model preselects, else None."""
    if not uses_keyframes(model, keyframes):
        return None
    return cache.preselection(key, model, motion_ids, lengths, version=index_version)


def annotate_documents(cache, key, model, words, lengths, motion_ids, *, tau=None, keyframes=None,
                       index_version=UNKNOWN, taus=None, min_length=None, min_won=None, margin=None):
    """Segments of stored motions given with their words (0-based inclusive, ``doc`` indexing ``motion_ids``).

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
        Keyframe preselection from the motions' stored postings (default: when
        the model has keyframe queries).
    taus : sequence of float, optional
        Annotate once per τ instead (paper Fig. 8): returns a list.
    min_length, min_won, margin : optional
        The segment filters (:func:`mocapdb.annotation.annotate`; default the model's).

    Returns
    -------
    ndarray of SEGMENT_DTYPE, or a list of them with ``taus``
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    pre = stored_preselection(cache, key, model, motion_ids, lengths, keyframes=keyframes,
                              index_version=index_version)
    if taus is not None:
        return annotate_sweep(words, model, taus, doc_lengths=lengths, preselection=pre, min_length=min_length,
                              min_won=min_won, margin=margin)
    return annotate(words, model, doc_lengths=lengths, preselection=pre, tau=tau, keep_hits=False,
                    min_length=min_length, min_won=min_won, margin=margin).segments


#: feature frames per batch when annotation reports progress (about a second of work each)
PROGRESS_FRAMES = 300_000


def annotate_motions(con, cache, key, model, motion_ids=None, *, max_frames=BATCH_FRAMES, index_version=UNKNOWN,
                     skip_unknown=False, **options):
    """Annotate stored motions a batch of whole motions at a time: the memory of one batch, whatever the archive.

    Each batch reads its words and, with keyframe preselection, its postings
    (:func:`mocapdb.storage.motions.iter_documents`,
    :meth:`ConnectionCache.preselection`); the segments are those of
    annotating everything at once (motions are independent). A motion that
    cannot be annotated — features that are not its frames 1 … n, or an
    error of its own — is reported and never costs the others.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    cache, key, model
        As :func:`annotate_documents`.
    motion_ids : sequence of int, optional
        Default: every motion.
    max_frames : int
        Frames per batch (:data:`~mocapdb.storage.motions.BATCH_FRAMES`).
    index_version : optional
        The keyframe index version, when the caller knows it.
    skip_unknown : bool
        Leave out ids the database does not have instead of raising.
    **options
        ``tau``, ``keyframes``, ``min_length``, ``min_won``, ``margin`` of :func:`annotate_documents`.

    Yields
    ------
    docs : Documents
        The batch's motions that were annotated (motion-id order).
    segments : ndarray of SEGMENT_DTYPE
        Their segments, ``doc`` indexing ``docs``.
    failed : list of (motion_id, name, reason)
        The batch's motions that were not.

    Raises
    ------
    SchemaError
        Keyframe preselection without a keyframe index (before anything is annotated).
    """
    if uses_keyframes(model, options.get("keyframes")):
        index_version = cache.version(index_version)
    for docs, failed in iter_documents(con, motion_ids, max_frames=max_frames, skip_unknown=skip_unknown):
        failed = list(failed)
        try:
            segs = annotate_documents(cache, key, model, docs.words, docs.lengths, docs.motion_ids,
                                      index_version=index_version, **options)
        except (MocapdbError, MemoryError):
            # one motion's failure must not cost the batch: one at a time, to name the culprit
            docs, segs, more = _one_by_one(cache, key, model, docs, index_version, options)
            failed += more
        yield docs, segs, failed


def _one_by_one(cache, key, model, docs, index_version, options):
    """:func:`annotate_motions` of one batch, motion by motion: (annotated docs, segments, failed)."""
    starts = np.concatenate(([0], np.cumsum(docs.lengths)))
    parts, ok, failed = [], [], []
    for k in range(len(docs.motion_ids)):
        try:
            segs = annotate_documents(cache, key, model, docs.words[starts[k]:starts[k + 1]], docs.lengths[k:k + 1],
                                      docs.motion_ids[k:k + 1], index_version=index_version, **options)
        except (MocapdbError, MemoryError) as exc:
            mid, name = int(docs.motion_ids[k]), docs.names[k]
            failed.append((mid, name, f"motion {mid} ({name}): not annotated: {exc or type(exc).__name__}"))
            continue
        segs["doc"] = len(ok)
        parts.append(segs)
        ok.append(k)
    segs = np.concatenate(parts) if parts else np.empty(0, SEGMENT_DTYPE)
    return docs.take(ok), segs, failed


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


def export_segments(con, table, out, *, format, motion_ids, video=None):
    """Write annotation segments as Parquet (one file, with an ``fps`` column after ``end_frame``: the 30 Hz
    grid of the frames) or ELAN (one ``.eaf`` per motion).

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
    video : callable, optional
        ELAN only: ``video(motion_id, path)`` writes the motion's video to
        ``path`` (``<eaf stem>.mp4`` beside the ``.eaf``), which is then
        linked as the file's second media, after the recording. A motion
        whose video cannot be made (its source gone or changed) keeps its
        ``.eaf`` without one; the others go on, and the error names them.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ParameterError
        After writing every file, if some videos could not be made.
    """
    import pyarrow.parquet as pq

    if format not in EXPORT_FORMATS:
        raise ParameterError(f"format must be one of {', '.join(EXPORT_FORMATS)}, got {format!r}")
    out = Path(out)
    if format == "eaf" and out.suffix.lower() == ".eaf" and len(set(motion_ids)) > 1:
        raise ParameterError(f"out: {len(set(motion_ids))} motions give one ELAN file each; give a directory, "
                             f"not {out.name}")
    sources = motion_sources(con, motion_ids) if format == "eaf" else []
    single = format == "parquet" or (len(sources) == 1 and out.suffix.lower() == ".eaf")
    # the file's folder, or the folder of files, made: a path into a missing folder is what a user means
    (out.parent if single else out).mkdir(parents=True, exist_ok=True)
    if format == "parquet":
        # the frame grid of start_frame/end_frame, as the CSV and JSON outputs carry it (label files read it)
        at = table.schema.get_field_index("end_frame") + 1
        pq.write_table(table.add_column(at, "fps", pa.array(np.full(table.num_rows, FEATURE_RATE))), out)
        return [out]
    ids = table.column("motion_id").to_numpy()
    written, no_video = [], []
    for s, stem in zip(sources, file_stems(sources)):
        rows = table.filter(pa.array(ids == s["motion_id"]))
        path = out if single else file_in(out, stem, ".eaf")
        # the last 30 Hz frame may cover fewer native frames than 4: end at the recording's end
        end = np.minimum(rows.column("end_s").to_numpy(), s["n_source_frames"] / s["source_fps"])
        media = [s["source_path"]]
        if video is not None:
            try:
                media.append(video(s["motion_id"], path.with_suffix(".mp4")))
                written.append(media[-1])
            except (MocapdbError, OSError) as exc:
                no_video.append(f"{s['name']}: {exc}")
        write_eaf(path, rows.column("label").to_pylist(), rows.column("start_s").to_numpy(), end,
                  media=media, fps=s["source_fps"],
                  confidence=rows.column("confidence").to_numpy(zero_copy_only=False))
        written.append(path)
    if no_video:
        raise ParameterError(f"{len(no_video)} of {len(sources)} ELAN files have no video: " + "; ".join(no_video))
    return written


__all__ = ["annotate_documents", "annotate_motions", "stored_preselection",
           "store_annotations", "motion_sources", "export_segments",
           "EXPORT_FORMATS", "PROGRESS_FRAMES"]
