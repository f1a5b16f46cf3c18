"""Annotation: label motions with a model, in the database or on a Ray cluster, and score it."""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from mocapdb.annotation import (SEGMENT_DTYPE, label_documents, read_segments, read_truth, segment_table,
                                segments_to_rows)
from mocapdb.distributed import BATCH_FILES, BUCKET_MOTIONS
from mocapdb.distributed import ray_annotate as run_on_ray
from mocapdb.errors import ParameterError, PartialAnnotationError, SchemaError, check_nonnegative
from mocapdb.evaluation import evaluate_annotation, evaluate_by_label, parse_tau_grid
from mocapdb.readers import ReaderOptions
from mocapdb.storage import annotations as stored_annotations
from mocapdb.storage.annotations import (EXPORT_FORMATS, annotate_documents, annotate_motions,
                                        export_segments, store_annotations)
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.motions import documents_by_name, motion_ids, source_rates
from mocapdb.storage.schema import require_own_tables
from mocapdb.storage.sqltext import statement
from mocapdb.viewer import motion_poses
from mocapdb.viewer.video import ffmpeg_path, write_video


def annotate(con, motions=None, *, model=DEFAULT_MODEL, tau=None, keyframes=None, store=True, format=None, out=None,
             progress=None, min_length=None, min_won=None, margin=None, video=False):
    """Annotate motions of the database with a model.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : sequence of int or str, optional
        Motion ids or names (default: every motion).
    model : str, keyword-only, default "default"
    tau : float, optional, keyword-only
        Hit threshold for every class (paper default 0.13; default: each class's τ).
    keyframes : bool, optional, keyword-only
        Keyframe preselection over the stored index (paper Sect. 5); default
        on when the model has keyframe queries. False is the reference mode.
    store : bool, keyword-only
        Replace the ``annotations`` rows of these motions and this model.
    format : {"parquet", "eaf"}, optional, keyword-only
        Also write the segments to ``out``: one Parquet file, or ELAN files
        (one ``.eaf`` per motion, a tier per label, the source file as linked
        media; see :func:`mocapdb.storage.annotations.export_segments`).
        Tables, CSV and JSON are printed by the CLI.
    out : str or Path, optional, keyword-only
        The file (or, for ELAN files of several motions, the directory).
    progress : callable, optional, keyword-only
        ``progress(n_motions_done, n_motions)`` while annotating.
    min_length : bool, optional, keyword-only
        Drop segments shorter than their label's minimum (the model's
        ``min_frames``); default on (models without minimums keep everything).
    min_won : bool, optional, keyword-only
        Drop segments whose label is the best label on fewer than a third of
        its minimum (:func:`mocapdb.annotation.postprocess.drop_unwon_segments`);
        default on (models without minimums keep everything).
    margin : float, optional, keyword-only
        Leave frames unlabelled where the best label wins by less than this;
        default the model's margin.
    video : bool, keyword-only
        With ``format="eaf"``: also write each motion's stick figure as an MP4
        beside its ``.eaf`` (``<stem>.mp4``, 30 frames a second, re-read from
        the source) and link it as media, so ELAN plays it in step with the
        tiers (:func:`mocapdb.viewer.video.write_video`; needs ``ffmpeg``).

    Returns
    -------
    pyarrow.Table
        Columns :data:`mocapdb.annotation.SEGMENT_COLUMNS` (30 Hz frames,
        1-based inclusive, and seconds), ordered by motion, start frame, label.

    Raises
    ------
    SchemaError
        The database holds no motions (ingest first), or an id or name is unknown.
    """
    check_nonnegative(tau, "tau", none="each class's τ")
    if (format is None) != (out is None) or (format is not None and format not in EXPORT_FORMATS):
        raise ParameterError(f"format and out go together, format one of {', '.join(EXPORT_FORMATS)}; "
                             f"got format={format!r}, out={out!r}")
    if video:
        if format != "eaf":
            raise ParameterError(f"video goes with ELAN files (format='eaf'), got format={format!r}")
        ffmpeg_path()  # before annotating: a missing ffmpeg is said at once
    if store:
        require_own_tables(con, "annotate with store=True (--store)")
    cache = connection_cache(con)
    key, m = cache.model(model)
    ids = None if motions is None else motion_ids(con, motions)
    n_motions = len(set(ids)) if ids is not None else con.execute(statement("motions.sql", "count")).fetchall()[0][0]
    if motions is None and not n_motions:
        raise SchemaError("the database holds no motions: ingest recordings first (mocapdb ingest PATH…)")
    tables, done, failed = [], [], []
    if progress is not None:
        progress(0, n_motions)
    # a batch at a time, each stored in its own transaction: memory does not grow with the archive,
    # and a motion that fails is reported without costing the others
    for docs, segs, bad in annotate_motions(con, cache, key, m, ids, tau=tau, keyframes=keyframes,
                                            min_length=min_length, min_won=min_won, margin=margin,
                                            max_frames=stored_annotations.PROGRESS_FRAMES if progress else cache.batch_frames):
        table = segment_table(segs, motion_ids=docs.motion_ids, names=docs.names, fps=docs.fps)
        if store:
            store_annotations(con, table, docs.motion_ids, model=model, tau=tau, keyframes=keyframes)
        tables.append(table)
        done.extend(docs.motion_ids.tolist())
        failed.extend(bad)
        if progress is not None:
            progress(len(done) + len(failed), n_motions)
    table = pa.concat_tables(tables) if tables else segment_table(
        np.empty(0, SEGMENT_DTYPE), motion_ids=np.zeros(0, np.int64), names=[], fps=np.zeros(0))
    if out is not None:
        export_segments(con, table, out, format=format, motion_ids=done,
                        video=(lambda motion_id, path: write_video(path, motion_poses(con, motion_id))) if video
                        else None)
    if failed:
        raise PartialAnnotationError(failed, table, n_motions, store)
    return table


