"""The Python API of a mocap database: one function per command of the CLI, same names.

Each function takes a connection from :func:`connect`, reads what it needs
from the database, calls the array functions of the algorithm sub-packages
and writes results back (sqlite-utils style). ``mocapdb COMMAND`` calls the
function of the same name with the same options (dashes for underscores).

============================  ==========================
CLI                           API
============================  ==========================
``mocapdb ingest``            :func:`ingest`
``mocapdb delete``            :func:`delete`
``mocapdb train``             :func:`train`
``mocapdb learn-keyframes``   :func:`learn_keyframes`
``mocapdb define-class``      :func:`define_class`
``mocapdb annotate``          :func:`annotate`
``mocapdb evaluate``          :func:`evaluate`
``mocapdb report``            :func:`report`
``mocapdb view``              :func:`view`
``mocapdb similar``           :func:`similar`
``mocapdb create-index``      :func:`create_index`
``mocapdb drop-index``        :func:`drop_index`
``mocapdb export-features``   :func:`export_features`
``mocapdb import-features``   :func:`import_features`
``mocapdb attach``            :func:`attach`
``mocapdb ray-annotate``      :func:`ray_annotate`
``mocapdb convert-labels``    :func:`convert_labels`
``mocapdb relocate``          :func:`relocate`
``mocapdb warmup``            :func:`warmup`
``mocapdb sql``               ``connect(...).sql(query)``
============================  ==========================
"""
from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
import pyarrow as pa

from mocapdb.annotation import (SEGMENT_DTYPE, class_labels, label_documents, read_class_labels, read_segments,
                                read_truth, segment_table, segments_to_rows, write_labels)
from mocapdb.annotation.foreign_labels import read_label_file
from mocapdb.distributed import BATCH_FILES, BUCKET_MOTIONS
from mocapdb.distributed import ray_annotate as run_on_ray
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.readers import joint_map_template as readers_joint_map_template
from mocapdb.evaluation import evaluate_annotation, evaluate_by_label, parse_tau_grid
from mocapdb.extension import connect as connect_database
from mocapdb.annotation import Model
from mocapdb.learning import clips_from_folders, clips_from_segments, learn_keyframe_queries, train_model
from mocapdb.learning.class_definitions import attach_keyframes, compile_definitions, read_definitions
from mocapdb.storage import annotations as stored_annotations
from mocapdb.storage import attached, parquet, postings
from mocapdb.storage.annotations import (EXPORT_FORMATS, PartialAnnotationError, annotate_documents, annotate_motions,
                                        export_segments, store_annotations)
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.ingest import IngestReport, delete_motions, ingest_files
from mocapdb.storage.models import (DEFAULT_MODEL, SHIPPED_MODELS, ga_statistics_rows, keyframe_query_stats,
                                    model_fingerprint, model_metadata, save_model)
from mocapdb.storage.motions import (documents_by_name, motion_ids, motions_to_delete,
                                     relocate_sources)
from mocapdb.storage.schema import require_own_tables
from mocapdb.storage.sqltext import statement
from mocapdb.viewer import motion_view, write_motion_page, write_pages
from mocapdb.storage.retrieval import query_stretch, similar_stretches
from mocapdb.viewer.results import write_results_pages
from mocapdb.warmup import (PARTS, background_compile_running, cache_is_cold, compile_kernels, sample_files,
                            start_background_compile, wait_for_background_compile)

log = logging.getLogger("mocapdb")


def connect(path=":memory:", *, read_only: bool = False, create: bool = True, memory_limit=None):
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
        Another process is writing the file.
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
    return connect_database(path, read_only=read_only, memory_limit=memory_limit)


