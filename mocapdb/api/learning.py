"""Models from labelled clips: templates (``train``), hand-designed classes (``define_class``)
and keyframe queries (``learn_keyframes``)."""
from __future__ import annotations

import dataclasses

from mocapdb.annotation import class_labels, label_documents, read_class_labels, read_truth
from mocapdb.errors import ParameterError
from mocapdb.annotation import Model
from mocapdb.learning import clips_from_folders, clips_from_segments, learn_keyframe_queries, train_model
from mocapdb.learning.class_definitions import apply_keyframe_definitions, compile_definitions, read_definitions
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.model_store import (DEFAULT_MODEL, SHIPPED_MODELS, ga_statistics_rows,
                                         keyframe_query_stats, model_fingerprint, model_metadata, save_model)
from mocapdb.storage.motions import documents_by_name


def _class_label_mapping(class_labels_arg, classes):
    """A class → label mapping: given as a dict or a CSV path; else the shipped HDM05
    mapping when it covers every class; else None (each class its own label)."""
    if isinstance(class_labels_arg, dict):
        return class_labels_arg
    if class_labels_arg is not None:
        return read_class_labels(class_labels_arg)
    shipped = class_labels("hdm05")
    return shipped if all(c in shipped for c in classes) else None


def _training_clips(con, *, folder=None, labels=None, progress=None):
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
    rows = read_truth(labels, fps=docs.native_rates(), n_frames=docs.native_lengths())
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
        classes join the learned ones (docs/MODEL.md "Class definitions").

    Returns
    -------
    mocapdb.annotation.Model
    """
    clips, source = _training_clips(con, folder=folder, labels=labels, progress=progress)
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
    new = {c.name for c in designed} | {k.cls for k in keyframes if k.template}   # designed classes and copies
    clash = sorted(new & set(model.class_names))
    if clash and not replace:
        raise ParameterError(f"model {model.name!r} already has the classes {clash}; pass replace=True "
                             "(--replace) to redefine them")
    classes = tuple(c for c in model.classes if c.name not in new) + tuple(designed)
    unknown = sorted({k.template or k.cls for k in keyframes} - {c.name for c in classes})
    if unknown:
        raise ParameterError(f"keyframe definitions name classes {unknown} that model {model.name!r} does not "
                             f"have; its classes: {', '.join(c.name for c in classes)}")
    classes, copies = apply_keyframe_definitions(classes, keyframes)
    classes += copies
    labels = tuple(dict.fromkeys(list(model.labels) + [c.label for c in designed]))
    return dataclasses.replace(model, classes=classes, labels=labels)


def define_class(con, definitions, *, model=DEFAULT_MODEL, replace=False, description=None):
    """Add hand-designed classes from class definition files to a model (paper Sect. 8).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    definitions : str, Path or sequence of them
        TOML class definition files, or folders of ``*.toml`` (docs/MODEL.md
        "Class definitions"); each class compiles to a quantized template
        and a keyframe query (:mod:`mocapdb.learning.class_definitions`);
        a ``[[keyframes]]`` table gives a class of the model a designed
        keyframe query (with ``template``, a copy of that class with the
        query: a class of its own).
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
        elif c.keyframe_query is not None and c.keyframe_query is not before.get(c.name):
            stats[c.name] = {"source": "keyframe definition"}   # a class's own, or a copy's
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
    clips, source = _training_clips(con, folder=folder, labels=labels)
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
