"""Database-level operations shared by the Python API, the CLI and the SQL functions.

Each function here is one CLI command (sqlite-utils style): it reads what it
needs from the database, calls the pure array functions of the algorithm
modules, and writes results back.
"""
from __future__ import annotations

import logging

import numpy as np
import pyarrow as pa

from .annotation import annotate as annotate_words
from .errors import ParameterError, SchemaError
from .modelstore import DEFAULT_MODEL, load_model
from .preselection import preselection_for, uses_keyframes

log = logging.getLogger("mocapdb")

#: columns of an annotation result (frames 1-based, inclusive, 30 Hz)
SEGMENT_COLUMNS = ("motion_id", "document", "label", "start_frame", "end_frame", "start_s", "end_s", "cost")


def motion_words(con, motion_ids=None):
    """Packed 30 Hz words of motions, in motion_id order.

    Returns
    -------
    ids : list of int
    names : list of str
    fps : (n,) float64
    words : (N,) uint64, all motions concatenated
    lengths : (n,) int64
    """
    where, params = "", []
    if motion_ids is not None:
        ids = [int(i) for i in motion_ids]
        if not ids:
            return [], [], np.zeros(0), np.zeros(0, np.uint64), np.zeros(0, np.int64)
        where, params = f"WHERE motion_id IN ({', '.join('?' * len(ids))})", ids
    meta = con.execute(f"SELECT motion_id, name, fps, n_frames FROM motions {where} ORDER BY motion_id",
                       params).fetchall()
    if motion_ids is not None and len(meta) != len(set(params)):
        missing = sorted(set(params) - {m[0] for m in meta})
        raise SchemaError(f"no motion with id {missing} (see: SELECT motion_id, name FROM motions)")
    bits = con.execute(f"SELECT bits FROM features {where} ORDER BY motion_id, frame", params).fetchnumpy()["bits"]
    lengths = np.array([m[3] for m in meta], dtype=np.int64)
    if int(lengths.sum()) != len(bits):
        raise SchemaError("features and motions.n_frames disagree; the database is inconsistent")
    return ([m[0] for m in meta], [m[1] for m in meta], np.array([m[2] for m in meta], np.float64),
            np.asarray(bits, dtype=np.uint64), lengths)


def segments_of_documents(words, lengths, model, *, tau=None, keyframes=None):
    """Annotate concatenated documents; segments per document (0-based inclusive).

    Parameters
    ----------
    words : (N,) uint64
    lengths : (n_docs,) int
    model : mocapdb.model.Model
    tau : float, optional
        One hit threshold for every class (default: each class's τ).
    keyframes : bool, optional
        Keyframe preselection (paper Sect. 5); default: on when the model has
        keyframe queries.

    Returns
    -------
    ndarray of mocapdb.annotation.SEGMENT_DTYPE
        (label, doc, start, end, cost), ``doc`` indexing ``lengths``.
    """
    pre = preselection_for(words, lengths, model, keyframes)
    return annotate_words(words, model, doc_lengths=lengths, preselection=pre, tau=tau, keep_hits=False).segments


def annotate_motions(con, motions=None, *, model=DEFAULT_MODEL, tau=None, keyframes=None, store=True):
    """Annotate motions of the database with a model.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : sequence of int, optional
        Motion ids (default: every motion).
    model : str, keyword-only, default "default"
        Model name; the shipped default model is loaded on first use.
    tau : float, optional, keyword-only
        Hit threshold for every class (paper default 0.13; default: each class's τ).
    keyframes : bool, optional, keyword-only
        Keyframe preselection; default on when the model has keyframe queries.
    store : bool, keyword-only
        Replace the ``annotations`` rows of these motions and this model.

    Returns
    -------
    pyarrow.Table
        Columns :data:`SEGMENT_COLUMNS`, ordered by motion, start frame, label.
    """
    if tau is not None and not (np.isfinite(tau) and tau >= 0):
        raise ParameterError(f"tau must be a non-negative number, got {tau!r}")
    m = load_model(con, model)
    ids, names, fps, words, lengths = motion_words(con, motions)
    segs = segments_of_documents(words, lengths, m, tau=tau, keyframes=keyframes)
    order = np.lexsort((segs["label"], segs["start"], segs["doc"]))
    segs = segs[order]
    doc = segs["doc"]
    seg_fps = fps[doc] if len(doc) else np.zeros(0)
    table = pa.table({
        "motion_id": pa.array(np.asarray(ids, dtype=np.int32)[doc] if len(doc) else [], pa.int32()),
        "document": pa.array([names[d] for d in doc], pa.string()),
        "label": pa.array(segs["label"].tolist(), pa.string()),
        "start_frame": pa.array(segs["start"] + 1, pa.int32()),
        "end_frame": pa.array(segs["end"] + 1, pa.int32()),
        "start_s": pa.array(segs["start"] / seg_fps if len(doc) else [], pa.float64()),
        "end_s": pa.array((segs["end"] + 1) / seg_fps if len(doc) else [], pa.float64()),
        "cost": pa.array(segs["cost"], pa.float64()),
    })
    if store:
        store_annotations(con, table, ids, model=model, tau=tau, keyframes=keyframes)
    return table


