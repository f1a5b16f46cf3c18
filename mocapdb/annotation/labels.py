"""Label and ground-truth rows: CSV files, frame grids, class → label mappings.

A label (or ground-truth) CSV has the columns ``document,label,start_frame,end_frame``
(DESIGN.md §5): one labelled segment per row, frames at the document's
**native** rate, 1-based and inclusive, as in the HDM05 annotations. An
optional column ``fps`` gives the rate of a row's frames instead (the output
of ``mocapdb annotate --format csv`` carries ``fps`` = 30, so it reads back
onto its own frames; a file with the columns ``start_s,end_s`` but no
``fps``, mocapdb's output before that column, is read at 30 Hz too). Other
columns are ignored; blank lines and lines starting with ``#`` are skipped.
An ELAN ``.eaf`` file is read wherever a label CSV is (:func:`read_labels`
dispatches on the suffix; the rules are in :mod:`mocapdb.annotation.elan`).

In memory a set of segments is a structured array of :data:`LABEL_DTYPE`
(``document``, ``label``, ``start``, ``end``). Which frame grid ``start`` and
``end`` refer to is fixed by the function that produced the array:

* :func:`read_labels` / :func:`write_labels`: native rate, 1-based inclusive
  (exactly the numbers of the file);
* :func:`to_feature_grid`: the 30 Hz feature grid, 0-based inclusive (the
  numpy-level convention of :mod:`mocapdb.annotation` and :mod:`mocapdb.evaluation.metrics`);
* :func:`to_native_grid`: back to native 1-based inclusive for output.

This module is **the one place** that converts between the two grids. At
120 Hz the 30 Hz feature frame k (1-based) is native frame 4k − 3 (FEATURES.md
§1, downsampling by 4 keeping the first frame) and *covers* the native frames
4k − 3 … 4k. At another rate the factor is ``fps/30`` (:func:`native_factor`;
native frame s lies at time (s − 1)/fps and belongs to 30 Hz frame
floor((s − 1)·30/fps)); the statements below are for the factor 4. Hence a native range [s, e] covers the 30 Hz frames
ceil(s/4) … ceil(e/4) (1-based), i.e. ``(s − 1) // 4 … (e − 1) // 4`` 0-based,
and a 30 Hz range [a, b] (0-based) covers the native frames 4a + 1 … 4b + 4
(clipped to the document's length). Feature grid → native → feature grid is
the identity; native → feature grid → native widens a range to whole blocks
of 4.

A class-label mapping file (CSV ``class,label``) maps fine classes (or the
action names of a foreign label set) to the coarse labels a model annotates
with; :func:`class_labels` loads the ones shipped in ``mocapdb/shipped_models/``
(``hdm05`` — the 11 HDM05 classes of the development data, Table 1 of the
paper; ``cmu86`` and ``cmu_mocap6`` — the CMU ground-truth actions of the
development evaluation, see :mod:`mocapdb.evaluation`; ``default`` — the
learned classes of the shipped default model). Row order is kept:
it is the label order (Δarg tie order) of a model trained with it.
"""
from __future__ import annotations

import csv
import io
from importlib import resources
from pathlib import Path

import numpy as np

from mocapdb.annotation.elan import eaf_document, eaf_source_fps, is_eaf, read_eaf
from mocapdb.errors import ParameterError, ParseError
from mocapdb.features import DOWNSAMPLING_FACTOR, FEATURE_RATE, TOOLBOX_RATE

__all__ = [
    "LABEL_COLUMNS", "LABEL_DTYPE", "label_rows", "as_label_rows", "read_labels", "label_documents",
    "read_segments", "read_truth",
    "write_labels",
    "native_to_feature_frames", "feature_to_native_frames", "to_feature_grid",
    "to_native_grid", "segments_to_rows", "map_labels", "read_class_labels",
    "write_class_labels", "class_labels", "read_text", "csv_records", "SHIPPED_CLASS_LABELS", "native_factor",
]

