"""Plotting helpers (optional dependency: ``pip install mocapdb[plot]``).

matplotlib is imported lazily, so ``import mocapdb.evaluation.figures`` works without it;
the functions raise ImportError with the install hint when it is missing.
No function shows a window: they return the Figure and optionally save it.
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.learning import GAStatistics

__all__ = ["plot_ga_statistics", "plot_ga_curve", "plot_annotation", "plot_timeline", "plot_delta", "plot_template",
           "plot_tau_sweep"]


def _pyplot():
    try:
        import matplotlib
        if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo"):
            matplotlib.use("Agg")  # no display needed; figures are written to files
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("plotting needs matplotlib: pip install 'mocapdb[plot]'") from e
    return plt


def _finish(fig, ax, title, path, dpi):
    if title:
        ax.set_title(title)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig


def plot_ga_statistics(statistics, path=None, *, title=None, show_best=True, dpi=150):
    """Average precision, recall and fitness over the GA generations (paper Fig. 5).

    Parameters
    ----------
    statistics : GAStatistics
        E.g. :func:`mocapdb.learning.average_statistics` of the results of all
        classes (averages over the individuals of a population and over
        classes and runs, as in the paper).
    path : str or Path, optional
        Write the figure there (format from the suffix, e.g. ``.png``).
    title : str, optional
    show_best : bool, default True
        Also draw the fitness of the best individual (dashed).
    dpi : int, default 150

    Returns
    -------
    matplotlib.figure.Figure

    References
    ----------
    Paper Sect. 7, Fig. 5: precision (black), recall (red), fitness (green).
    """
    if not isinstance(statistics, GAStatistics):
        raise ParameterError(f"statistics must be a GAStatistics (see "
                             f"mocapdb.learning.average_statistics), got {type(statistics).__name__}")
    plt = _pyplot()
    g = np.arange(statistics.generations + 1)
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    ax.plot(g, statistics.mean_precision, color="black", label="precision")
    ax.plot(g, statistics.mean_recall, color="red", label="recall")
    ax.plot(g, statistics.mean_fitness, color="green", label="fitness (F$_2$)")
    if show_best:
        ax.plot(g, statistics.best_fitness, color="green", linestyle="--", linewidth=0.8,
                label="best fitness")
    ax.set_xlabel("generation")
    ax.set_ylabel("population average")
    ax.set_xlim(0, max(1, statistics.generations))
    lo = min(statistics.mean_precision.min(), statistics.mean_recall.min())
    ax.set_ylim(max(0.0, np.floor(lo * 10) / 10 - 0.05), 1.01)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    return _finish(fig, ax, title, path, dpi)


def plot_ga_curve(rows, path=None, *, title=None, dpi=150):
    """Paper Fig. 5 from per-generation averages as stored in ``ga_statistics``.

    Parameters
    ----------
    rows : mapping of str to (n_generations,) arrays
        ``mean_precision``, ``mean_recall``, ``mean_fitness``, ``best_fitness``,
        ``mean_keyframes`` per generation (averaged over classes and runs).
    """
    cols = [np.asarray(rows[k], np.float64) for k in ("mean_precision", "mean_recall", "mean_fitness",
                                                      "best_fitness", "mean_keyframes")]
    nan = np.full_like(cols[0], np.nan)
    stats = GAStatistics(cols[0], cols[1], cols[2], cols[3], nan, nan, cols[4])
    return plot_ga_statistics(stats, path, title=title, dpi=dpi)


def plot_annotation(segments, labels, n_frames, *, label_delta=None, fps=30.0, truth=None, path=None,
                    title=None, dpi=150):
    """An annotated motion as a timeline (paper Fig. 6): one row per label.

    Parameters
    ----------
    segments : ndarray of mocapdb.annotation.SEGMENT_DTYPE
        Segments of one document (0-based inclusive 30 Hz frames).
    labels : sequence of str
        Row order (the model's labels).
    n_frames : int
        Length of the motion in 30 Hz frames.
    label_delta : (n_labels, n_frames) float, optional
        Δ̄^τ per label (the segmenter's input, ``annotate(..., keep_deltas=True).label_delta``),
        drawn as a curve in each row (inf = not drawn).
    fps : float, default 30
        Feature frame rate, for the time axis in seconds.
    truth : ndarray of LABEL_DTYPE, optional
        Ground truth on the same grid, drawn as grey bars under the segments.
    path : str or Path, optional
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """

    plt = _pyplot()
    labels = list(labels)
    n = len(labels)
    fig, ax = plt.subplots(figsize=(8.0, 0.45 * n + 1.2))
    t = np.arange(n_frames) / fps
    colors = plt.get_cmap("tab10")
    for k, lab in enumerate(labels):
        y = n - 1 - k
        if truth is not None:
            for r in truth[truth["label"] == lab]:
                ax.barh(y, (r["end"] - r["start"] + 1) / fps, left=r["start"] / fps, height=0.8,
                        color="0.85", edgecolor="none")
        for s in segments[segments["label"] == lab]:
            ax.barh(y, (s["end"] - s["start"] + 1) / fps, left=s["start"] / fps, height=0.45,
                    color=colors(k % 10), edgecolor="none")
        if label_delta is not None:
            d = np.asarray(label_delta[k], dtype=np.float64)
            top = np.nanmax(np.where(np.isfinite(d), d, np.nan)) if np.isfinite(d).any() else 1.0
            ax.plot(t, y - 0.4 + 0.8 * np.where(np.isfinite(d), d / max(top, 1e-9), np.nan), color="black",
                    linewidth=0.6)
    ax.set_yticks(range(n))
    ax.set_yticklabels(labels[::-1])
    ax.set_xlim(0, max(n_frames / fps, 1e-3))
    ax.set_ylim(-0.6, n - 0.4)
    ax.set_xlabel("time [s]")
    return _finish(fig, ax, title, path, dpi)


#: paper Fig. 6/7 is a timeline of labels: the name ``report --figure timeline`` uses
plot_timeline = plot_annotation


def plot_delta(class_delta, class_names, taus, *, fps=30.0, segments=None, class_labels=None, truth=None,
               path=None, title=None, dpi=150):
    """Δ̄^τ per class over time as a heat map, white above τ (paper Fig. 3a), with the segments below (Fig. 3b).

    Parameters
    ----------
    class_delta : (n_classes, n_frames) float
        Δ̄^τ per class (``annotate(..., keep_deltas=True).classification_delta``):
        finite values are ≤ the class's τ, inf elsewhere.
    class_names : sequence of str
        Row names.
    taus : (n_classes,) float
        The τ of each class; the colour scale runs from 0 to the largest and
        the colour bar marks each τ.
    fps : float, default 30
    segments : ndarray of SEGMENT_DTYPE, optional
        The resulting annotation (red blocks, Fig. 3b) in a panel below, one
        row per label (needs ``class_labels``).
    class_labels : sequence of str, optional
        Label of each class (the rows of the lower panel, in order of first use).
    truth : ndarray of LABEL_DTYPE, optional
        Ground truth on the same grid (black blocks under the red ones).
    path, title, dpi
        As :func:`plot_annotation`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _pyplot()
    d = np.asarray(class_delta, np.float64)
    taus = np.broadcast_to(np.asarray(taus, np.float64), (d.shape[0],))
    if d.ndim != 2 or d.shape[0] != len(class_names):
        raise ParameterError(f"class_delta must have one row per class ({len(class_names)}), got shape {d.shape}")
    n_cls, n = d.shape
    top = float(taus.max()) if taus.size else 1.0
    shown = np.ma.masked_where(~np.isfinite(d) | (d > taus[:, None]), d)
    has_blocks = segments is not None or truth is not None
    fig, axes = plt.subplots(2 if has_blocks else 1, 1, figsize=(8.0, 0.3 * n_cls + (2.4 if has_blocks else 1.4)),
                             sharex=True, squeeze=False,
                             gridspec_kw={"height_ratios": [n_cls, max(2, n_cls // 2)]} if has_blocks else None)
    ax = axes[0, 0]
    cmap = plt.get_cmap("jet").with_extremes(bad="white")  # above τ: white, as in the paper
    im = ax.imshow(shown, aspect="auto", interpolation="nearest", cmap=cmap, vmin=0.0, vmax=top,
                   extent=(0, n / fps, n_cls - 0.5, -0.5))
    ax.set_yticks(range(n_cls))
    ax.set_yticklabels(list(class_names), fontsize=7)
    bar = fig.colorbar(im, ax=axes[:, 0].tolist(), pad=0.01, fraction=0.04)
    levels = np.unique(taus)
    for t in levels:
        bar.ax.axhline(t, color="black", linewidth=1.2)
    # the bar's own ticks read as Δ̄ values; the black lines are the τ (one per class): "τ=" on every
    # tick read as though each value were a τ
    bar.set_label(f"Δ̄^τ (line: τ = {levels[0]:g}; white: above it)" if len(levels) == 1 else
                  f"Δ̄^τ (lines: the classes' τ, {levels[0]:g}–{levels[-1]:g}; white: above a class's τ)")
    if has_blocks:
        bx = axes[1, 0]
        lab = list(dict.fromkeys(class_labels)) if class_labels is not None else []
        rows = {x: k for k, x in enumerate(lab)}
        for rows_arr, color, h in ((truth, "black", 0.8), (segments, "red", 0.45)):
            if rows_arr is None:
                continue
            for r in rows_arr:
                y = rows.get(str(r["label"]))
                if y is not None:
                    bx.barh(y, (r["end"] - r["start"] + 1) / fps, left=r["start"] / fps, height=h, color=color,
                            edgecolor="none")
        bx.set_yticks(range(len(lab)))
        bx.set_yticklabels(lab, fontsize=7)
        bx.set_ylim(len(lab) - 0.5, -0.5)
        bx.set_xlabel("time [s]")
    else:
        ax.set_xlabel("time [s]")
    ax.set_xlim(0, max(n / fps, 1e-3))
    if title:
        ax.set_title(title)
    if path is not None:
        fig.savefig(path, dpi=dpi, bbox_inches="tight")
    return fig


def plot_template(quantized, real=None, *, feature_names=None, fps=30.0, path=None, title=None, dpi=150):
    """A class motion template, real-valued and quantized (paper Fig. 1c/d).

    Parameters
    ----------
    quantized : (K, 40) float
        The quantized template as 0 / 1 / 0.5 (wildcard), e.g.
        ``QuantizedTemplate.dense()``: black 0, white 1, red wildcard.
    real : (K', 40) float, optional
        The real-valued template (values in [0, 1]): black 0, white 1,
        colours in between (inconsistent across the training clips).
    feature_names : sequence of str, optional
        Row labels (default: the feature numbers 1–40).
    fps : float, default 30
        Columns per second, for the time axis.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.colors import ListedColormap

    plt = _pyplot()
    panels = [("real", np.asarray(real, np.float64))] if real is not None else []
    panels.append(("quantized", np.asarray(quantized, np.float64)))
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.0, 3.4 * len(panels)), squeeze=False)
    for ax, (kind, m) in zip(axes[:, 0], panels):
        if m.ndim != 2 or m.shape[1] != 40:
            raise ParameterError(f"the {kind} template must have shape (K, 40), got {m.shape}")
        k = m.shape[0]
        if kind == "real":
            im = ax.imshow(m.T, aspect="auto", interpolation="nearest", cmap="hot", vmin=0, vmax=1,
                           extent=(0, k / fps, 40.5, 0.5))
            fig.colorbar(im, ax=ax, pad=0.01, fraction=0.04)
            ax.set_title("real-valued MT (Fig. 1c)" if not title else f"{title}: real-valued (Fig. 1c)")
        else:
            cmap = ListedColormap(["black", "tab:red", "white"])
            ax.imshow(m.T, aspect="auto", interpolation="nearest", cmap=cmap, vmin=0, vmax=1,
                      extent=(0, k / fps, 40.5, 0.5))
            ax.set_title("quantized MT, red = wildcard (Fig. 1d)" if not title
                         else f"{title}: quantized, red = wildcard (Fig. 1d)")
        ticks = [1, 14, 15, 26, 27, 40]
        ax.set_yticks(ticks)
        ax.set_yticklabels([feature_names[t - 1] for t in ticks] if feature_names is not None else ticks,
                           fontsize=6)
        ax.set_ylabel("feature")
    axes[-1, 0].set_xlabel("template time [s]")
    return _finish(fig, axes[0, 0], None, path, dpi)


def plot_tau_sweep(results, *, tau=None, path=None, title=None, dpi=150):
    """Precision, recall and F-measure over τ, frame- and segment-based (paper Fig. 8).

    Parameters
    ----------
    results : sequence of (float, Scores)
        As ``mocapdb.api.evaluate(..., sweep_tau=...)`` returns.
    tau : float, optional
        The τ in use, marked by a dashed line.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _pyplot()
    if not results:
        raise ParameterError("results must hold at least one (tau, Scores) pair")
    t = np.array([r[0] for r in results], np.float64)
    fig, axes = plt.subplots(1, 2, figsize=(8.0, 3.2), sharey=True)
    for ax, (kind, keys) in zip(axes, (("frame-based", ("p1", "r1", "f1")), ("segment-based", ("p2", "r2", "f2")))):
        for key, color, name in zip(keys, ("black", "red", "green"), ("precision", "recall", "F-measure")):
            ax.plot(t, [getattr(sc, key) for _, sc in results], color=color, marker=".", label=name)
        if tau is not None:
            ax.axvline(tau, color="0.5", linestyle="--", linewidth=0.8)
        ax.set_title(kind)
        ax.set_xlabel("τ")
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="lower right", fontsize=8)
    if title:
        fig.suptitle(title)
    return _finish(fig, axes[0], None, path, dpi)
