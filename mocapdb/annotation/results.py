"""Annotation results as a table: the one shape of segments for the API, the CLI and SQL.

:func:`segment_table` turns the segments of :func:`mocapdb.annotation.annotate`
(0-based inclusive frames per document) into rows with 1-based inclusive
30 Hz frames and seconds, ordered by document, start frame and label — what
``mocapdb.api.annotate`` returns, the CLI prints and the SQL ``annotate()``
returns per motion.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from mocapdb.errors import ParameterError

#: columns of :func:`segment_table` (frames 1-based, inclusive, at the feature rate)
SEGMENT_COLUMNS = ("motion_id", "document", "label", "start_frame", "end_frame", "start_s", "end_s", "cost")


def segment_table(segments, *, motion_ids, names, fps) -> pa.Table:
    """Segments as an Arrow table with the columns :data:`SEGMENT_COLUMNS`.

    Parameters
    ----------
    segments : ndarray of mocapdb.annotation.SEGMENT_DTYPE
        ``doc`` indexes the documents below.
    motion_ids : (n_docs,) int
    names : sequence of str, length n_docs
    fps : (n_docs,) float
        Rate of the frames (the feature rate, 30 Hz); frame k (0-based) starts
        at k / fps seconds, so a segment [s, e] spans s / fps to (e + 1) / fps.

    Returns
    -------
    pyarrow.Table
        Sorted by (document order, start frame, label).
    """
    ids = np.asarray(motion_ids, dtype=np.int32)
    fps = np.asarray(fps, dtype=np.float64)
    if not (ids.shape == fps.shape == (len(names),)):
        raise ParameterError(f"motion_ids, names and fps must have one entry per document, got "
                             f"{ids.shape}, {len(names)}, {fps.shape}")
    segs = segments[np.lexsort((segments["label"], segments["start"], segments["doc"]))]
    doc = segs["doc"]
    seg_fps = fps[doc]
    return pa.table({
        "motion_id": pa.array(ids[doc], pa.int32()),
        "document": pa.array(np.asarray(names, dtype=object)[doc] if len(doc) else [], pa.string()),
        "label": pa.array(segs["label"].tolist(), pa.string()),
        "start_frame": pa.array(segs["start"] + 1, pa.int32()),
        "end_frame": pa.array(segs["end"] + 1, pa.int32()),
        "start_s": pa.array(segs["start"] / seg_fps, pa.float64()),
        "end_s": pa.array((segs["end"] + 1) / seg_fps, pa.float64()),
        "cost": pa.array(segs["cost"], pa.float64()),
    })


__all__ = ["SEGMENT_COLUMNS", "segment_table"]