#: the columns of a label / ground-truth CSV (DESIGN.md §5)
LABEL_COLUMNS = ("document", "label", "start_frame", "end_frame")

#: segments in memory; the frame grid of start/end depends on the producer
LABEL_DTYPE = np.dtype([("document", object), ("label", object), ("start", np.int64),
                        ("end", np.int64)])

#: class-label mapping files shipped in mocapdb/shipped_models/ (name → file)
SHIPPED_CLASS_LABELS = {
    "hdm05": "hdm05_labels.csv",
    "cmu86": "cmu86_labels.csv",
    "cmu_mocap6": "cmu_mocap6_labels.csv",
    "default": "default_labels.csv",
}


# ---------------------------------------------------------------------------
# rows


def label_rows(documents, labels, starts, ends):
    """Build an array of labelled segments (scalars broadcast).

    Parameters
    ----------
    documents, labels : str or sequence of str
    starts, ends : int or array_like of int

    Returns
    -------
    ndarray of LABEL_DTYPE
    """
    st = np.atleast_1d(np.asarray(starts, dtype=np.int64))
    en = np.atleast_1d(np.asarray(ends, dtype=np.int64))
    n = max(st.size, en.size,
            1 if isinstance(documents, str) else len(documents),
            1 if isinstance(labels, str) else len(labels))
    out = np.empty(n, dtype=LABEL_DTYPE)
    for field, x in (("document", documents), ("label", labels)):
        if isinstance(x, str):
            out[field] = [x] * n
        else:
            x = [str(v) for v in x]
            if len(x) != n:
                raise ParameterError(f"{field}s must have {n} entries, got {len(x)}")
            out[field] = x
    out["start"] = np.broadcast_to(st, (n,))
    out["end"] = np.broadcast_to(en, (n,))
    return out


def as_label_rows(rows, name="rows"):
    """Rows as a LABEL_DTYPE array (a copy).

    Parameters
    ----------
    rows : structured ndarray or iterable of (document, label, start, end)
        A structured array needs the fields ``label``, ``start``, ``end`` and
        ``document`` or ``doc`` (e.g. :data:`mocapdb.annotation.SEGMENT_DTYPE`,
        whose document index becomes its string); other fields are ignored.
    name : str
        Used in error messages.

    Returns
    -------
    ndarray of LABEL_DTYPE
    """
    if isinstance(rows, np.ndarray) and rows.dtype.names:
        names = rows.dtype.names
        doc = "document" if "document" in names else "doc" if "doc" in names else None
        if doc is None or not {"label", "start", "end"} <= set(names):
            raise ParameterError(
                f"{name} must have fields document (or doc), label, start, end; got {names}")
        out = np.empty(rows.shape[0], dtype=LABEL_DTYPE)
        out["document"] = [str(x) for x in rows[doc]]
        out["label"] = [str(x) for x in rows["label"]]
        out["start"], out["end"] = rows["start"], rows["end"]
        return out
    rows = list(rows)
    for k, r in enumerate(rows):
        if len(r) != 4:
            raise ParameterError(
                f"{name}[{k}] must be (document, label, start, end), got {r!r}")
    if not rows:
        return np.empty(0, dtype=LABEL_DTYPE)
    d, lab, s, e = zip(*rows)
    return label_rows(list(d), list(lab), s, e)


# ---------------------------------------------------------------------------
# CSV files


