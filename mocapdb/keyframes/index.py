"""Inverted file index over packed feature words (KEYFRAMES.md §1, §3).

A document is a sequence of packed 30 Hz feature words (``uint64``, bit k-1 =
feature k).  The index stores, per *part*, the maximal runs of constant word
("segments") of every document and one posting list per distinct word.  A part
is one of the toolbox's feature sets (``"upper"``, ``"lower"``, ``"mix"``: the
word restricted to the set's bits, shifted so that feature 1 of the set is
bit 0, exactly as the toolbox's per-set indexes) or ``"full"`` (the whole
40-bit word).  Both layouts answer the same keyframe queries with the same
frame intervals; they differ in size and speed
(``benchmarks/bench_keyframes_search.py``).

Storage (all parts in one set of flat arrays, part after part, within a part
document after document):

* the segment table -- per segment its first frame, length and word id; it
  maps 1:1 onto ``postings(motion_id, feature_set, seg, word, start_frame,
  n_frames)`` (:meth:`Index.to_columns`, :meth:`Index.from_columns`);
* the posting lists -- per distinct word the (doc, seg) pairs in the toolbox's
  order, each carrying the segment's first and last frame, so that a query
  reads its lists sequentially and never touches the segment table.

A fuzzy keyframe ``(mask, value)`` is answered without enumerating the 2^w
wildcard words: the index's distinct words are tested with
``word & mask == value``.  Its frame intervals come from the union of the
matching posting lists (heap merge or bitset) or, in a few documents, from
a forward scan of their segments (the keyframe search's document filter,
mocapdb.keyframes); all give the same intervals.

Building (and loading from the ``postings`` table) is O(segments): word ids
by hashing, posting lists by a counting sort -- no sort of the segments.

Public functions
----------------
build_index        words of many documents -> :class:`Index`
fuzzy_postings     distinct words matching a keyframe + union of their lists
fuzzy_intervals    the union converted to frame intervals (§3)

Frame numbers are 0-based with inclusive ends; document ids are 0-based
positions in the order the documents were given.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import SET_BITS, as_doc_lengths, segment_runs
from mocapdb.keyframes.index_kernels import (_distinct_words_kernel, _fill_postings_kernel, _fuzzy_kernel, _group_count_kernel, _scatter_rows_kernel, _tiling_error_kernel)

#: index parts in canonical order; the integer code of a part is its position
INDEX_PARTS = ("upper", "lower", "mix", "full")
#: (first bit, n bits) of every part
PART_BITS = SET_BITS
#: the toolbox layout: one index per feature set (KEYFRAMES.md §1)
SET_PARTS = ("upper", "lower", "mix")

_I32_MAX = 2**31 - 1


class Segments(NamedTuple):
    """Frame ranges ``(doc, start, end)`` (0-based, inclusive), each ``(n,) int64``."""

    doc: np.ndarray
    start: np.ndarray
    end: np.ndarray

    @property
    def n_frames(self) -> int:
        """Total number of frames covered (the toolbox's ``framesTotalNum``)."""
        return int(np.sum(self.end - self.start + 1))

    def __len__(self) -> int:  # number of ranges, not of fields
        return len(self.doc)

    def as_array(self) -> np.ndarray:
        """``(n, 3) int64`` rows (doc, start, end)."""
        return np.stack([self.doc, self.start, self.end], axis=1)


class Postings(NamedTuple):
    """One fuzzy keyframe against one index part (KEYFRAMES.md §3).

    ``words`` (W,) uint64: the distinct index words matching the keyframe,
    ascending (words without postings do not exist in the index);
    ``list_lengths`` (W,) int64; ``doc``, ``seg`` (P,) int64: the union of
    their posting lists in (doc, seg) order, without duplicates.
    """

    words: np.ndarray
    list_lengths: np.ndarray
    doc: np.ndarray
    seg: np.ndarray


# --------------------------------------------------------------------------
# building


def _as_u64(x, name):
    a = np.asarray(x)
    if a.dtype != np.uint64:
        if a.dtype.kind not in "iu":
            raise ParameterError(f"{name} must hold packed uint64 feature words, "
                                 f"got dtype {a.dtype}")
        if a.size and a.min() < 0:
            raise ParameterError(f"{name} holds negative words; pass packed uint64 feature words")
        a = a.astype(np.uint64)
    return np.ascontiguousarray(a)


def _as_int(x, name):
    """A 1-D integer column, kept in its dtype when it is a signed or small one."""
    a = np.asarray(x)
    if a.dtype.kind == "f" and a.size and not np.all(a == np.floor(a)):
        raise ParameterError(f"column {name} must hold integers, got dtype {a.dtype}")
    if a.dtype.kind not in "iu" or a.dtype == np.uint64:  # uint64 + int64 would be float
        a = a.astype(np.int64)
    return np.ascontiguousarray(a.ravel())


def _part_names(feature_sets) -> tuple:
    if isinstance(feature_sets, str):
        feature_sets = (feature_sets,)
    names = tuple(feature_sets)
    if not names:
        raise ParameterError("feature_sets is empty; pass e.g. ('upper', 'lower', 'mix') "
                             "or ('full',)")
    for n in names:
        if n not in INDEX_PARTS:
            raise ParameterError(f"feature_sets contains {n!r}; allowed: {', '.join(INDEX_PARTS)}")
    if len(set(names)) != len(names):
        raise ParameterError(f"feature_sets={names!r} repeats a part")
    return tuple(n for n in INDEX_PARTS if n in names)  # canonical order



@dataclass(frozen=True, eq=False)
class Index:
    """Inverted file index of one or more parts over the same documents.

    Attributes
    ----------
    parts : tuple of str
        Parts present, canonical order (subset of :data:`INDEX_PARTS`).
    doc_lengths : (n_docs,) int64
        Frames per document (the toolbox's ``files_frame_length``).
    part_seg_offset : (n_parts + 1,) int64
        Segments of part p are ``part_seg_offset[p]:part_seg_offset[p+1]``.
    doc_seg_offset : (n_parts, n_docs + 1) int64
        Segments of document d in part p are
        ``doc_seg_offset[p, d]:doc_seg_offset[p, d+1]`` (global ids).
    seg_start, seg_len : (n_segs,) int32
        First frame (within the document) and length of each segment.
    seg_wid : (n_segs,) int32
        Word of each segment as a part-local word id:
        ``words[part_word_offset[p] + seg_wid]``.
    words : (n_words,) uint64
        Distinct words, per part ascending (restricted to the part's bits,
        shifted); one non-empty posting list each.
    part_word_offset : (n_parts + 1,) int64
    list_offset : (n_words + 1,) int64
        Posting list of word i = entries ``list_offset[i]:list_offset[i+1]``
        of the ``list_*`` arrays, in (doc, seg) order.
    list_doc, list_seg : (n_segs,) int32
        The postings (doc, seg) (seg 0-based within document and part).
    list_start, list_end : (n_segs,) int32
        First and last frame of the posting's segment.

    Build with :func:`build_index` or :meth:`from_columns`; never mutate.
    """

    parts: tuple
    doc_lengths: np.ndarray
    part_seg_offset: np.ndarray
    doc_seg_offset: np.ndarray
    seg_start: np.ndarray
    seg_len: np.ndarray
    seg_wid: np.ndarray
    words: np.ndarray
    part_word_offset: np.ndarray
    list_offset: np.ndarray
    list_doc: np.ndarray
    list_seg: np.ndarray
    list_start: np.ndarray
    list_end: np.ndarray

    @property
    def n_docs(self) -> int:
        return len(self.doc_lengths)

    @property
    def n_frames(self) -> int:
        return int(self.doc_lengths.sum())

    @property
    def nbytes(self) -> int:
        """Memory held by the index arrays."""
        return sum(getattr(self, f).nbytes for f in self.__dataclass_fields__ if f != "parts")

    def part_id(self, part: str) -> int:
        """Position of ``part`` in :attr:`parts`; ParameterError when absent."""
        try:
            return self.parts.index(part)
        except ValueError:
            raise ParameterError(
                f"the index has no part {part!r} (it has {', '.join(self.parts)}); "
                f"rebuild it with build_index(..., feature_sets=...) including {part!r}") from None

    def segments(self, part: str, doc: int):
        """Segments of one document: ``(start, length, word)`` int64/int64/uint64 (§1.3)."""
        p = self.part_id(part)
        a, b = self.doc_seg_offset[p, doc], self.doc_seg_offset[p, doc + 1]
        return (self.seg_start[a:b].astype(np.int64), self.seg_len[a:b].astype(np.int64),
                self.words[self.part_word_offset[p] + self.seg_wid[a:b]])

    def posting_list(self, part: str, word: int):
        """Posting list of ``word`` in ``part``: ``(doc, seg)`` int64 arrays in (doc, seg) order."""
        p = self.part_id(part)
        lo, hi = self.part_word_offset[p], self.part_word_offset[p + 1]
        i = lo + np.searchsorted(self.words[lo:hi], np.uint64(word))
        if i == hi or self.words[i] != np.uint64(word):
            return np.empty(0, np.int64), np.empty(0, np.int64)
        a, b = self.list_offset[i], self.list_offset[i + 1]
        return self.list_doc[a:b].astype(np.int64), self.list_seg[a:b].astype(np.int64)

    def kernel_arrays(self) -> tuple:
        """The arrays the search kernels take, in their argument order."""
        return (self.words, self.list_offset, self.list_doc, self.list_seg, self.list_start,
                self.list_end, self.seg_start, self.seg_len, self.seg_wid, self.part_word_offset,
                self.doc_seg_offset)

    # ---- columns <-> index -------------------------------------------------

    def to_columns(self) -> dict:
        """The segment table as the columns of the DuckDB ``postings`` table.

        ``postings(motion_id, feature_set, seg, word, start_frame, n_frames)``.

        Returns
        -------
        dict of (n_segs,) arrays, rows ordered by (feature_set, doc, seg)
            ``doc`` int64 (0-based document position; map it to
            ``motion_id``), ``feature_set`` int8 (code = position in
            :data:`INDEX_PARTS`), ``seg`` int64 (0-based within document and
            part), ``word`` uint64, ``start_frame`` int64 (0-based),
            ``n_frames`` int64.  A posting list is
            ``SELECT doc, seg ... WHERE feature_set = ? AND word = ? ORDER BY doc, seg``.
        """
        n = len(self.seg_start)
        codes = np.empty(n, np.int8)
        doc = np.empty(n, np.int64)
        seg = np.empty(n, np.int64)
        word = np.empty(n, np.uint64)
        for p, name in enumerate(self.parts):
            a, b = self.part_seg_offset[p], self.part_seg_offset[p + 1]
            codes[a:b] = INDEX_PARTS.index(name)
            counts = np.diff(self.doc_seg_offset[p])
            doc[a:b] = np.repeat(np.arange(self.n_docs), counts)
            seg[a:b] = np.arange(a, b) - np.repeat(self.doc_seg_offset[p, :-1], counts)
            word[a:b] = self.words[self.part_word_offset[p] + self.seg_wid[a:b]]
        return {"doc": doc, "feature_set": codes, "seg": seg, "word": word,
                "start_frame": self.seg_start.astype(np.int64),
                "n_frames": self.seg_len.astype(np.int64)}

    @classmethod
    def from_columns(cls, doc, feature_set, seg, word, start_frame, n_frames, *, doc_lengths, parts=None):
        """Rebuild the searchable index from postings-table columns (any row order).

        Parameters
        ----------
        doc, seg, start_frame, n_frames : (n,) int
            0-based document position, segment id within (part, document),
            first frame and run length.
        feature_set : (n,) int or str
            Part code (position in :data:`INDEX_PARTS`) or part name; codes
            are much faster (no per-row strings).
        word : (n,) uint64
        doc_lengths : (n_docs,) int
            Frames per document, in document-position order (documents without
            frames have no rows but count).
        parts : sequence of str, optional
            The parts the index has (default: those present in the rows; an
            index without rows needs them).

        Raises
        ------
        ParameterError
            Columns of different lengths, unknown part, or segments that do not
            tile each document exactly (gaps, overlaps, wrong seg numbering).
        """
        n = len(doc)
        fs = np.asarray(feature_set)
        if fs.dtype.kind in "UOS":  # names: map the few distinct ones, not every row
            names, inverse = np.unique(fs.astype(str), return_inverse=True)
            unknown = [x for x in names.tolist() if x not in INDEX_PARTS]
            if unknown:
                raise ParameterError(f"feature_set holds unknown part {unknown[0]!r}; "
                                     f"allowed: {', '.join(INDEX_PARTS)}")
            fs = np.array([INDEX_PARTS.index(x) for x in names.tolist()], np.int64)[inverse]
        # integer columns keep their dtype (no copies of millions of rows)
        doc, fs, seg, start, length = (_as_int(c, name) for c, name in (
            (doc, "doc"), (fs, "feature_set"), (seg, "seg"), (start_frame, "start_frame"),
            (n_frames, "n_frames")))
        word = _as_u64(word, "word")
        lengths = as_doc_lengths(doc_lengths)
        for name, col in (("feature_set", fs), ("seg", seg), ("word", word),
                          ("start_frame", start), ("n_frames", length)):
            if len(col) != n:
                raise ParameterError(f"column {name} has {len(col)} rows, doc has {n}")
        if n and (fs.min() < 0 or fs.max() >= len(INDEX_PARTS)):
            raise ParameterError(f"feature_set codes must be in 0..{len(INDEX_PARTS) - 1}")
        if n and (doc.min() < 0 or doc.max() >= len(lengths)):
            raise ParameterError(f"doc ids must be in 0..{len(lengths) - 1} (len(doc_lengths)); "
                                 f"got {doc.min()}..{doc.max()}")
        present = np.flatnonzero(np.bincount(fs, minlength=len(INDEX_PARTS)))
        if parts is not None:
            wanted = np.array([INDEX_PARTS.index(p) for p in _part_names(parts)], np.int64)
            if not np.isin(present, wanted).all():
                raise ParameterError(f"rows hold parts outside parts={tuple(parts)}")
            present = wanted
        if len(present) == 0:
            raise ParameterError("no postings rows: cannot tell which parts the index has; pass parts=")
        parts = tuple(INDEX_PARTS[c] for c in present)
        # row position in (part, doc, seg) order without sorting: groups (part,
        # doc) are counted, a row goes to its group's offset + seg
        n_docs = len(lengths)
        part_pos = np.full(len(INDEX_PARTS), -1, np.int64)
        part_pos[present] = np.arange(len(present))
        group_offset = np.zeros(len(parts) * n_docs + 1, np.int64)
        _group_count_kernel(part_pos, fs, doc, n_docs, group_offset)
        np.cumsum(group_offset, out=group_offset)
        ok = n == 0 or (start.min() >= 0 and length.min() > 0 and
                        max(start.max(), length.max()) <= _I32_MAX)
        seg_start = np.empty(n, np.int32)
        seg_len = np.empty(n, np.int32)
        seg_word = np.empty(n, np.uint64)
        if ok:
            ok = _scatter_rows_kernel(part_pos, fs, doc, seg, start, length, word, n_docs,
                                      group_offset, np.zeros(n, np.bool_), seg_start, seg_len,
                                      seg_word)
        doc_seg_offset = np.stack([group_offset[p * n_docs:(p + 1) * n_docs + 1]
                                   for p in range(len(parts))])
        for p in range(len(parts)):
            if ok:  # the runs must tile every document exactly
                ok = _tiling_error_kernel(doc_seg_offset[p], seg_start, seg_len, lengths) < 0
            if not ok:
                raise ParameterError(
                    f"part {parts[p]!r}: segments do not tile the documents given by doc_lengths "
                    "(seg numbering, start_frame or n_frames inconsistent); rebuild the postings "
                    "with build_index")
        part_seg_offset = group_offset[np.arange(len(parts) + 1) * n_docs]
        return cls._assemble(parts, lengths, part_seg_offset, doc_seg_offset, seg_start, seg_len,
                             seg_word)

    @classmethod
    def _assemble(cls, parts, lengths, part_seg_offset, doc_seg_offset, start, length, word):
        """Posting lists and word ids from the segment table (all parts, global order)."""
        if len(lengths) > _I32_MAX:
            raise ParameterError(f"at most {_I32_MAX} documents per index")
        n = len(start)
        seg_start = start.astype(np.int32, copy=False)
        seg_len = length.astype(np.int32, copy=False)
        seg_wid = np.empty(n, np.int32)
        words_all, counts_all, wofs = [], [], [0]
        for p in range(len(parts)):
            a, b = part_seg_offset[p], part_seg_offset[p + 1]
            first_seen = np.empty(b - a, np.int64)
            distinct, counts = _distinct_words_kernel(word, a, b, first_seen)
            order = np.argsort(distinct)  # few distinct words: word ids ascending by word
            rank = np.empty(len(order), np.int32)
            rank[order] = np.arange(len(order), dtype=np.int32)
            seg_wid[a:b] = rank[first_seen]
            words_all.append(distinct[order])
            counts_all.append(counts[order])
            wofs.append(wofs[-1] + len(order))
        words = np.concatenate(words_all)
        list_offset = np.zeros(len(words) + 1, np.int64)
        np.cumsum(np.concatenate(counts_all), out=list_offset[1:])
        list_doc = np.empty(n, np.int32)
        list_seg = np.empty(n, np.int32)
        list_start = np.empty(n, np.int32)
        list_end = np.empty(n, np.int32)
        for p in range(len(parts)):
            cursor = list_offset[wofs[p]:wofs[p + 1]].copy()
            _fill_postings_kernel(seg_wid, doc_seg_offset[p], seg_start, seg_len, cursor,
                                  list_doc, list_seg, list_start, list_end)
        return cls(parts=tuple(parts), doc_lengths=lengths,
                   part_seg_offset=np.asarray(part_seg_offset, np.int64),
                   doc_seg_offset=np.ascontiguousarray(doc_seg_offset, np.int64),
                   seg_start=seg_start, seg_len=seg_len, seg_wid=seg_wid, words=words,
                   part_word_offset=np.asarray(wofs, np.int64), list_offset=list_offset,
                   list_doc=list_doc, list_seg=list_seg, list_start=list_start,
                   list_end=list_end)


def _flatten_docs(words_per_doc, doc_lengths):
    if doc_lengths is not None:
        words = _as_u64(words_per_doc, "words")
        if words.ndim != 1:
            raise ParameterError("with doc_lengths, words must be one flat (n_frames,) array")
        return words, as_doc_lengths(doc_lengths, len(words))
    if isinstance(words_per_doc, np.ndarray):
        raise ParameterError("pass a sequence of per-document word arrays, "
                             "or one flat array together with doc_lengths=")
    docs = [_as_u64(w, f"words_per_doc[{i}]").ravel() for i, w in enumerate(words_per_doc)]
    lengths = as_doc_lengths(np.array([len(w) for w in docs], dtype=np.int64))
    words = np.concatenate(docs) if docs else np.empty(0, np.uint64)
    return words, lengths


def build_index(words_per_doc, *, doc_lengths=None, feature_sets=SET_PARTS) -> Index:
    """Build the inverted file index of many documents (KEYFRAMES.md §1).

    Parameters
    ----------
    words_per_doc : sequence of (n_d,) uint64, or (n_frames,) uint64 with ``doc_lengths``
        Packed 30 Hz feature words per document (document ids = positions).
    doc_lengths : (n_docs,) int, optional
        Frames per document when ``words_per_doc`` is one flat array.
    feature_sets : sequence of str, default ('upper', 'lower', 'mix')
        Parts to build: the toolbox's per-set indexes and/or ``'full'`` (one
        index over the whole 40-bit word).

    Returns
    -------
    Index

    Notes
    -----
    The toolbox downsamples 120 Hz features by 4 inside ``index_build``; the
    input here already is the 30 Hz word sequence (every 4th frame).

    References
    ----------
    KEYFRAMES.md §1; toolbox ``index_build.m``, ``runs_find_constant.m``.
    """
    parts = _part_names(feature_sets)
    words, lengths = _flatten_docs(words_per_doc, doc_lengths)
    runs = [segment_runs(words, lengths, feature_set=name) for name in parts]
    part_seg_offset = np.zeros(len(parts) + 1, np.int64)
    np.cumsum([len(r[0]) for r in runs], out=part_seg_offset[1:])
    doc_seg_offset = np.stack([r[3] + part_seg_offset[p] for p, r in enumerate(runs)])
    start, length, word = (np.concatenate([r[i] for r in runs]) for i in range(3))
    return Index._assemble(parts, lengths, part_seg_offset, doc_seg_offset, start, length, word)


# --------------------------------------------------------------------------
# one fuzzy keyframe against one part


def _fuzzy(index: Index, part: str, mask, value, want_union, strategy=0):
    p = index.part_id(part)
    nbits = PART_BITS[part][1]
    m, v = int(mask), int(value)
    if m < 0 or v < 0 or m >> nbits or v & ~m:
        raise ParameterError(
            f"mask={m:#x}/value={v:#x} must be {part!r}-local words (bits 0..{nbits - 1}) "
            "with value bits only where mask is set")
    return _fuzzy_kernel(*index.kernel_arrays(), p, np.uint64(m), np.uint64(v), 0, index.n_docs,
                         want_union, strategy)


def fuzzy_postings(index: Index, part: str, mask, value) -> Postings:
    """Words of ``part`` matching a fuzzy keyframe and the union of their lists (§3).

    Parameters
    ----------
    index : Index
    part : str
        Part to query; ``mask``/``value`` are words local to it (feature 1 of
        the set = bit 0).
    mask, value : int
        A word w matches iff ``w & mask == value`` (mask bit 0 = wildcard).

    Returns
    -------
    Postings
    """
    idx, _, _, _, u_doc, u_seg = _fuzzy(index, part, mask, value, True)
    return Postings(index.words[idx], np.diff(index.list_offset)[idx], u_doc, u_seg)


def fuzzy_intervals(index: Index, part: str, mask, value) -> Segments:
    """Frame intervals of a fuzzy keyframe (§3, re-segmentation of the union list).

    Per document a sorted list of disjoint, non-adjacent intervals: the
    maximal runs of frames whose ``part`` word matches ``(mask, value)``.

    Returns
    -------
    Segments
        ``(doc, start, end)``, sorted by (doc, start).
    """
    _, doc, start, end, _, _ = _fuzzy(index, part, mask, value, False)
    return Segments(doc, start, end)


__all__ = ["INDEX_PARTS", "PART_BITS", "SET_PARTS", "Index", "Postings", "Segments",
           "build_index", "fuzzy_intervals", "fuzzy_postings"]
