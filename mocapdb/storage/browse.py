"""The archive as ``mocapdb serve`` shows it: pages of motions with their label strips, one motion, a label's segments.

Every function only reads (serve opens the database read-only). A page of
the archive is one query (``sql/browse.sql``, ``motion_page``): the filters —
a label among the motion's stored segments, the source format, a substring
of the name or of the source path (its folder), the duration — one of :data:`SORTS`, ``LIMIT``/``OFFSET``, and
the number of motions kept as a window count beside the rows. The label
strips are then read for the page's motions only (``page_segments``: a
semi-join on their ids, never the archive's annotations), so a page costs
the same on a 100-hour archive as on a small one apart from the scan of
``motions``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError, SchemaError
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.sqltext import statement

__all__ = ["SORTS", "STRIP_BINS", "MAX_LIMIT", "MAX_OFFSET", "MotionPage", "motion_page", "motion_row",
           "motion_segments", "label_segments", "model_labels", "known_labels"]

#: the orders of a page: a column, ``-`` for descending (``id``: ingest order)
SORTS = ("id", "-id", "name", "-name", "seconds", "-seconds", "format", "-format", "rate", "-rate")
#: cells of a motion's label strip (a strip is drawn ~240 px wide: two pixels a cell)
STRIP_BINS = 120
#: the most rows one page or one request returns
MAX_LIMIT = 500
#: the largest offset of a page (motion ids and segment counts are 32-bit in the schema; a larger offset
#: would reach DuckDB as an integer it cannot take, not as an empty page)
MAX_OFFSET = 2**31 - 1


def _sql(name):
    return statement("browse.sql", name)


@dataclass(frozen=True)
class MotionPage:
    """One page of the archive.

    Attributes
    ----------
    rows : list of dict
        Per motion: ``motion_id``, ``name``, ``format``, ``source_fps``,
        ``fps``, ``n_frames``, ``seconds``, ``source_path``, ``folder`` (the
        source path's folder), ``labels`` (the labels of its stored
        segments, most time first), ``strip``: runs ``[label, first, last,
        row]`` of :data:`STRIP_BINS` cells over the motion's duration (a cell
        holds a label when a segment of it covers part of the cell), and
        ``strip_rows``: concurrent labels (a ``turn`` during a ``move``) are
        drawn on rows of their own, a label on the first row where none of
        its cells meets another label's.
    total : int
        The motions the filters keep (all pages).
    """

    rows: list
    total: int


def _check_limit(limit, offset):
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or not 1 <= limit <= MAX_LIMIT:
        raise ParameterError(f"limit must be an integer from 1 to {MAX_LIMIT}, got {limit!r}")
    if isinstance(offset, bool) or not isinstance(offset, (int, np.integer)) or not 0 <= offset <= MAX_OFFSET:
        raise ParameterError(f"offset must be an integer from 0 to {MAX_OFFSET}, got {offset!r}")


def _check_seconds(name, value):
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number of seconds, got {value!r}") from None
    if not math.isfinite(v) or v < 0:
        raise ParameterError(f"{name} must be a finite number of seconds >= 0, got {value!r}")
    return v


def _runs(cells):
    """Runs ``(first, last)`` of consecutive cells of a sorted list."""
    runs, start = [], cells[0]
    for prev, c in zip(cells, cells[1:]):
        if c != prev + 1:
            runs.append((start, prev))
            start = c
    runs.append((start, cells[-1]))
    return runs


def _strips(rows, segments):
    """Each row's labels (most covered time first), label strip and strip rows, from the page's segments."""
    by_motion = {}
    for mid, label, a, b in zip(segments["motion_id"].tolist(), segments["label"].tolist(),
                                segments["start_frame"].tolist(), segments["end_frame"].tolist()):
        by_motion.setdefault(mid, []).append((label, a, b))
    for row in rows:
        n = max(int(row["n_frames"]), 1)
        cells, covered = {}, {}
        for label, a, b in by_motion.get(row["motion_id"], ()):
            covered[label] = covered.get(label, 0) + (b - a + 1)
            first, last = (a - 1) * STRIP_BINS // n, min((b - 1) * STRIP_BINS // n, STRIP_BINS - 1)
            cells.setdefault(label, set()).update(range(first, last + 1))
        labels = sorted(covered, key=lambda lab: (-covered[lab], lab))
        # the label covering most time on the first row; each other on the first row it does not share a cell
        # of (a few labels per motion: at most STRIP_BINS cells each)
        taken, strip = [], []
        for label in labels:
            on = cells[label]
            k = next((k for k, used in enumerate(taken) if not used & on), len(taken))
            if k == len(taken):
                taken.append(set())
            taken[k] |= on
            strip.extend([label, a, b, k] for a, b in _runs(sorted(on)))
        row["labels"] = labels
        row["strip"] = sorted(strip, key=lambda s: (s[1], s[3], s[0]))
        row["strip_rows"] = max(len(taken), 1)
    return rows


def motion_page(con, *, label=None, format=None, q=None, min_s=None, max_s=None, sort="id", limit=50, offset=0,
                model=DEFAULT_MODEL) -> MotionPage:
    """One page of the archive's motions, filtered and sorted, with their label strips.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    label : str, optional, keyword-only
        Keep motions with a stored segment of this label (of ``model``).
    format : str, optional
        Keep motions of this source format (``amc``, ``bvh``, ``c3d``, …).
    q : str, optional
        Keep motions whose name contains this (ignoring case).
    min_s, max_s : float, optional
        Keep motions lasting at least / at most this many seconds.
    sort : str, default "id"
        One of :data:`SORTS`.
    limit : int, default 50
        Rows of the page (1 … :data:`MAX_LIMIT`).
    offset : int, default 0
        Rows skipped before the page.
    model : str
        The model whose stored segments (``annotations``) give labels and strips.

    Returns
    -------
    MotionPage

    Raises
    ------
    ParameterError
        A sort not in :data:`SORTS`, a bad limit, offset or duration, a label
        neither of the model nor among its stored segments (the message lists them).
    """
    if sort not in SORTS:
        raise ParameterError(f"sort must be one of {', '.join(SORTS)}, got {sort!r}")
    _check_limit(limit, offset)
    if label:
        _check_label(con, label, model)
    params = {"label": label or None, "format": format or None, "q": q or None,
              "min_s": _check_seconds("min_s", min_s), "max_s": _check_seconds("max_s", max_s), "model": model}
    cur = con.execute(_sql("motion_page"), {**params, "sort": sort, "limit": int(limit), "offset": int(offset)})
    cols = [d[0] for d in cur.description]
    rows = [dict(zip(cols, r)) for r in cur.fetchall()]
    if rows:
        total = int(rows[0]["total"])
    else:
        total = int(con.execute(_sql("motion_count"), params).fetchall()[0][0]) if offset else 0
    for r in rows:
        del r["total"]
    segments = con.execute(_sql("page_segments"), {"model": model, "ids": [r["motion_id"] for r in rows]}
                           ).fetchnumpy() if rows else None
    return MotionPage(_strips(rows, segments) if rows else rows, total)


def motion_row(con, motion_id, *, model=DEFAULT_MODEL) -> dict:
    """One motion's row (``motions`` columns, ``seconds``) with its stored labels and label strip
    (as :class:`MotionPage` rows).

    Raises
    ------
    SchemaError
        No motion with this id.
    """
    cur = con.execute(_sql("motion_row"), {"id": int(motion_id)})
    cols = [d[0] for d in cur.description]
    found = cur.fetchall()
    if not found:
        raise SchemaError(f"no motion with id {motion_id} (see: SELECT motion_id, name FROM motions)")
    row = dict(zip(cols, found[0]))
    row["ingested_at"] = str(row["ingested_at"])
    segments = con.execute(_sql("page_segments"), {"model": model, "ids": [int(motion_id)]}).fetchnumpy()
    return _strips([row], segments)[0]


def motion_segments(con, motion_id, *, model=DEFAULT_MODEL) -> list:
    """One motion's stored segments of a model (``label``, ``start_frame``, ``end_frame``, ``start_s``,
    ``end_s``, ``cost``, ``confidence``; 30 Hz frames, 1-based inclusive), in time order."""
    cur = con.execute(_sql("motion_segments"), {"model": model, "id": int(motion_id)})
    cols = [d[0] for d in cur.description]
    return [dict(zip(cols, r)) for r in cur.fetchall()]


def label_segments(con, label, *, model=DEFAULT_MODEL, limit=50, offset=0):
    """Every stored segment of a label across the archive, a page at a time (longest first).

    Returns
    -------
    rows : list of dict
        ``motion_id``, ``name``, ``start_frame``, ``end_frame`` (30 Hz, 1-based
        inclusive), ``start_s``, ``end_s``, ``cost``, ``confidence``.
    total : int
        The label's segments in all.
    """
    if not label:
        raise ParameterError("label must be a label name, got an empty one")
    _check_limit(limit, offset)
    _check_label(con, label, model)
    cur = con.execute(_sql("label_segments"), {"model": model, "label": str(label), "limit": int(limit),
                                               "offset": int(offset)})
    cols = [d[0] for d in cur.description]
    rows = [dict(zip(cols, r)) for r in cur.fetchall()]
    total = int(rows[0]["total"]) if rows else 0
    for r in rows:
        del r["total"]
    return rows, total


def _check_label(con, label, model):
    known = known_labels(con, model)
    if label not in known:
        raise ParameterError(f"{label!r} is not a label of model {model!r}; its labels: "
                             f"{', '.join(known) or 'none (the model is not in this database)'}")


def known_labels(con, model=DEFAULT_MODEL) -> list:
    """The labels a filter may name: the model's own (in its label order), then any other its stored
    segments hold (segments annotated before the model was redefined)."""
    own = model_labels(con, model)
    stored = [r[0] for r in con.execute(_sql("stored_labels"), {"model": model}).fetchall()]
    return own + [lab for lab in stored if lab not in own]


def model_labels(con, model=DEFAULT_MODEL) -> list:
    """A model's labels in its label order (empty when the database lacks the model)."""
    return [r[0] for r in con.execute(_sql("model_labels"), {"model": model}).fetchall()]