def read_text(path):
    """The text of a label file: UTF-8 (with or without BOM), else Latin-1.

    Raises
    ------
    ParseError
        If the file cannot be read.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ParseError(path, None, f"cannot read the file: {exc.strerror or exc}") from exc
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def csv_records(path, required, optional=(), *, hint=""):
    """(line number, {column: value}) for every data line of a CSV with a header.

    Blank lines and lines starting with ``#`` are skipped; the header must hold
    the ``required`` columns (lower case; matched case-insensitively, any
    order, extra columns ignored; else a :class:`ParseError` ending with
    ``hint``); the ``optional`` columns the header has are in the dicts too.
    """
    text = read_text(path)
    reader = csv.reader(io.StringIO(text, newline=""))
    header = None
    for row in reader:
        line = reader.line_num
        if not row or not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        if header is None:
            header = [c.strip().lower() for c in row]
            missing = [c for c in required if c not in header]
            if missing:
                raise ParseError(path, line, f"expected a header with the columns "
                                 f"{','.join(required)}; missing {','.join(missing)} "
                                 f"(got {','.join(header)}){hint}")
            col = {c: header.index(c) for c in (*required, *optional) if c in header}
            continue
        if len(row) < len(header):
            raise ParseError(path, line, f"expected {len(header)} fields, got {len(row)}")
        yield line, {c: row[i].strip() for c, i in col.items()}
    if header is None:
        raise ParseError(path, None, f"empty file: expected a header {','.join(required)}")


def _int_field(path, line, name, text):
    try:
        return int(text)
    except ValueError:
        raise ParseError(path, line, f"{name} must be an integer frame number, "
                         f"got {text!r}") from None


#: optional label CSV column: the rate of the row's frames (default: the document's native rate)
FPS_COLUMN = "fps"
#: columns of ``mocapdb annotate --format csv`` that mark its output (30 Hz frames) in files without ``fps``
ANNOTATION_COLUMNS = ("start_s", "end_s")


def _rate_of(fps, document):
    """The native rate of ``document`` from a rate or a mapping of rates (None: unknown)."""
    rate = fps.get(document) if isinstance(fps, dict) else fps
    return None if rate is None else float(rate)


def _row_rate(path, line, rec):
    """The rate of a CSV row's frames: its ``fps`` column, 30 for mocapdb's annotation output, else None (native)."""
    text = rec.get(FPS_COLUMN, "")
    if text:
        try:
            rate = float(text)
        except ValueError:
            rate = float("nan")
        if not (np.isfinite(rate) and rate > 0):
            raise ParseError(path, line, f"fps must be a positive frame rate, got {text!r}")
        return rate
    if all(c in rec for c in ANNOTATION_COLUMNS):
        return float(FEATURE_RATE)
    return None


def _to_native(path, line, doc, s, e, rate, fps, n_frames):
    """A row's frames at ``rate`` Hz → the document's native frames (1-based inclusive), checked in the
    file's own frames."""
    native = _rate_of(fps, doc)
    if native is None:
        raise ParseError(path, line, f"frames at {rate:g} Hz (the fps column), but the native rate of document "
                         f"{doc!r} is unknown: ingest it first, so the database knows its rate")
    a, b = feature_to_native_frames(s - 1, e - 1, factor=native / rate)
    if n_frames is not None and doc in n_frames:
        n = int(n_frames[doc])
        last = int(np.floor((n - 1) * rate / native + _EPS)) + 1  # the document's last frame at this rate
        if e > last:
            raise ParseError(path, line, f"end_frame {e} is beyond the last frame of document {doc!r} ({last} "
                             f"frames at {rate:g} Hz, the rate of this row)")
        b = min(int(b), n)
    return int(a), int(b)