def store_annotations(con, table, motion_ids, *, model, tau, keyframes):
    """Replace the stored annotations of ``motion_ids`` under ``model`` (one transaction)."""
    con.begin()
    try:
        if motion_ids:
            con.execute(f"DELETE FROM annotations WHERE model = ? AND motion_id IN "
                        f"({', '.join('?' * len(motion_ids))})", [model, *map(int, motion_ids)])
        con.register("_mocapdb_new_annotations", table)
        try:
            con.execute(
                "INSERT INTO annotations (motion_id, model, label, start_frame, end_frame, cost, start_s, end_s, "
                "tau, keyframes) SELECT motion_id, ?, label, start_frame, end_frame, cost, start_s, end_s, ?, ? "
                "FROM _mocapdb_new_annotations", [model, tau, keyframes])
        finally:
            con.unregister("_mocapdb_new_annotations")
        con.commit()
    except BaseException:
        con.rollback()
        raise


def documents_by_name(con, names=None) -> dict:
    """Packed words of motions by name (for cutting labelled clips out of documents).

    Raises
    ------
    SchemaError
        A name matches no motion, or several (give unique names).
    """
    rows = con.execute("SELECT name, count(*) FROM motions GROUP BY name").fetchall()
    count = dict(rows)
    wanted = sorted(count) if names is None else sorted(set(names))
    missing = [n for n in wanted if n not in count]
    if missing:
        raise SchemaError(f"documents {missing} are not in the database; ingest them first "
                          "(document = motion name, the file stem)")
    dup = [n for n in wanted if count[n] > 1]
    if dup:
        raise SchemaError(f"documents {dup} name several motions; rename or delete duplicates")
    out = {}
    for name in wanted:
        out[name] = np.asarray(con.execute(
            "SELECT f.bits FROM features f JOIN motions m USING (motion_id) WHERE m.name = ? ORDER BY f.frame",
            [name]).fetchnumpy()["bits"], dtype=np.uint64)
    return out


def default_class_labels(classes) -> dict | None:
    """The shipped HDM05 class → label mapping when it covers every class, else None
    (each class its own label)."""
    from .labels import class_labels

    shipped = class_labels("hdm05")
    return shipped if all(c in shipped for c in classes) else None


def training_clips(con, *, folder=None, label_csv=None, progress=None):
    """Labelled clips from a class-folder tree or from a label CSV over ingested documents.

    Returns
    -------
    clips : dict of str to list of (name, words)
    source : str
        A description for the model's ``source``.
    """
    from .labels import read_labels, to_feature_grid
    from .training import clips_from_folders, clips_from_segments

    if (folder is None) == (label_csv is None):
        raise ParameterError("give exactly one of folder (--folder) and label_csv (--labels)")
    if folder is not None:
        return clips_from_folders(folder, progress=progress), f"folder {folder}"
    rows = to_feature_grid(read_labels(label_csv))
    return clips_from_segments(documents_by_name(con, set(rows["document"])), rows), f"label CSV {label_csv}"


def train(con, *, model, folder=None, label_csv=None, class_labels=None, delta=0.05, tau=0.13,
          replace=False, description=None, progress=None):
    """Learn a model from labelled clips and store it.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        Name to store the model under.
    folder : str or Path, optional, keyword-only
        Clips in the HDM05 "cut" layout: one folder per class under ``folder``
        (files read directly, not from the database).
    label_csv : str or Path, optional, keyword-only
        A label CSV ``document,label,start_frame,end_frame`` (native frames,
        1-based inclusive) cutting clips out of ingested documents; the label
        column names the class. Exactly one of ``folder``/``label_csv``.
    class_labels : str, Path or dict, optional, keyword-only
        Class → coarse label mapping (CSV ``class,label``); default the shipped
        HDM05 mapping when it covers every class, else each class its own label.
    delta, tau : float, keyword-only
        Quantization threshold δ and hit threshold τ (paper defaults 0.05, 0.13).
    replace : bool, keyword-only
        Overwrite a stored model of the same name.
    progress : callable, optional
        ``progress(n_done, n_total, what)`` while reading clips and learning.

    Returns
    -------
    mocapdb.model.Model
    """
    from .labels import read_class_labels
    from .modelstore import save_model
    from .training import train_model

    clips, source = training_clips(con, folder=folder, label_csv=label_csv, progress=progress)
    if isinstance(class_labels, dict):
        mapping = class_labels
    elif class_labels is not None:
        mapping = read_class_labels(class_labels)
    else:
        mapping = default_class_labels(clips)
    trained = train_model(clips, name=model, labels=mapping, delta=delta, tau=tau, progress=progress)
    save_model(con, trained, description=description, replace=replace,
               source=f"mocapdb train from {source}: {sum(len(v) for v in clips.values())} clips")
    return trained


