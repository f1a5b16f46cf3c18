"""What users look at: the paper's figures, viewer pages, query by example and the archive's summary (the
archive in a browser is :func:`mocapdb.server.serve`, a face above this API)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapdb.api.annotating import evaluate
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.storage.browse import MAX_LIMIT
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.motions import motion_rows, one_motion
from mocapdb.storage.names import safe_stem
from mocapdb.storage.sqltext import statement
from mocapdb.storage.stats import archive_stats
from mocapdb.viewer import motion_view, write_motion_page, write_pages
from mocapdb.storage.retrieval import query_stretch, similar_stretches
from mocapdb.viewer.results import write_results_pages


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
        The motion (id or name; a name must name one motion) of one page, written to ``out``.
    out : str or Path, optional, keyword-only
        The page of ``motion`` (default: ``<motion name>.html`` in the working folder).
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
    if motion is None:
        raise ParameterError("give a motion (and out, --out FILE), or all (--all DIR) for every motion")
    mid = one_motion(con, motion)   # a name of two motions is refused, not one of them drawn
    if out is None:   # <motion name>.html in the working folder, as view --all names pages
        out = Path(safe_stem(str(motion_rows(con, [mid])["name"][0])) + ".html")
    write_motion_page(con, mid, out, **options)
    return [Path(out)]


#: output formats of :func:`similar` that write files (tables, CSV and JSON are printed by the CLI)
SIMILAR_FORMATS = ("html",)


def similar(con, motion, start=None, end=None, *, start_frame=None, end_frame=None, examples=None, limit=10,
            features="all", tau=None, keyframes=None, format=None, out=None, model=DEFAULT_MODEL, progress=None):
    """Find the stretches of the archive most like a stretch of a motion (query by example).

    The stretch (the whole motion without a range) is a template of its own
    30 Hz words; Δ, its subsequence DTW with every feature weighted by its
    information in the archive, finds where it matches, the non-overlapping
    local minima are the hits, cheapest first; keyframes taken from the
    stretch preselect (docs/USER_GUIDE.md "Finding similar motions";
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
        The number of results (1 … :data:`mocapdb.storage.browse.MAX_LIMIT`).
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
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or not 1 <= limit <= MAX_LIMIT:
        # a page of results, as every listing of mocapdb (``mocapdb serve`` too): each one ranked costs work
        raise ParameterError(f"limit must be an integer from 1 to {MAX_LIMIT}, got {limit!r}")
    if (format is None) != (out is None) or (format is not None and format not in SIMILAR_FORMATS):
        raise ParameterError(f"format and out go together, format one of {', '.join(SIMILAR_FORMATS)}; "
                             f"got format={format!r}, out={out!r}")
    stretches = [query_stretch(con, one_motion(con, motion), start_frame, end_frame, start=start, end=end)]
    for k, ex in enumerate(examples or ()):
        if isinstance(ex, (int, np.integer, str)):
            ex = (ex, None, None)
        if not isinstance(ex, (tuple, list)) or len(ex) != 3:
            raise ParameterError(f"examples[{k}] must be a motion (id or name) or (motion, start_frame, end_frame), "
                                 f"got {ex!r}")
        stretches.append(query_stretch(con, one_motion(con, ex[0]), ex[1], ex[2]))
    table = similar_stretches(con, stretches, limit=limit, features=features, tau=tau, keyframes=keyframes)
    if out is not None:
        write_results_pages(con, table, [s[:3] for s in stretches], out, model=model, progress=progress)
    return table


def stats(con, *, model=DEFAULT_MODEL):
    """What the archive holds: hours and motions per source format and rate, annotated hours per label,
    and the files its ingests refused.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        The model whose stored annotations (``annotations``) give the hours per label.

    Returns
    -------
    mocapdb.storage.stats.ArchiveStats
        Arrow tables ``formats`` (``format, source_fps, motions, hours``),
        ``labels`` (``label, segments, motions, hours``) and ``refused``
        (``path, member, outcome, reason, logged_at`` of each file whose latest
        ingest failed or found no motion; None when the database keeps no
        ingest log), and the totals ``motions`` and ``hours``.
    """
    return archive_stats(con, model=model)
