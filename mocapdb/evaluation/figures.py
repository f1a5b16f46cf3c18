"""Plotting helpers (optional dependency: ``pip install mocapdb[plot]``).

matplotlib is imported lazily, so ``import mocapdb.evaluation.figures`` works without it;
the functions raise ImportError with the install hint when it is missing.
No function shows a window: they return the Figure and optionally save it.
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.learning import GAStatistics

__all__ = ["plot_ga_statistics", "plot_ga_curve", "plot_annotation"]


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