def ingest(con, paths=(), *, sample=False, asf=None, joint_map=None, marker_map=None, marker_rules=None,
           progress=None, replace=False) -> IngestReport:
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
    asf : str or Path, optional, keyword-only
        Skeleton for every AMC file (default: found by the dataset conventions).
    joint_map : dict, str or Path, optional, keyword-only
        BVH files: canonical joint → the file's joint name(s) (TOML/JSON file or
        dict), overriding the automatic mapping (README "Mapping files").
    marker_map : dict, str or Path, optional, keyword-only
        C3D files: canonical joint → the markers whose mean it is.
    marker_rules : {"toolbox", "anatomical"}, optional, keyword-only
        C3D files of the HDM05/CMU marker set: the toolbox's formulas (default,
        the reference) or anatomical joint centres (README "C3D marker files").
    progress : callable, optional, keyword-only
        ``progress(path, n_source_frames)`` once per file.
    replace : bool, keyword-only
        Read files already stored (same bytes) again and replace their
        motions, e.g. after correcting ``joint_map``; default: skip them.

    Returns
    -------
    IngestReport
        Ingested, skipped, failed and unsupported files, unreadable folder
        entries, and the readers' notes on what they decided per file;
        ``failed`` lists every file that was not stored, with the reason
        (the command exits 1 when it is not empty).
    """
    require_own_tables(con, "ingest")
    paths = [*paths, *(sample_files() if sample else [])]
    return ingest_files(con, paths, asf=asf, joint_map=joint_map, marker_map=marker_map,
                        marker_rules=marker_rules, progress=progress, replace=replace)


def warmup(*, parts=None) -> float:
    """Compile the numba kernels into numba's cache now.

    ``pip install .`` does this when it builds the package, so a new install
    answers at once; this is for installs without that cache (editable, or
    another numba version). See :mod:`mocapdb.warmup`.

    Parameters
    ----------
    parts : iterable of {"ingest", "search", "segments"}, optional, keyword-only
        Default: all.

    Returns
    -------
    float
        Seconds it took.
    """
    return compile_kernels(parts or PARTS)


#: the numba cache's state, for the command line's messages (not commands)
kernels_cold = cache_is_cold


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


def annotate(con, motions=None, *, model=DEFAULT_MODEL, tau=None, keyframes=None, store=True, format=None, out=None,
             progress=None, min_length=None, min_won=None, margin=None):
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
    if tau is not None and not (np.isfinite(tau) and tau >= 0):
        raise ParameterError(f"tau must be a non-negative number, got {tau!r}")
    if (format is None) != (out is None) or (format is not None and format not in EXPORT_FORMATS):
        raise ParameterError(f"format and out go together, format one of {', '.join(EXPORT_FORMATS)}; "
                             f"got format={format!r}, out={out!r}")
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
        export_segments(con, table, out, format=format, motion_ids=done)
    if failed:
        raise PartialAnnotationError(failed, table, n_motions, store)
    return table


def _native_rates(docs):
    """Document name → native frame rate (reads ELAN times onto native frames)."""
    return dict(zip(docs.names, docs.source_fps.tolist()))


def _class_label_mapping(class_labels_arg, classes):
    """A class → label mapping: given as a dict or a CSV path; else the shipped HDM05
    mapping when it covers every class; else None (each class its own label)."""
    if isinstance(class_labels_arg, dict):
        return class_labels_arg
    if class_labels_arg is not None:
        return read_class_labels(class_labels_arg)
    shipped = class_labels("hdm05")
    return shipped if all(c in shipped for c in classes) else None


def training_clips(con, *, folder=None, labels=None, progress=None):
    """Labelled clips from a class-folder tree or from a label file over ingested documents.

    Returns
    -------
    clips : dict of str to list of (name, words)
    source : str
        A description for the model's ``source``.
    """
    if (folder is None) == (labels is None):
        raise ParameterError("give exactly one of folder (--folder) and labels (--labels)")
    if folder is not None:
        return clips_from_folders(folder, progress=progress), f"folder {folder}"
    docs = documents_by_name(con, set(label_documents(labels)))
    # with the documents' lengths, a row beyond one is an error in the file's own frames
    rows = read_truth(labels, fps=_native_rates(docs), n_frames=dict(zip(docs.names, docs.n_source_frames)))
    return clips_from_segments({n: docs.words_of(n) for n in docs.names}, rows), f"labels {labels}"


def train(con, *, model, folder=None, labels=None, class_labels=None, delta=0.05, tau=0.13, replace=False,
          description=None, progress=None, definitions=None):
    """Learn a model from labelled clips and store it.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        Name to store the model under.
    folder : str or Path, optional, keyword-only
        Clips in the HDM05 "cut" layout: one folder per class under ``folder``
        (files read directly, not from the database).
    labels : str or Path, optional, keyword-only
        A label file ``document,label,start_frame,end_frame`` (native frames,
        1-based inclusive) or an ELAN ``.eaf`` file cutting clips out of
        ingested documents; the label names the class. Exactly one of
        ``folder``/``labels``.
    class_labels : str, Path or dict, optional, keyword-only
        Class → coarse label mapping (CSV ``class,label``); default the shipped
        HDM05 mapping when it covers every class, else each class its own label.
    delta, tau : float, keyword-only
        Quantization threshold δ and hit threshold τ (paper defaults 0.05, 0.13).
    replace : bool, keyword-only
        Overwrite a stored model of the same name.
    progress : callable, optional
        ``progress(n_done, n_total, what)`` while reading clips and learning.
    definitions : str, Path or sequence of them, optional, keyword-only
        Class definition files (or folders of ``*.toml``) whose hand-designed
        classes join the learned ones (README "Class definitions").

    Returns
    -------
    mocapdb.annotation.Model
    """
    clips, source = training_clips(con, folder=folder, labels=labels, progress=progress)
    trained = train_model(clips, name=model, labels=_class_label_mapping(class_labels, clips), delta=delta,
                          tau=tau, progress=progress)
    source = f"mocapdb train from {source}: {sum(len(v) for v in clips.values())} clips"
    if definitions is not None:
        trained = _with_definitions(trained, definitions)
        source += f"; class definitions {definitions}"
    save_model(con, trained, description=description, replace=replace, source=source,
               keyframe_stats={c.name: {"source": "class definition"} for c in trained.classes
                               if c.template is None and c.keyframe_query is not None})
    return trained


def _with_definitions(model, definitions, *, replace=False):
    """``model`` with the compiled classes of definition files added (or replaced), and the
    keyframe definitions' queries attached to the classes they name."""
    defs, keyframes = read_definitions(definitions)
    designed = compile_definitions(defs)
    clash = sorted({c.name for c in designed} & set(model.class_names))
    if clash and not replace:
        raise ParameterError(f"model {model.name!r} already has the classes {clash}; pass replace=True "
                             "(--replace) to redefine them")
    new = {c.name for c in designed}
    classes = tuple(c for c in model.classes if c.name not in new) + tuple(designed)
    by_class = {k.cls: k for k in keyframes}
    unknown = sorted(set(by_class) - {c.name for c in classes})
    if unknown:
        raise ParameterError(f"keyframe definitions name classes {unknown} that model {model.name!r} does not "
                             f"have; its classes: {', '.join(c.name for c in classes)}")
    classes = tuple(attach_keyframes(c, by_class[c.name]) if c.name in by_class else c for c in classes)
    labels = tuple(dict.fromkeys(list(model.labels) + [c.label for c in designed]))
    return dataclasses.replace(model, classes=classes, labels=labels)