def read_labels(path, *, n_frames=None, fps=None):
    """Read a label / ground-truth CSV (``document,label,start_frame,end_frame[,fps]``) or an ELAN file.

    Parameters
    ----------
    path : str or Path
        A CSV, or an ELAN ``.eaf`` file (by the suffix; the tier → label and
        time → frame rules are in :mod:`mocapdb.annotation.elan`).
    n_frames : mapping of str to int, optional
        Native frame count per document; rows of these documents must end
        within it (other documents are not checked).
    fps : float or mapping of str to float, optional
        The document's native frame rate: places ELAN times on native frames
        (default: the file's ``mocapdb:source_fps`` property) and CSV rows
        with an ``fps`` of their own (or mocapdb's annotation output, 30 Hz)
        on native frames.

    Returns
    -------
    ndarray of LABEL_DTYPE
        In file order; ``start``/``end`` on the native rate, 1-based
        inclusive (a native-rate CSV's numbers exactly). Use
        :func:`to_feature_grid` for the 30 Hz grid.

    Raises
    ------
    ParseError
        ``file:line: …`` on a missing column, an empty document or label, a
        non-integer frame, start_frame < 1, end_frame < start_frame, an end
        beyond the document's frames (said in the file's own frames), or
        frames at a rate of their own for a document of unknown rate.

    References
    ----------
    DESIGN.md §5.
    """
    if is_eaf(path):
        rows = read_eaf(path, fps=fps)
        for doc, _, _, e in rows:
            if n_frames is not None and doc in n_frames and e > int(n_frames[doc]):
                raise ParseError(path, None, f"an annotation ends at native frame {e}, beyond the last frame "
                                 f"of document {doc!r} ({int(n_frames[doc])} frames)")
        return as_label_rows(rows)
    out = []
    for line, rec in csv_records(path, LABEL_COLUMNS, (FPS_COLUMN, *ANNOTATION_COLUMNS)):
        doc, lab = rec["document"], rec["label"]
        if not doc:
            raise ParseError(path, line, "empty document name")
        if not lab:
            raise ParseError(path, line, "empty label")
        s = _int_field(path, line, "start_frame", rec["start_frame"])
        e = _int_field(path, line, "end_frame", rec["end_frame"])
        if s < 1:
            raise ParseError(path, line, f"start_frame must be >= 1 (frames are 1-based), got {s}")
        if e < s:
            raise ParseError(path, line, f"end_frame {e} is before start_frame {s}")
        rate = _row_rate(path, line, rec)
        if rate is not None:
            s, e = _to_native(path, line, doc, s, e, rate, fps, n_frames)
        elif n_frames is not None and doc in n_frames and e > int(n_frames[doc]):
            raise ParseError(path, line, f"end_frame {e} is beyond the last frame of document "
                             f"{doc!r} ({int(n_frames[doc])} frames at the native rate)")
        out.append((doc, lab, s, e))
    return as_label_rows(out)


def label_documents(path):
    """The documents a label file (CSV or ELAN) names, in first-appearance order.

    For an ELAN file this needs no frame rate (the rows need one).

    Returns
    -------
    list of str
    """
    if is_eaf(path):
        return [eaf_document(path)]
    return list(dict.fromkeys(rec["document"] for _, rec in csv_records(path, LABEL_COLUMNS) if rec["document"]))


def read_segments(path):
    """Read an annotation CSV as written by ``mocapdb annotate --format csv``.

    Columns ``document,label,start_frame,end_frame`` (others ignored) with
    frames on the 30 Hz feature grid, 1-based inclusive.

    Returns
    -------
    ndarray of LABEL_DTYPE
        On the 30 Hz grid, 0-based inclusive (ready for :mod:`mocapdb.evaluation.metrics`).

    Raises
    ------
    ParseError
        ``file:line: …`` as :func:`read_labels`.
    """
    out = []
    for line, rec in csv_records(path, LABEL_COLUMNS):
        s = _int_field(path, line, "start_frame", rec["start_frame"])
        e = _int_field(path, line, "end_frame", rec["end_frame"])
        if s < 1 or e < s:
            raise ParseError(path, line, f"need 1 <= start_frame <= end_frame, got {s}, {e}")
        out.append((rec["document"], rec["label"], s - 1, e - 1))
    return as_label_rows(out)


