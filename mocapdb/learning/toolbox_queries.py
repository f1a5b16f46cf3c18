"""The toolbox's keyframe queries for a model: hand-made where they exist, heuristic otherwise.

The authors' toolbox ships hand-made keyframe queries for five HDM05 classes
(``manualKeyframesForAnnotation_AVR.m``; exported as CSV files in the
keyframe oracle, ``<class>_keyframes.csv`` + ``<class>_gaps.csv``) and, for
every other class, a heuristic chooser working on the quantized template
(``keyframesChooseLeastGrayValuesEquallyDistributed.m``, KEYFRAMES.md §8.1).
:func:`toolbox_keyframe_queries` puts the two together: the "toolbox
keyframes" model used by the benchmarks and by comparisons with learned
(GA) queries.
"""
from __future__ import annotations

import csv
from pathlib import Path

from mocapdb.errors import ParameterError, ParseError
from mocapdb.keyframes import KeyframeQuery, choose_keyframes_equally_distributed
from mocapdb.annotation.model import Model

__all__ = ["read_toolbox_query", "toolbox_keyframe_queries", "has_toolbox_query"]


def _paths(queries_dir, cls):
    d = Path(queries_dir)
    return d / f"{cls}_keyframes.csv", d / f"{cls}_gaps.csv"


def has_toolbox_query(queries_dir, cls) -> bool:
    """Whether ``queries_dir`` holds a hand-made query for class ``cls``."""
    kf, gaps = _paths(queries_dir, cls)
    return kf.is_file() and gaps.is_file()


def _rows(path, columns):
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        missing = [c for c in columns if c not in (reader.fieldnames or [])]
        if missing:
            raise ParseError(path, 1, f"header lacks the columns {missing}")
        return [(line, row) for line, row in enumerate(reader, start=2)]


def _number(path, line, row, col, kind=float):
    try:
        return kind(row[col])
    except (TypeError, ValueError):
        raise ParseError(path, line, f"column {col}: expected a number, got {row[col]!r}") from None


def read_toolbox_query(queries_dir, cls) -> KeyframeQuery:
    """Read a hand-made toolbox query (``<cls>_keyframes.csv`` and ``<cls>_gaps.csv``).

    The keyframes file has one row per keyframe: ``k, set_index`` (1 upper,
    2 lower, 3 mix), ``n_features, position`` (1-based template column),
    ``templateLength`` and the vector ``v01..v14`` (0, 1, 0.5 = wildcard; the
    first ``n_features`` entries count). The gaps file has one row per gap
    with its ``stiffness``; the gap bounds are derived from the positions and
    the stiffness as the toolbox does (KEYFRAMES.md §4).

    Parameters
    ----------
    queries_dir : str or Path
        Folder of the query files (the oracle's ``keyframes/queries``).
    cls : str
        Class name, e.g. ``"squat1Reps"``.

    Returns
    -------
    KeyframeQuery
        Keyframes restricted to their feature sets, 0-based positions,
        ``template_length`` as in the file.

    Raises
    ------
    ParameterError
        No query files for ``cls`` in ``queries_dir``, or a query the toolbox
        rejects (checkKeyframes.m).
    ParseError
        A malformed file (missing column, non-numeric entry, keyframes out of
        order, gap count not K − 1).
    """
    kf_path, gap_path = _paths(queries_dir, cls)
    if not has_toolbox_query(queries_dir, cls):
        raise ParameterError(f"no hand-made query for class {cls!r}: {kf_path} and {gap_path} "
                             "must both exist (use the heuristic chooser for other classes)")
    rows = _rows(kf_path, ["k", "set_index", "n_features", "position", "templateLength"])
    if not rows:
        raise ParseError(kf_path, None, "no keyframe rows")
    vectors, sets, positions, lengths = [], [], [], set()
    for k, (line, row) in enumerate(rows, start=1):
        if _number(kf_path, line, row, "k", int) != k:
            raise ParseError(kf_path, line, f"expected keyframe k = {k}, got {row['k']!r}")
        n = _number(kf_path, line, row, "n_features", int)
        vectors.append([_number(kf_path, line, row, f"v{i:02d}") for i in range(1, n + 1)])
        sets.append(_number(kf_path, line, row, "set_index", int))
        positions.append(_number(kf_path, line, row, "position", int))
        lengths.add(_number(kf_path, line, row, "templateLength", int))
    if len(lengths) != 1:
        raise ParseError(kf_path, None, f"rows disagree on templateLength: {sorted(lengths)}")
    gaps = _rows(gap_path, ["stiffness"])
    if len(gaps) != len(rows) - 1:
        raise ParseError(gap_path, None, f"{len(gaps)} gap rows for {len(rows)} keyframes "
                         f"(need {len(rows) - 1})")
    stiffness = [_number(gap_path, line, row, "stiffness") for line, row in gaps]
    try:
        return KeyframeQuery.from_toolbox(vectors, sets, positions, stiffness,
                                          template_length=lengths.pop())
    except ParameterError as e:
        raise ParameterError(f"{kf_path}: {e}") from None


def toolbox_keyframe_queries(model: Model, *, queries_dir) -> Model:
    """A copy of ``model`` with the toolbox's keyframe query on every class.

    A class gets its hand-made query when ``queries_dir`` holds one
    (:func:`read_toolbox_query`), otherwise the toolbox's heuristic choice
    on its quantized template
    (:func:`~mocapdb.keyframes.choose_keyframes_equally_distributed`: 3
    keyframes over all 40 features, stiffness 0.5). Queries already on the
    model are replaced; templates, labels and τ are kept.

    Parameters
    ----------
    model : Model
    queries_dir : str or Path, keyword-only
        Folder of hand-made query files (``<class>_keyframes.csv``,
        ``<class>_gaps.csv``).

    Returns
    -------
    Model
        Same name, classes in the same order.

    Raises
    ------
    ParameterError
        ``queries_dir`` is not a folder, or a template too short for the
        heuristic (fewer than about 4 columns).

    References
    ----------
    KEYFRAMES.md §2 (hand-made queries), §4 (stiffness), §8.1 (heuristic).
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a mocapdb.annotation.model.Model, got {type(model).__name__}")
    if not Path(queries_dir).is_dir():
        raise ParameterError(f"queries_dir={str(queries_dir)!r} is not a folder")
    queries = {}
    for c in model.classes:
        if has_toolbox_query(queries_dir, c.name):
            queries[c.name] = read_toolbox_query(queries_dir, c.name)
        else:
            try:
                queries[c.name] = choose_keyframes_equally_distributed(c.quantized.mask, c.quantized.value)
            except ParameterError as e:
                raise ParameterError(f"class {c.name!r}: {e}") from None
    return model.with_keyframe_queries(queries)