def define_class(con, definitions, *, model=DEFAULT_MODEL, replace=False, description=None):
    """Add hand-designed classes from class definition files to a model (paper Sect. 8).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    definitions : str, Path or sequence of them
        TOML class definition files, or folders of ``*.toml`` (README
        "Class definitions"); each class compiles to a quantized template
        and a keyframe query (:mod:`mocapdb.learning.class_definitions`);
        a ``[[keyframes]]`` table gives a class of the model a designed
        keyframe query.
    model : str, keyword-only
        The model to add them to; a model the database does not have is
        created with just these classes.
    replace : bool, keyword-only
        Redefine classes the model already has (otherwise an error).

    Returns
    -------
    mocapdb.annotation.Model
        The stored model.
    """
    stored = model_fingerprint(con, model) is not None or model in SHIPPED_MODELS
    if stored:
        _, base = connection_cache(con).model(model)
        meta = (model_metadata(con, model) if model_fingerprint(con, model) is not None
                else {"description": None, "source": f"the shipped model {model!r}"})
        stats = keyframe_query_stats(con, model) if model_fingerprint(con, model) is not None else {}
        ga = ga_statistics_rows(con, model) if model_fingerprint(con, model) is not None else []
    else:
        base, meta, stats, ga = Model(model, ()), {"description": description, "source": ""}, {}, []
    new = _with_definitions(base, definitions, replace=replace)
    before = {c.name: c.keyframe_query for c in base.classes}
    for c in new.classes:
        if c.template is None and c.keyframe_query is not None and c.name not in base.class_names:
            stats[c.name] = {"source": "class definition"}
        elif c.name in before and c.keyframe_query is not before[c.name]:
            stats[c.name] = {"source": "keyframe definition"}
    save_model(con, new, replace=True, description=description or meta["description"],
               source=f"{meta['source']}; class definitions {definitions}".lstrip("; "), keyframe_stats=stats,
               ga_statistics=ga)
    return new