def write_labels(path, rows, *, fps=None):
    """Write labelled segments as a label CSV (native rate, 1-based inclusive).

    Parameters
    ----------
    path : str, Path or text file object
    rows : ndarray of LABEL_DTYPE (or with a ``doc`` field) or iterable of
        (document, label, start, end), already on the native 1-based grid
        (:func:`to_native_grid`), or 1-based at ``fps``.
    fps : float, optional, keyword-only
        The rate of the rows' frames when it is not the documents' native
        rate: written as the column ``fps`` of every row.

    Raises
    ------
    ParameterError
        If a start is < 1 or an end before its start.
    """
    r = as_label_rows(rows)
    bad = (r["start"] < 1) | (r["end"] < r["start"])
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ParameterError(
            f"rows[{k}] = {tuple(r[k])}: need 1 <= start <= end (native 1-based frames); "
            "convert 0-based 30 Hz segments with to_native_grid first")

    def _write(fh):
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(LABEL_COLUMNS + ((FPS_COLUMN,) if fps is not None else ()))
        rate = () if fps is None else (f"{float(fps):g}",)
        for x in r:
            w.writerow((x["document"], x["label"], int(x["start"]), int(x["end"]), *rate))

    if hasattr(path, "write"):
        _write(path)
    else:
        with open(path, "w", newline="", encoding="utf-8") as fh:
            _write(fh)


# ---------------------------------------------------------------------------
# frame grids


def _check_factor(factor):
    """Native frames per 30 Hz frame: a number or one per range (source rate / 30)."""
    if isinstance(factor, bool):
        raise ParameterError(f"factor must be a positive number, got {factor!r}; default 4 (120 Hz)")
    f = np.asarray(factor, dtype=np.float64)
    if not (np.isfinite(f).all() and (f > 0).all()):
        raise ParameterError(f"factor must be positive (native frames per 30 Hz frame), got {factor!r}")
    return f


def native_factor(fps):
    """Native frames per 30 Hz feature frame of a source at ``fps`` Hz (4 at 120 Hz)."""
    return np.asarray(fps, dtype=np.float64) / FEATURE_RATE


# grid arithmetic on floats: 1e-9 absorbs the rounding of fps/30 (e.g. 29.97 Hz)
_EPS = 1e-9


def native_to_feature_frames(start, end, *, factor=DOWNSAMPLING_FACTOR):
    """Native 1-based inclusive ranges → 30 Hz feature frames, 0-based inclusive.

    30 Hz frame k (1-based) covers native frames ``factor·k − factor + 1 … factor·k``,
    so [s, e] covers ceil(s/factor) … ceil(e/factor) (1-based).

    Parameters
    ----------
    start, end : int or array_like of int
        Native frames, 1-based inclusive (``1 <= start <= end``).
    factor : float or array_like of float, default 4
        Native frames per 30 Hz frame: ``source_fps / 30`` (:func:`native_factor`),
        one number or one per range.
        The toolbox's fixed downsampling factor (FEATURES.md §1).

    Returns
    -------
    start, end : ndarray of int64
        ``(start − 1) // factor`` and ``(end − 1) // factor``.

    Raises
    ------
    ParameterError
        If a start is < 1 or an end before its start.

    Examples
    --------
    >>> native_to_feature_frames([1, 5, 881], [4, 880, 1044])
    (array([  0,   1, 220]), array([  0, 219, 260]))
    """
    f = _check_factor(factor)
    s = np.asarray(start, dtype=np.int64)
    e = np.asarray(end, dtype=np.int64)
    if (s < 1).any() or (e < s).any():
        raise ParameterError("native ranges must satisfy 1 <= start <= end (1-based frames)")
    return (np.floor((s - 1) / f + _EPS).astype(np.int64), np.floor((e - 1) / f + _EPS).astype(np.int64))