def read_truth(path, *, label_map=None, n_frames=None):
    """A ground-truth CSV (native frames, 1-based) on the 30 Hz grid, labels mapped.

    ``label_map`` (CSV ``class,label`` path or dict) renames truth labels to the
    model's (e.g. 86_09's ``walk`` → ``move``); unmapped labels are kept.
    """
    from .labels import map_labels, read_class_labels, read_labels, to_feature_grid

    rows = to_feature_grid(read_labels(path, n_frames=n_frames))
    if label_map is not None:
        rows = map_labels(rows, label_map if isinstance(label_map, dict) else read_class_labels(label_map))
    return rows


def evaluate(con, truth_csv, *, model=DEFAULT_MODEL, tau=None, keyframes=None, label_map=None, taus=None):
    """Annotate the documents of a ground-truth CSV and score the result (paper Eq. 5–8).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    truth_csv : str or Path
        ``document,label,start_frame,end_frame`` (native frames, 1-based);
        documents are motion names in the database.
    model : str, keyword-only
    tau, keyframes
        As :func:`annotate_motions`.
    label_map : str, Path or dict, optional
        Truth label → model label (e.g. the shipped ``cmu86_labels.csv``).
    taus : sequence of float, optional
        Score every τ of the sweep (paper Fig. 8) instead of one τ.

    Returns
    -------
    mocapdb.metrics.Scores, or list of (τ, Scores) with ``taus``
        Truth labels the model cannot produce are dropped (``Scores.dropped_truth``).
    """
    from .labels import segments_to_rows
    from .metrics import evaluate_annotation, sweep_tau

    m = load_model(con, model)
    names = sorted(set(read_truth(truth_csv)["document"]))
    words_by_doc = documents_by_name(con, names)
    native = dict(con.execute(f"SELECT name, n_source_frames FROM motions WHERE name IN "
                              f"({', '.join('?' * len(names))})", names).fetchall())
    truth = read_truth(truth_csv, label_map=label_map, n_frames=native)
    words = np.concatenate([words_by_doc[n] for n in names])
    lengths = np.array([len(words_by_doc[n]) for n in names], dtype=np.int64)
    pre = preselection_for(words, lengths, m, keyframes)
    if taus is not None:
        return sweep_tau(words, m, truth, taus, documents=names, doc_lengths=lengths, preselection=pre)
    segs = annotate_words(words, m, doc_lengths=lengths, preselection=pre, tau=tau, keep_hits=False).segments
    return evaluate_annotation(truth, segments_to_rows(segs, names), labels=m.labels)