def learn_keyframes(con, *, model=DEFAULT_MODEL, folder=None, labels=None, classes=None, runs=20, seed=0,
                    jobs=None, generations=100, progress=None):
    """Learn a keyframe query per class with the genetic algorithm (paper Sect. 6) and store it.

    The training clips (``folder`` or ``labels``, as :func:`train`) give T+
    for each class and T− = the clips of every other class; the model's stored
    real-valued templates seed the initial populations (δ = 0).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        A stored model (its classes must be the clips' classes).
    folder, labels : keyword-only
        As :func:`train`.
    classes : sequence of str, optional
        Classes to learn (default: all of the model's).
    runs : int, default 20
        Independent GA runs per class (paper: 100–500); the consensus is kept.
    seed : int, default 0
        Reproducible: the same seed gives the same queries.
    jobs : int, optional
        Worker processes (default: all cores).
    generations : int, default 100
        Generations per run (paper: 100).
    progress : callable, optional
        ``progress(class_name, runs_done, runs)``.

    Returns
    -------
    dict of str to mocapdb.learning.LearnedQuery
    """
    _, m = connection_cache(con).model(model)
    clips, source = training_clips(con, folder=folder, labels=labels)
    unknown = sorted(set(clips) - set(m.class_names))
    if unknown:
        raise ParameterError(f"the clips hold classes {unknown} that model {model!r} does not have")
    classes = list(m.class_names if classes is None else classes)
    missing = [c for c in classes if c not in clips]
    if missing:
        raise ParameterError(f"no training clips for classes {missing}")
    templates = {c.name: c.template for c in m.classes if c.template is not None}
    learned = learn_keyframe_queries(clips, classes=classes, runs=runs, random_state=seed, n_jobs=jobs,
                                     templates=templates or None, progress=progress, generations=generations)
    stats = keyframe_query_stats(con, model)
    rows = ga_statistics_rows(con, model, exclude_classes=learned)
    for name, lq in learned.items():
        stats[name] = {"source": f"ga (runs={runs}, seed={seed})", "fitness": lq.fitness,
                       "precision": lq.precision, "recall": lq.recall}
        for r, res in enumerate(lq.runs):
            st = res.statistics
            rows += [(name, r, g, st.mean_precision[g], st.mean_recall[g], st.mean_fitness[g],
                      st.best_fitness[g], st.mean_keyframes[g]) for g in range(st.generations + 1)]
    meta = model_metadata(con, model)
    save_model(con, m.with_keyframe_queries({n: lq.query for n, lq in learned.items()}),
               description=meta["description"], source=f"{meta['source']}; keyframe queries: GA from {source}",
               replace=True, keyframe_stats=stats, ga_statistics=rows)
    return learned


