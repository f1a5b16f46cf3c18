"""Annotation results as a table: the one shape of segments for the API, the CLI and SQL.

:func:`segment_table` turns the segments of :func:`mocapdb.annotation.annotate`
(0-based inclusive frames per document) into rows with 1-based inclusive
30 Hz frames and seconds, ordered by document, start frame and label — what
``mocapdb.api.annotate`` returns, the CLI prints and the SQL ``annotate()``
returns per motion. :data:`SEGMENT_SCHEMA` is the one definition of a
segment's fields and types; the SQL functions derive their segment type from
:data:`SEGMENT_ARROW`.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from mocapdb.errors import ParameterError

#: Arrow schema of :func:`segment_table` (frames 1-based, inclusive, at the feature rate; seconds)
SEGMENT_SCHEMA = pa.schema([("motion_id", pa.int32()), ("document", pa.string()), ("label", pa.string()),
                            ("start_frame", pa.int32()), ("end_frame", pa.int32()), ("start_s", pa.float64()),
                            ("end_s", pa.float64()), ("cost", pa.float64()), ("confidence", pa.float64())])
#: columns of :func:`segment_table`
SEGMENT_COLUMNS = tuple(SEGMENT_SCHEMA.names)
#: a segment of one motion, as SQL ``annotate(motion_id)`` lists them (the motion is the row's)
SEGMENT_ARROW = pa.struct([SEGMENT_SCHEMA.field(name) for name in
                           ("label", "start_frame", "end_frame", "cost", "start_s", "end_s", "confidence")])


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
    return pa.Table.from_pydict({
        "motion_id": ids[doc],
        "document": np.asarray(names, dtype=object)[doc] if len(doc) else [],
        "label": segs["label"].tolist(),
        "start_frame": segs["start"] + 1,
        "end_frame": segs["end"] + 1,
        "start_s": segs["start"] / seg_fps,
        "end_s": (segs["end"] + 1) / seg_fps,
        "cost": segs["cost"],
        "confidence": segs["confidence"],
    }, schema=SEGMENT_SCHEMA)


__all__ = ["SEGMENT_SCHEMA", "SEGMENT_COLUMNS", "SEGMENT_ARROW", "segment_table"]