def feature_to_native_frames(start, end, *, factor=DOWNSAMPLING_FACTOR, n_native=None):
    """30 Hz feature frames, 0-based inclusive → native 1-based inclusive ranges.

    Parameters
    ----------
    start, end : int or array_like of int
        0-based inclusive 30 Hz frames (``0 <= start <= end``).
    factor : float or array_like of float, default 4
        Native frames per 30 Hz frame: ``source_fps / 30`` (:func:`native_factor`),
        one number or one per range.
    n_native : int or array_like of int, optional
        Native length of each range's document: ends are clipped to it (the
        last 30 Hz frame of a document may cover fewer than ``factor`` frames).

    Returns
    -------
    start, end : ndarray of int64
        ``factor·start + 1`` and ``min(factor·end + factor, n_native)``.

    Raises
    ------
    ParameterError
        If a start is < 0, an end before its start, or a start beyond ``n_native``.
    """
    f = _check_factor(factor)
    a = np.asarray(start, dtype=np.int64)
    b = np.asarray(end, dtype=np.int64)
    if (a < 0).any() or (b < a).any():
        raise ParameterError("feature-grid ranges must satisfy 0 <= start <= end (0-based)")
    # 30 Hz frame k covers the native frames s with floor((s - 1)/f) = k
    s = np.ceil(a * f - _EPS).astype(np.int64) + 1
    e = np.ceil((b + 1) * f - _EPS).astype(np.int64)
    if n_native is not None:
        n = np.asarray(n_native, dtype=np.int64)
        if (s > n).any():
            raise ParameterError("a range starts beyond its document's native length n_native")
        e = np.minimum(e, n)
    return s, e


def to_feature_grid(rows, *, factor=DOWNSAMPLING_FACTOR):
    """Label rows on the native 1-based grid → the 30 Hz grid, 0-based inclusive.

    Parameters
    ----------
    rows : ndarray of LABEL_DTYPE or iterable of (document, label, start, end)
    factor : float or array_like of float, default 4
        Native frames per 30 Hz frame: ``source_fps / 30`` (:func:`native_factor`),
        one number or one per range.

    Returns
    -------
    ndarray of LABEL_DTYPE (a copy)
    """
    r = as_label_rows(rows).copy()
    r["start"], r["end"] = native_to_feature_frames(r["start"], r["end"], factor=factor)
    return r


def to_native_grid(rows, *, factor=DOWNSAMPLING_FACTOR, n_native=None):
    """Label rows on the 30 Hz grid (0-based inclusive) → native 1-based inclusive.

    Parameters
    ----------
    rows : ndarray of LABEL_DTYPE (or with a ``doc`` field) or iterable of tuples
    factor : float or array_like of float, default 4
        Native frames per 30 Hz frame: ``source_fps / 30`` (:func:`native_factor`),
        one number or one per range.
    n_native : mapping of str to int, optional
        Native frame count per document; ends are clipped to it (documents
        missing from the mapping are not clipped).

    Returns
    -------
    ndarray of LABEL_DTYPE (a copy)
    """
    r = as_label_rows(rows).copy()
    n = None
    if n_native is not None:
        big = np.iinfo(np.int64).max // 2
        n = np.array([int(n_native.get(d, big)) for d in r["document"]], dtype=np.int64)
    r["start"], r["end"] = feature_to_native_frames(r["start"], r["end"], factor=factor,
                                                    n_native=n)
    return r


def segments_to_rows(segments, documents):
    """Annotation segments (``doc`` = index in the call) → rows named by document.

    Parameters
    ----------
    segments : ndarray of mocapdb.annotation.SEGMENT_DTYPE
    documents : sequence of str
        Name of each document of the annotation call, in order.

    Returns
    -------
    ndarray of LABEL_DTYPE
        Same grid as the segments (30 Hz, 0-based inclusive).
    """
    docs = np.asarray([str(d) for d in documents], dtype=object)
    idx = np.asarray(segments["doc"], dtype=np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= docs.size):
        raise ParameterError(f"segments refer to document {int(idx.max())}, but only "
                             f"{docs.size} document names were given")
    out = np.empty(idx.size, dtype=LABEL_DTYPE)
    out["document"] = docs[idx]
    out["label"] = [str(x) for x in segments["label"]]
    out["start"], out["end"] = segments["start"], segments["end"]
    return out