def evaluate(con, truth, *, pred=None, model=DEFAULT_MODEL, tau=None, keyframes=None, label_map=None,
             vocabulary=None, sweep_tau=None, by_label=False, min_length=None, min_won=None, margin=None):
    """Score an annotation against ground truth with the paper's measures (Eq. 5–8).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection or None
        Needed unless ``pred`` is given.
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
        return _scores(read_truth(truth, label_map=label_map), read_segments(pred), vocabulary, by_label)
    if con is None:
        raise ParameterError("give pred (an annotation CSV), or a database to annotate the truth's documents")
    cache = connection_cache(con)
    key, m = cache.model(model)
    docs = documents_by_name(con, set(label_documents(truth)))
    truth_rows = read_truth(truth, label_map=label_map, n_frames=dict(zip(docs.names, docs.n_source_frames)),
                            fps=_native_rates(docs))
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


#: the figures of ``report``; ``annotation`` is the former name of ``timeline``
FIGURES = ("ga", "delta", "template", "tau", "timeline", "annotation")


def report(con, figure, out, *, model=DEFAULT_MODEL, motion=None, keyframes=None, tau=None, truth=None,
           label_map=None, class_name=None, sweep_tau=None):
    """Draw a figure of the paper from the database as an image (needs the ``plot`` extra).

    Parameters
    ----------
    figure : {"ga", "delta", "template", "tau", "timeline", "annotation"}
        ``ga``: GA precision/recall/fitness over generations from the model's
        stored GA statistics (paper Fig. 5); ``delta``: one motion's Δ̄^τ per
        class as a heat map, white above τ, with the segments below (Fig. 3a/b);
        ``template``: a class's motion template, real-valued and quantized
        (Fig. 1c/d); ``tau``: precision, recall and F over τ against ground
        truth, frame- and segment-based (Fig. 8); ``timeline`` (formerly
        ``annotation``): one motion's labels over time with Δ̄^τ per label,
        and the ground truth when given (Figs. 6, 7).
    out : str or Path
        Image file (format from the suffix).
    model : str, keyword-only
    motion : int or str, optional
        The motion of ``delta`` and ``timeline``.
    keyframes : bool, optional
        Keyframe preselection (``delta``, ``timeline``, ``tau``).
    tau : float, optional
        One hit threshold for every class (``delta``, ``timeline``).
    truth : str or Path, optional
        Ground truth, label CSV or ELAN file (``tau``; optional for ``timeline``, ``delta``).
    label_map : str, Path or dict, optional
        Truth label → model label, as :func:`evaluate`.
    class_name : str, optional
        The class of ``template``.
    sweep_tau : str or sequence of float, optional
        The τ values of ``tau`` (default ``"0.05:0.25:0.01"``, as the paper).
    """
    from mocapdb.evaluation import figures  # matplotlib is the optional plot extra

    if figure not in FIGURES:
        raise ParameterError(f"figure must be one of {', '.join(FIGURES)}, got {figure!r}")
    _, m = connection_cache(con).model(model)
    if figure == "ga":
        rows = con.execute(statement("models.sql", "ga_curve"), {"model": model}).fetchnumpy()
        if len(rows["generation"]) == 0:
            raise SchemaError(f"model {model!r} has no GA statistics; learn its keyframe queries with "
                              "`mocapdb learn-keyframes`")
        figures.plot_ga_curve(rows, out, title=f"model {model}: averages over {int(rows['n_runs'][0])} GA runs")
    elif figure == "template":
        if class_name not in m.class_names:
            raise ParameterError(f"the template figure needs a class of model {model!r} (--class NAME), got "
                                 f"{class_name!r}; its classes: {', '.join(m.class_names)}")
        c = m.classes[m.class_names.index(class_name)]
        figures.plot_template(c.quantized.dense(), None if c.template is None else c.template.real, path=out,
                              title=f"{c.name} (model {model}, δ={c.delta:g})")
    elif figure == "tau":
        if truth is None:
            raise ParameterError("the tau figure needs ground truth (--truth FILE: label CSV or ELAN file)")
        results = evaluate(con, truth, model=model, keyframes=keyframes, label_map=label_map,
                           sweep_tau="0.05:0.25:0.01" if sweep_tau is None else sweep_tau)
        taus = sorted({c.tau for c in m.classes})
        figures.plot_tau_sweep(results, tau=taus[0] if len(taus) == 1 else None, path=out,
                               title=f"model {model} against {Path(truth).name}")
    else:
        if motion is None:
            raise ParameterError(f"the {figure} figure needs a motion (--motion ID or NAME)")
        v = motion_view(con, motion, model=model, tau=tau, keyframes=keyframes, truth=truth, label_map=label_map)
        title = f"{v.name} — model {model}{' with keyframes' if v.keyframes else ''}"
        if figure == "delta":
            figures.plot_delta(v.class_delta, v.class_names, v.taus, fps=v.fps, segments=v.segments,
                               class_labels=v.class_labels, truth=v.truth, path=out, title=title)
        else:
            figures.plot_timeline(v.segments, v.labels, v.n_frames, label_delta=v.label_delta, fps=v.fps,
                                  truth=v.truth, path=out, title=title)


def view(con, motion=None, *, out=None, all=None, model=DEFAULT_MODEL, tau=None, keyframes=None, truth=None,
         label_map=None, progress=None):
    """Write a self-contained HTML page showing a motion: the skeleton animated above its labels.

    The page (no network, no libraries: inline CSS, JavaScript and data)
    shows the skeleton in 3-D (orbit, zoom, play/pause, scrubber, speed),
    the annotation as a timeline with one colour per label, the ground truth
    in a lane of its own, and Δ̄^τ per label as a heat map (paper Fig. 3);
    clicking a segment seeks the animation there. The poses are re-read
    from the source file (:func:`mocapdb.viewer.motion_poses`).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion : int or str, optional
        The motion (id or name) of one page, written to ``out``.
    out : str or Path, optional, keyword-only
        The page of ``motion``.
    all : str or Path, optional, keyword-only
        Instead: a folder receiving one page per motion and ``index.html``.
    model : str, keyword-only
    tau, keyframes
        As :func:`annotate` (the page shows the segments it gives).
    truth : str or Path, optional
        Ground truth (label CSV or ELAN file) for the truth lane.
    label_map : str, Path or dict, optional
        Truth label → model label, as :func:`evaluate`.
    progress : callable, optional
        ``progress(n_done, n_total)`` per page of ``all``.

    Returns
    -------
    list of Path
        The files written (with ``all``: the index first).
    """
    options = {"model": model, "tau": tau, "keyframes": keyframes, "truth": truth, "label_map": label_map}
    if all is not None:
        if motion is not None or out is not None:
            raise ParameterError("give either a motion and out (--out FILE), or all (--all DIR)")
        return write_pages(con, all, progress=progress, **options)
    if motion is None or out is None:
        raise ParameterError("give a motion and out (--out FILE), or all (--all DIR) for every motion")
    write_motion_page(con, motion, out, **options)
    return [Path(out)]

#: output formats of :func:`similar` that write files (tables, CSV and JSON are printed by the CLI)
SIMILAR_FORMATS = ("html",)


def _one_motion(con, motion):
    """The id of a motion given by id or name; a name must name one motion."""
    ids = motion_ids(con, [motion])
    if len(ids) > 1:
        raise ParameterError(f"{motion!r} names {len(ids)} motions (ids {', '.join(map(str, ids))}); give the id")
    return ids[0]


def similar(con, motion, start=None, end=None, *, start_frame=None, end_frame=None, examples=None, limit=10,
            features="all", tau=None, keyframes=None, format=None, out=None, model=DEFAULT_MODEL, progress=None):
    """Find the stretches of the archive most like a stretch of a motion (query by example).

    The stretch (the whole motion without a range) is a template of its own
    30 Hz words; Δ, its subsequence DTW with every feature weighted by its
    information in the archive, finds where it matches, the non-overlapping
    local minima are the hits, cheapest first; keyframes taken from the
    stretch preselect (README "Finding similar motions";
    :mod:`mocapdb.retrieval`). With ``examples``, a template is learned from
    all the stretches ("more like these").

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion : int or str
        Motion id or name.
    start, end : float, optional
        The range in seconds from the motion's start.
    start_frame, end_frame : int, optional, keyword-only
        Or in 30 Hz frames, 1-based inclusive (as annotation output).
    examples : sequence, optional, keyword-only
        Further example stretches: a motion (id or name, the whole of it) or
        ``(motion, start_frame, end_frame)``.
    limit : int, keyword-only, default 10
        The number of results.
    features : str or sequence of str, keyword-only, default "all"
        ``all``, ``upper`` (features 1–14), ``lower`` (15–26) or feature names
        (comma-separated or a sequence; those of the ``feature_flags`` view).
    tau : float, optional, keyword-only
        Hit threshold on the weighted Δ (default: ¾ of the query's chance level).
    keyframes : bool, optional, keyword-only
        Preselect with keyframes taken from the stretch (needs the keyframe
        index): True always, False never; default as far as the archive's size
        needs to keep the query's work within :data:`mocapdb.retrieval.CELL_BUDGET`.
    format : {"html"}, optional, keyword-only
        Also write the results as a page listing them, with a viewer page per
        motion linked at each hit (``out`` is a directory).
    out : str or Path, optional, keyword-only
    model : str, keyword-only
        The model whose annotation the viewer pages show (``format="html"``).
    progress : callable, optional, keyword-only
        ``progress(n_done, n_total)`` per viewer page written.

    Returns
    -------
    pyarrow.Table
        Columns ``document, motion_id, start_frame, end_frame, start_s, end_s,
        cost``, ranked by cost; no row overlaps another or a query stretch.

    Raises
    ------
    SchemaError
        An unknown motion.
    ParameterError
        An empty range or one outside the motion, or bad options.
    """
    if (format is None) != (out is None) or (format is not None and format not in SIMILAR_FORMATS):
        raise ParameterError(f"format and out go together, format one of {', '.join(SIMILAR_FORMATS)}; "
                             f"got format={format!r}, out={out!r}")
    stretches = [query_stretch(con, _one_motion(con, motion), start_frame, end_frame, start=start, end=end)]
    for k, ex in enumerate(examples or ()):
        if isinstance(ex, (int, np.integer, str)):
            ex = (ex, None, None)
        if not isinstance(ex, (tuple, list)) or len(ex) != 3:
            raise ParameterError(f"examples[{k}] must be a motion (id or name) or (motion, start_frame, end_frame), "
                                 f"got {ex!r}")
        stretches.append(query_stretch(con, _one_motion(con, ex[0]), ex[1], ex[2]))
    table = similar_stretches(con, stretches, limit=limit, features=features, tau=tau, keyframes=keyframes)
    if out is not None:
        write_results_pages(con, table, [s[:3] for s in stretches], out, model=model, progress=progress)
    return table


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
        ``imported`` maps archive motion ids to the new ones; ``failed`` names the refused motions.
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


def ray_annotate(sources, out, *, address=None, model=DEFAULT_MODEL, tau=None, keyframes=None, database=None,
                 asf=None, joint_map=None, marker_map=None, num_cpus=None, batch_files=BATCH_FILES,
                 bucket_motions=BUCKET_MOTIONS, overwrite=False):
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

    Returns
    -------
    mocapdb.distributed.RayReport
    """
    return run_on_ray(sources, out, address=address, model=model, tau=tau, keyframes=keyframes, database=database,
                      asf=asf, joint_map=joint_map, marker_map=marker_map, num_cpus=num_cpus,
                      batch_files=batch_files, bucket_motions=bucket_motions, overwrite=overwrite)


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


__all__ = ["warmup", "connect", "ingest", "delete", "annotate", "train", "learn_keyframes", "define_class", "evaluate",
           "report", "view", "similar", "SIMILAR_FORMATS", "create_index", "drop_index", "export_features",
           "import_features", "attach", "ray_annotate", "read_truth", "training_clips", "convert_labels", "relocate",
           "FIGURES"]