def evaluate(con, truth, *, pred=None, model=DEFAULT_MODEL, tau=None, keyframes=None, label_map=None,
             vocabulary=None, sweep_tau=None, by_label=False, min_length=None, min_won=None, margin=None):
    """Score an annotation against ground truth with the paper's measures (Eq. 5–8).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection or None
        Needed unless ``pred`` is given; with ``pred``, the source rate of each
        truth document it knows places the truth's native frames (else 120 Hz,
        or an ELAN file's own rate).
    truth : str or Path
        ``document,label,start_frame,end_frame`` (native frames, 1-based) or
        an ELAN ``.eaf`` file; documents are motion names in the database.
    pred : str or Path, optional
        Score this annotation CSV (as written by ``annotate --format csv``, 30 Hz
        frames) instead of annotating the truth's documents from the database.
    model : str, keyword-only
    tau, keyframes
        As :func:`annotate`.
    label_map : str, Path or dict, optional
        Truth label → model label (e.g. the shipped ``cmu86_labels.csv``).
    vocabulary : sequence of str, optional
        Labels to score (default: the model's labels; with ``pred``: every truth label).
    sweep_tau : str or sequence of float, optional
        Score every τ of a sweep (paper Fig. 8) instead of one τ: the values,
        or ``"start:stop:step"`` (e.g. ``"0.05:0.25:0.01"``).
    by_label : bool, keyword-only
        Also score each label of the vocabulary on its own.
    min_length, min_won, margin : optional, keyword-only
        The segment filters, as :func:`annotate`.

    Returns
    -------
    mocapdb.evaluation.Scores, or list of (τ, Scores) with ``sweep_tau``
        Truth labels outside the vocabulary are dropped (``Scores.dropped_truth``).
        With ``by_label``: a dict ``{"all": Scores, label: Scores, …}`` (per τ
        with ``sweep_tau``).
    """
    taus = parse_tau_grid(sweep_tau) if isinstance(sweep_tau, str) else sweep_tau
    if pred is not None:
        if taus is not None:
            raise ParameterError("a tau sweep re-annotates: use it with a database, not with pred")
        # a document the database knows is read at its source rate, not the 120 Hz default
        fps = None if con is None else source_rates(con, label_documents(truth)) or None
        return _scores(read_truth(truth, label_map=label_map, fps=fps), read_segments(pred), vocabulary, by_label)
    if con is None:
        raise ParameterError("give pred (an annotation CSV), or a database to annotate the truth's documents")
    cache = connection_cache(con)
    key, m = cache.model(model)
    docs = documents_by_name(con, set(label_documents(truth)))
    truth_rows = read_truth(truth, label_map=label_map, n_frames=docs.native_lengths(),
                            fps=docs.native_rates())
    vocab = m.labels if vocabulary is None else tuple(vocabulary)
    segs = annotate_documents(cache, key, m, docs.words, docs.lengths, docs.motion_ids, tau=tau,
                              keyframes=keyframes, taus=taus, min_length=min_length, min_won=min_won,
                              margin=margin)
    if taus is not None:
        return [(float(t), _scores(truth_rows, segments_to_rows(s, docs.names), vocab, by_label))
                for t, s in zip(taus, segs)]
    return _scores(truth_rows, segments_to_rows(segs, docs.names), vocab, by_label)