def learn_keyframes(con, *, model=DEFAULT_MODEL, folder=None, label_csv=None, classes=None, runs=20, seed=0,
                    n_jobs=None, progress=None, **ga_params):
    """Learn a keyframe query per class with the genetic algorithm (paper Sect. 6) and store it.

    The training clips (``folder`` or ``label_csv``, as :func:`train`) give
    T+ for each class and T− = the clips of every other class; the model's
    stored real-valued templates seed the initial populations (δ = 0).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        A stored model (its classes must be the clips' classes).
    folder, label_csv : keyword-only
        As :func:`train`.
    classes : sequence of str, optional
        Classes to learn (default: all of the model's).
    runs : int, default 20
        Independent GA runs per class (paper: 100–500); the consensus is kept.
    seed : int, default 0
        Reproducible: the same seed gives the same queries.
    n_jobs : int, optional
        Worker processes (default: all cores).
    progress : callable, optional
        ``progress(class_name, runs_done, runs)``.
    **ga_params
        GA parameters (:data:`mocapdb.ga.GA_DEFAULTS`: population_size=50,
        n_parents=5, generations=100, beta=2, …).

    Returns
    -------
    dict of str to mocapdb.ga.LearnedQuery
    """
    from .ga import learn_keyframe_queries
    from .modelstore import keyframe_query_stats, save_model

    m = load_model(con, model)
    clips, source = training_clips(con, folder=folder, label_csv=label_csv)
    unknown = sorted(set(clips) - set(m.class_names))
    if unknown:
        raise ParameterError(f"the clips hold classes {unknown} that model {model!r} does not have")
    classes = list(m.class_names if classes is None else classes)
    missing = [c for c in classes if c not in clips]
    if missing:
        raise ParameterError(f"no training clips for classes {missing}")
    templates = {c.name: c.template for c in m.classes if c.template is not None}
    learned = learn_keyframe_queries(clips, classes=classes, runs=runs, random_state=seed, n_jobs=n_jobs,
                                     templates=templates or None, progress=progress, **ga_params)
    stats = keyframe_query_stats(con, model)
    rows = [r[1:] for r in con.execute(
        "SELECT * FROM ga_statistics WHERE model = ? ORDER BY class, run, generation", [model]).fetchall()
        if r[1] not in learned]
    for name, lq in learned.items():
        stats[name] = {"source": f"ga (runs={runs}, seed={seed})", "fitness": lq.fitness,
                       "precision": lq.precision, "recall": lq.recall}
        for r, res in enumerate(lq.runs):
            st = res.statistics
            rows += [(name, r, g, st.mean_precision[g], st.mean_recall[g], st.mean_fitness[g],
                      st.best_fitness[g], st.mean_keyframes[g]) for g in range(st.generations + 1)]
    meta = con.execute("SELECT description, source FROM models WHERE model = ?", [model]).fetchall()[0]
    save_model(con, m.with_keyframe_queries({n: lq.query for n, lq in learned.items()}), description=meta[0],
               source=f"{meta[1]}; keyframe queries: GA from {source}", replace=True, keyframe_stats=stats,
               ga_statistics=rows)
    return learned


def plot_figure(con, figure, path, *, model=DEFAULT_MODEL, motion=None, keyframes=None):
    """Write a figure: ``"ga"`` (paper Fig. 5 from the model's stored GA statistics) or
    ``"annotation"`` (one motion's labels over time with Δ̄^τ per label, paper Fig. 6)."""
    from . import plots
    from .ga import GAStatistics

    if figure == "ga":
        load_model(con, model)  # the default model is loaded on first use
        rows = con.execute("""SELECT generation, avg(mean_precision), avg(mean_recall), avg(mean_fitness),
                                     avg(best_fitness), avg(mean_keyframes)
                              FROM ga_statistics WHERE model = ? GROUP BY generation ORDER BY generation""",
                           [model]).fetchnumpy()
        if len(rows["generation"]) == 0:
            raise SchemaError(f"model {model!r} has no GA statistics; learn its keyframe queries with "
                              "`mocapdb learn-keyframes`")
        cols = [np.asarray(rows[k]) for k in list(rows)[1:]]
        stats = GAStatistics(cols[0], cols[1], cols[2], cols[3], np.full_like(cols[0], np.nan),
                             np.full_like(cols[0], np.nan), cols[4])
        n_runs = con.execute("SELECT count(DISTINCT (class, run)) FROM ga_statistics WHERE model = ?",
                             [model]).fetchall()[0][0]
        plots.plot_ga_statistics(stats, path, title=f"model {model}: averages over {n_runs} GA runs")
        return
    if figure != "annotation":
        raise ParameterError(f"figure must be 'ga' or 'annotation', got {figure!r}")
    if motion is None:
        raise ParameterError("the annotation figure needs a motion (--motion ID or NAME)")
    from .database import motion_ids

    ids = motion_ids(con, [motion])
    m = load_model(con, model)
    _, names, fps, words, lengths = motion_words(con, ids[:1])
    use_kf = uses_keyframes(m, keyframes)
    pre = preselection_for(words, lengths, m, use_kf)
    ann = annotate_words(words, m, doc_lengths=lengths, preselection=pre, keep_deltas=True, keep_hits=False)
    plots.plot_annotation(ann.segments, m.labels, int(lengths[0]), label_delta=ann.label_delta, fps=float(fps[0]),
                          path=path, title=f"{names[0]} — model {model}{' with keyframes' if use_kf else ''}")


__all__ = ["annotate_motions", "train", "learn_keyframes", "plot_figure", "training_clips", "evaluate", "read_truth", "documents_by_name", "default_class_labels", "segments_of_documents", "motion_words", "store_annotations", "SEGMENT_COLUMNS"]
