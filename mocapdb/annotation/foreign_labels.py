"""Label files of other projects, read into label rows (``mocapdb convert-labels``).

Two shapes cover the published ground truths of motion capture archives:

* a **segment table**: a CSV with a header, one segment per row, whose
  columns have other names than mocapdb's ``document,label,start_frame,end_frame``
  (the CMU 86_09 segmentation: ``trial,segment,label,start_frame,end_frame,…``);
* **per-frame labels**: whitespace-separated label ids, one per frame or per
  block of frames, with a file of names (mocap6: one id per 12 frames of
  120 Hz, ``action_names.txt`` with ``id<TAB>name`` lines).

Both read into :data:`~mocapdb.annotation.labels.LABEL_DTYPE` rows with
frames 1-based inclusive at the rate of the file's frames, which
:func:`~mocapdb.annotation.labels.write_labels` writes as a label CSV (with
an ``fps`` column when that rate is not the recording's own).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapdb.annotation.labels import LABEL_DTYPE, csv_records, label_rows, read_text
from mocapdb.errors import ParseError, shorten

__all__ = ["read_segment_table", "read_label_names", "read_frame_labels", "read_label_file"]


def read_segment_table(path, *, document_column="document", label_column="label", start_column="start_frame",
                       end_column="end_frame", document=None):
    """Segments of a CSV whose columns are named otherwise (case-insensitive; other columns ignored).

    Parameters
    ----------
    path : str or Path
    document_column, label_column, start_column, end_column : str
        The header names of the four values (e.g. ``document_column="trial"``).
    document : str, optional
        Keep only this document's rows (the file may hold several).

    Returns
    -------
    ndarray of LABEL_DTYPE
        Frames exactly as in the file (1-based inclusive), in file order.

    Raises
    ------
    ParseError
        ``file:line: …`` on a missing column, an empty document or label, a
        non-integer frame or ``not 1 <= start <= end``; no rows (of ``document``).
    """
    cols = {"document": document_column.lower(), "label": label_column.lower(), "start": start_column.lower(),
            "end": end_column.lower()}
    rows = []
    for line, found in csv_records(path, tuple(dict.fromkeys(cols.values())),
                                   hint="; name the columns (--document-column, --label-column, --start-column, "
                                        "--end-column)"):
        rec = {k: found[v] for k, v in cols.items()}
        if document is not None and rec["document"] != document:
            continue
        if not rec["document"] or not rec["label"]:
            raise ParseError(path, line, f"empty {document_column if not rec['document'] else label_column}")
        try:
            s, e = int(rec["start"]), int(rec["end"])
        except ValueError:
            raise ParseError(path, line, f"{start_column} and {end_column} must be integer frames, got "
                             f"{shorten(rec['start'], 20)}, {shorten(rec['end'], 20)}") from None
        if not 1 <= s <= e:
            raise ParseError(path, line, f"need 1 <= {start_column} <= {end_column} (1-based frames), got {s}, {e}")
        rows.append((rec["document"], rec["label"], s, e))
    if not rows:
        raise ParseError(path, None, "no segments" + (f" of document {document!r}" if document is not None else ""))
    d, lab, s, e = zip(*rows)
    return label_rows(list(d), list(lab), s, e)


def read_label_names(path) -> dict:
    """Label id → name of a names file: lines ``<id> <name>`` (tab or spaces), ``#`` comments.

    Raises
    ------
    ParseError
        On a line that is not an integer id and a name, or an id given twice.
    """
    out = {}
    for k, line in enumerate(read_text(path).splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split(None, 1)
        if len(parts) != 2 or not parts[0].lstrip("-").isdigit():
            raise ParseError(path, k, f"expected '<id> <name>', got {shorten(line)}")
        if int(parts[0]) in out:
            raise ParseError(path, k, f"label id {parts[0]} is named twice")
        out[int(parts[0])] = parts[1].strip()
    return out


def read_frame_labels(path, *, document, names=None, frames_per_label=1, n_frames=None):
    """Segments of a per-frame label file: one label id per block of ``frames_per_label`` frames.

    Parameters
    ----------
    path : str or Path
        Whitespace-separated integer label ids.
    document : str
    names : mapping of int to str, optional
        Label names (:func:`read_label_names`); default the ids as text.
    frames_per_label : int, default 1
        Frames of the recording each id covers (mocap6: 12 of 120 Hz).
    n_frames : int, optional
        The recording's frames: blocks that start beyond it are dropped,
        the last segment ends at it (the last block may be partial).

    Returns
    -------
    ndarray of LABEL_DTYPE
        One segment per run of equal ids, frames 1-based inclusive.

    Raises
    ------
    ParseError
        On a token that is not an integer, or an id ``names`` lacks.
    """
    if int(frames_per_label) < 1:
        raise ParseError(path, None, f"frames per label must be >= 1, got {frames_per_label}")
    block = int(frames_per_label)
    tokens = read_text(path).split()
    try:
        ids = np.array([int(t) for t in tokens], dtype=np.int64)
    except ValueError:
        bad = next(t for t in tokens if not t.lstrip("-").isdigit())
        raise ParseError(path, None, f"expected whitespace-separated integer label ids, got {shorten(bad, 20)} "
                         f"(token {tokens.index(bad) + 1})") from None
    if names is not None:
        unknown = sorted(set(ids.tolist()) - set(names))
        if unknown:
            raise ParseError(path, None, f"label ids {unknown[:10]} are not in the names file")
    if n_frames is not None:
        ids = ids[:-(-int(n_frames) // block)]  # blocks past the recording
    if ids.size == 0:
        return np.empty(0, LABEL_DTYPE)
    cut = np.flatnonzero(np.diff(ids)) + 1
    first = np.concatenate(([0], cut))
    last = np.concatenate((cut, [ids.size])) - 1
    ends = (last + 1) * block if n_frames is None else np.minimum((last + 1) * block, int(n_frames))
    labels = [names[i] if names is not None else str(i) for i in ids[first].tolist()]
    return label_rows(document, labels, first * block + 1, ends)


def read_label_file(path, *, document=None, document_column="document", label_column="label",
                    start_column="start_frame", end_column="end_frame", names=None, frames_per_label=None, fps=None,
                    length=None):
    """A segment table or, with ``names`` or ``frames_per_label``, per-frame labels (``convert-labels``).

    Parameters
    ----------
    document : str, optional
        Per-frame labels: the document (default: the file's stem); a segment
        table: keep only its rows.
    document_column, label_column, start_column, end_column : str
        As :func:`read_segment_table`.
    names : str or Path, optional
        As :func:`read_label_names`.
    frames_per_label : int, optional
        As :func:`read_frame_labels` (default 1).
    fps : float, optional
        The rate of the file's frames, when it is not the recording's.
    length : (int, float), optional
        The recording's native frames and rate: per-frame labels end at its
        last frame.

    Returns
    -------
    ndarray of LABEL_DTYPE
    """
    if frames_per_label is None and names is None:
        return read_segment_table(path, document_column=document_column, label_column=label_column,
                                  start_column=start_column, end_column=end_column, document=document)
    n_frames = None
    if length is not None:
        n, rate = length
        n_frames = n if fps is None else int(np.floor((n - 1) * float(fps) / rate + 1e-9)) + 1
    return read_frame_labels(path, document=Path(path).stem if document is None else document,
                             names=None if names is None else read_label_names(names),
                             frames_per_label=1 if frames_per_label is None else frames_per_label, n_frames=n_frames)