def _scores(truth_rows, auto_rows, vocabulary, by_label):
    """Scores of all labels, and with ``by_label`` of each label (``{"all": …, label: …}``)."""
    total = evaluate_annotation(truth_rows, auto_rows, labels=vocabulary)
    if not by_label:
        return total
    return {"all": total, **evaluate_by_label(truth_rows, auto_rows, labels=vocabulary)}


def ray_annotate(sources, out, *, address=None, model=DEFAULT_MODEL, tau=None, keyframes=None, database=None,
                 asf=None, joint_map=None, marker_map=None, marker_rules=None, body_model=None, max_decompressed=None,
                 num_cpus=None, batch_files=BATCH_FILES, bucket_motions=BUCKET_MOTIONS, overwrite=False):
    """``ingest`` + ``annotate`` on a Ray cluster, Parquet out (needs the ``ray`` extra).

    Reads the recordings on Ray actors with the same readers, kernels and
    model and writes the datasets ``motions``, ``features``, ``postings``,
    ``annotations`` (the columns of the DuckDB tables) and ``errors``
    (file, reason) under ``out``; :func:`import_features` loads them into a
    database, and DuckDB queries them in place. See
    :func:`mocapdb.distributed.ray_annotate` for every parameter.

    Parameters
    ----------
    sources : iterable of str or Path
        Files, folders or glob patterns, at the same path on every node.
    out : str or Path
        Archive folder (empty or absent unless ``overwrite``).
    address : str, optional, keyword-only
        Ray cluster address; default: a local Ray with ``num_cpus`` CPUs.
    model, tau, keyframes
        As :func:`annotate`; the model is a shipped one or one stored in ``database``.
    asf, joint_map, marker_map, marker_rules, max_decompressed : optional, keyword-only
        How files are read, as :func:`mocapdb.api.ingest` reads them (one
        :class:`mocapdb.readers.ReaderOptions` value, checked here and sent to
        every worker).

    Returns
    -------
    mocapdb.distributed.RayReport
    """
    options = ReaderOptions(asf=asf, joint_map=joint_map, marker_map=marker_map, marker_rules=marker_rules,
                            body_model=body_model, max_decompressed=max_decompressed)
    return run_on_ray(sources, out, address=address, model=model, tau=tau, keyframes=keyframes, database=database,
                      options=options, num_cpus=num_cpus, batch_files=batch_files, bucket_motions=bucket_motions,
                      overwrite=overwrite)