def read_truth(path, *, label_map=None, n_frames=None, fps=None):
    """A ground-truth or label file (CSV or ELAN, native frames) on the 30 Hz grid, labels mapped.

    Parameters
    ----------
    path : str or Path
    label_map : str, Path or dict, optional
        Truth label → model label (CSV ``class,label`` or a dict), e.g.
        86_09's ``walk`` → ``move``; unmapped labels are kept.
    n_frames : mapping of str to int, optional
        As :func:`read_labels`.
    fps : float or mapping of str to float, optional
        Each document's native rate (a database's ``motions.source_fps``):
        places ELAN times on native frames and native frames on the 30 Hz
        grid (:func:`native_factor`). Default: an ELAN file's
        ``mocapdb:source_fps`` property, else 120 Hz.

    Returns
    -------
    ndarray of LABEL_DTYPE
        30 Hz feature frames, 0-based inclusive.
    """
    default = (eaf_source_fps(path) if is_eaf(path) else None) or TOOLBOX_RATE
    if not is_eaf(path) and (fps is None or isinstance(fps, dict)):
        # a CSV's documents of unknown rate are taken at the default (an ELAN file says its own or fails)
        fps = {d: (fps or {}).get(d, default) for d in label_documents(path)}
    native = read_labels(path, n_frames=n_frames, fps=fps)
    rates = [_rate_of(fps, d) or default for d in native["document"]]
    rows = to_feature_grid(native, factor=native_factor(rates) if rates else DOWNSAMPLING_FACTOR)
    if label_map is not None:
        rows = map_labels(rows, label_map if isinstance(label_map, dict) else read_class_labels(label_map))
    return rows


def map_labels(rows, mapping):
    """Rename labels by a mapping; labels not in it are kept unchanged.

    Unmapped labels are deliberately kept (not dropped): an evaluation
    restricted to a model's label vocabulary drops and reports them
    (:func:`mocapdb.evaluation.metrics.evaluate_annotation`).

    Returns
    -------
    ndarray of LABEL_DTYPE (a copy)
    """
    r = as_label_rows(rows).copy()
    r["label"] = [mapping.get(x, x) for x in r["label"]]
    return r


# ---------------------------------------------------------------------------
# class → label mapping files


def read_class_labels(path):
    """Read a class → label mapping (CSV with the columns ``class,label``).

    Returns
    -------
    dict of str to str
        In file order (the label order of a model trained with it).

    Raises
    ------
    ParseError
        On a missing column, an empty field, or a class listed twice.
    """
    out = {}
    for line, rec in csv_records(path, ("class", "label")):
        c, lab = rec["class"], rec["label"]
        if not c or not lab:
            raise ParseError(path, line, "class and label must not be empty")
        if c in out:
            raise ParseError(path, line, f"class {c!r} is listed twice")
        out[c] = lab
    return out


def write_class_labels(path, mapping):
    """Write a class → label mapping as CSV ``class,label`` (mapping order)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(("class", "label"))
        for c, lab in mapping.items():
            w.writerow((c, lab))


def class_labels(name="hdm05"):
    """A class → label mapping shipped with the package (``mocapdb/shipped_models/``).

    Parameters
    ----------
    name : {"hdm05", "cmu86", "cmu_mocap6", "default"}, default "hdm05"
        ``hdm05``: the 11 HDM05 classes of the development data → the coarse
        labels of paper Table 1 (data/README.md); ``cmu86``: the 86_09 ground
        truth actions; ``cmu_mocap6``: the mocap6 exercise names;
        ``default``: the learned classes of the shipped default model.

    Returns
    -------
    dict of str to str
    """
    if name not in SHIPPED_CLASS_LABELS:
        raise ParameterError(f"name must be one of {sorted(SHIPPED_CLASS_LABELS)}, got {name!r}")
    ref = resources.files("mocapdb.shipped_models").joinpath(SHIPPED_CLASS_LABELS[name])
    with resources.as_file(ref) as p:
        return read_class_labels(p)
