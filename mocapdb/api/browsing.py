"""The archive as a list: pages of motions with their labels, one motion with its stored segments, a label's
segments across the archive. ``mocapdb motions`` and the pages of ``mocapdb serve`` are these functions."""
from __future__ import annotations

from mocapdb.storage import browse
from mocapdb.storage.browse import MAX_LIMIT, SORTS, STRIP_BINS
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.motions import one_motion
from mocapdb.viewer import label_colors as _colors

__all__ = ["motions", "motion_info", "label_segments", "labels", "label_colors", "MOTION_COLUMNS", "SORTS", "MAX_LIMIT",
           "STRIP_BINS"]

#: the columns of a row of :func:`motions` (and ``mocapdb motions``), besides its strip
MOTION_COLUMNS = ("motion_id", "name", "format", "source_fps", "fps", "n_frames", "seconds", "folder",
                  "source_path", "labels")


def motions(con, *, label=None, source_format=None, q=None, min_s=None, max_s=None, sort="id", limit=50, offset=0,
            model=DEFAULT_MODEL) -> browse.MotionPage:
    """A page of the archive's motions, filtered and sorted (the archive page of ``mocapdb serve``).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    label : str, optional, keyword-only
        Keep motions with a stored segment of this label (of ``model``); a
        label the model does not know is an error listing its labels.
    source_format : str, optional, keyword-only
        Keep motions of this source format (``amc``, ``bvh``, ``c3d``, …).
    q : str, optional, keyword-only
        Keep motions whose name or source path contains this (ignoring
        case): a session's folder is a filter too.
    min_s, max_s : float, optional, keyword-only
        Keep motions lasting at least / at most this many seconds.
    sort : str, keyword-only, default "id"
        One of :data:`mocapdb.storage.browse.SORTS` (``-`` for descending).
    limit : int, keyword-only, default 50
        Rows of the page (1 … :data:`mocapdb.storage.browse.MAX_LIMIT`).
    offset : int, keyword-only, default 0
        Rows skipped before the page.
    model : str, keyword-only
        The model whose stored segments give labels and strips.

    Returns
    -------
    mocapdb.storage.browse.MotionPage
        ``rows`` (:data:`MOTION_COLUMNS`, ``strip``, ``strip_rows``) and
        ``total``, the motions the filters keep over all pages.
    """
    return browse.motion_page(con, label=label, format=source_format, q=q, min_s=min_s, max_s=max_s, sort=sort,
                              limit=limit, offset=offset, model=model)


def motion_info(con, motion, *, model=DEFAULT_MODEL) -> dict:
    """One motion (id or name; a name must name one motion): its row as :func:`motions` gives it, with
    ``n_source_frames``, ``skeleton``, ``reader_options``, ``ingested_at`` and ``segments``, its stored
    segments of ``model`` in time order (``label``, ``start_frame``, ``end_frame`` at 30 Hz, 1-based
    inclusive, ``start_s``, ``end_s``, ``cost``, ``confidence``)."""
    mid = one_motion(con, motion)
    row = browse.motion_row(con, mid, model=model)
    row["segments"] = browse.motion_segments(con, mid, model=model)
    return row


def label_segments(con, label, *, model=DEFAULT_MODEL, limit=50, offset=0):
    """Every stored segment of a label across the archive, longest first, a page at a time.

    Returns
    -------
    rows : list of dict
        ``motion_id``, ``name``, ``start_frame``, ``end_frame``, ``start_s``, ``end_s``, ``cost``, ``confidence``.
    total : int
        The label's segments in all.
    """
    return browse.label_segments(con, label, model=model, limit=limit, offset=offset)


def labels(con, *, model=DEFAULT_MODEL) -> list:
    """The labels a filter may name: the model's own in its label order, then others its stored segments hold."""
    return browse.known_labels(con, model)


def label_colors(con, *extra, model=DEFAULT_MODEL) -> dict:
    """Label → colour as every page draws it: the model's labels in their order, then ``extra`` labels."""
    return _colors(browse.model_labels(con, model), *extra)
