"""Python UDFs behind the SQL functions, and their registration.

Each UDF is Arrow in / Arrow out and a thin call of the library function of
the same job. The temporary macros of ``sql/macros.sql`` pass the motion id,
the model's fingerprint and the keyframe index version in; the UDF reads
the words (and postings) of its rows' motions itself, a batch of motions at a
time, through a cursor of its connection
(:func:`~mocapdb.storage.annotations.annotate_motions`). Handing the words in
through the macro would make DuckDB collect every motion's words of the
query at once (it decorrelates the macro's ``list(bits)`` subquery into one
aggregate over the whole ``features`` table), memory that grows with the
archive. The connection's :class:`~mocapdb.storage.cache.ConnectionCache`
holds the parsed model (re-read only when its fingerprint changed). DuckDB
calls a Python UDF from one thread with up to 2048 rows; the numba kernels
underneath parallelise.
"""
from __future__ import annotations

import duckdb
import numpy as np
import pyarrow as pa
from duckdb import sqltypes as T

from mocapdb.annotation import SEGMENT_ARROW, segment_table
from mocapdb.errors import ParameterError, SchemaError, check_nonnegative
from mocapdb.features import N_FEATURES
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery, annot_margins
from mocapdb.storage.annotations import annotate_motions
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.motions import iter_documents, one_motion
from mocapdb.storage.retrieval import query_stretch, search_archive
from mocapdb.storage.sqltext import sql_text, statement
from mocapdb.templates import mt_distance

#: limits of an inline keyframe query (keyframe_search_words): they bound the
#: memory of a search (one interval list per keyframe) and the chain search
MAX_KEYFRAMES = 32
#: largest finite gap bound, in 30 Hz frames (one hour)
MAX_GAP = 30 * 3600

#: DuckDB's names of the Arrow types the UDFs return
_SQL_TYPE_NAMES = {pa.string(): "VARCHAR", pa.int32(): "INTEGER", pa.float64(): "DOUBLE"}


def _sql_struct(arrow: pa.StructType):
    """The DuckDB struct type of an Arrow struct type (the UDF's declared return type of its values)."""
    return duckdb.struct_type({field.name: _SQL_TYPE_NAMES[field.type] for field in arrow})


#: SQL type of one annotation segment (frames 1-based at 30 Hz): :data:`mocapdb.annotation.SEGMENT_ARROW`
SEGMENT_TYPE = _sql_struct(SEGMENT_ARROW)
#: one hit of ``keyframe_search`` (frames 1-based at 30 Hz)
_HIT_ARROW = pa.struct([("motion_id", pa.int32()), ("start_frame", pa.int32()), ("end_frame", pa.int32())])
HIT_TYPE = _sql_struct(_HIT_ARROW)
#: the SQL types ``similar_to`` reads as a motion id (any other but text is refused, not cast)
_INTEGER_TYPES = {"TINYINT", "SMALLINT", "INTEGER", "BIGINT", "HUGEINT", "UTINYINT", "USMALLINT", "UINTEGER",
                  "UBIGINT", "UHUGEINT"}
#: one result of ``similar_to`` (ranked; frames 1-based at 30 Hz)
_SIMILAR_ARROW = pa.struct([("rank", pa.int32()), ("motion_id", pa.int32()), ("start_frame", pa.int32()),
                            ("end_frame", pa.int32()), ("cost", pa.float64())])
SIMILAR_TYPE = _sql_struct(_SIMILAR_ARROW)


def _column(arr):
    return arr.combine_chunks() if isinstance(arr, pa.ChunkedArray) else arr


def _motions(arr):
    """A motion-id column as (int64 ids, not-NULL mask); NULL rows hold -1."""
    arr = _column(arr)
    known = ~arr.is_null().to_numpy(zero_copy_only=False)
    return np.asarray(arr.fill_null(-1).to_numpy(zero_copy_only=False), dtype=np.int64), known


def _nulls(parts, n_rows):
    """Rows no group answered (a NULL or unknown motion): NULL."""
    out = np.ones(n_rows, bool)
    for rows, _, _ in parts:
        out[rows] = False
    return out


def _refuse(failed):
    """A motion a SQL function cannot use is an error that names it (and says how to repair it)."""
    if failed:
        raise SchemaError("; ".join(reason for _, _, reason in failed))


def _annotated(cache, key, model, motion_ids, **options):
    """:func:`~mocapdb.storage.annotations.annotate_motions` of the distinct known motions of a UDF call."""
    ids = np.unique(motion_ids)
    if not len(ids):
        return
    with cache.cursor() as cur:
        for docs, segs, failed in annotate_motions(cur, cache, key, model, ids, skip_unknown=True,
                                                   max_frames=cache.batch_frames, **options):
            _refuse(failed)
            yield docs, segs


def _groups(*columns):
    """Row indices grouped by the values of small per-row parameters.

    Usually every row of a call has the same model, τ and keyframe setting:
    that case is answered without converting the columns to Python objects.
    """
    columns = [_column(c) for c in columns]
    n = len(columns[0]) if columns else 0
    if n and all(c.null_count in (0, n) and len(c.unique()) == 1 for c in columns):
        return {tuple(c[0].as_py() for c in columns): np.arange(n)}
    out = {}
    for i, k in enumerate(zip(*[c.to_pylist() for c in columns])):
        out.setdefault(k, []).append(i)
    return {k: np.array(v, dtype=np.int64) for k, v in out.items()}


def _list_array(parts, n_rows, nulls, values_type):
    """One ListArray from per-group results.

    ``parts``: (rows, values, counts) per group — the group's rows, their
    values concatenated in the rows' order and the number of values per row.
    Rows in no group (NULL rows) are NULL.
    """
    counts = np.zeros(n_rows, np.int64)
    start_in = np.zeros(n_rows, np.int64)  # position of a row's first value in the concatenation
    base = 0
    for rows, values, row_counts in parts:
        counts[rows] = row_counts
        start_in[rows] = base + np.concatenate(([0], np.cumsum(row_counts)[:-1]))
        base += len(values)
    offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
    values = pa.concat_arrays([v for _, v, _ in parts]) if parts else pa.array([], values_type)
    if len(parts) > 1:  # rows of different groups interleave: gather the values in row order
        order = np.repeat(start_in - offsets[:-1], counts) + np.arange(offsets[-1])
        values = values.take(pa.array(order))
    return pa.ListArray.from_arrays(pa.array(offsets), values, mask=pa.array(np.asarray(nulls, bool)))


def make_udfs(cache):
    """The UDFs of one connection, bound to its cache."""

    def annotate_udf(motion, model_name, fingerprint, tau, keyframes, index_version):
        """``mocap_annotate(...)`` → LIST(segment) per row (see sql/macros.sql)."""
        motion, known = _motions(motion)
        parts = []
        for (name, fp, t, kf, version), rows in _groups(model_name, fingerprint, tau, keyframes,
                                                       index_version).items():
            key, model = cache.model(name, fp)
            check_nonnegative(t, "tau", none="each class's τ")
            per_motion = {}
            for docs, segs in _annotated(cache, key, model, motion[rows[known[rows]]], tau=t, keyframes=kf,
                                         index_version=version):
                table = segment_table(segs, motion_ids=docs.motion_ids, names=[""] * len(docs.names), fps=docs.fps)
                values = pa.StructArray.from_arrays([_column(table.column(f.name)) for f in SEGMENT_ARROW],
                                                    fields=list(SEGMENT_ARROW))
                # the table is sorted by document first
                ends = np.cumsum(np.bincount(segs["doc"], minlength=len(docs.motion_ids)))
                for k, mid in enumerate(docs.motion_ids.tolist()):
                    per_motion[mid] = values.slice(ends[k - 1] if k else 0, ends[k] - (ends[k - 1] if k else 0))
            rows = rows[[int(motion[r]) in per_motion for r in rows]]  # unknown motions stay NULL
            if len(rows):
                got = [per_motion[int(motion[r])] for r in rows]
                parts.append((rows, pa.concat_arrays(got), np.array([len(g) for g in got])))
        return _list_array(parts, len(motion), _nulls(parts, len(motion)), SEGMENT_ARROW)

    def mt_distance_udf(motion, model_name, fingerprint, cls):
        """``mocap_mt_distance(motion, model, fingerprint, class)`` → DOUBLE[] per row (Δ, inf where undefined)."""
        motion, known = _motions(motion)
        parts = []
        for (name, fp, c), rows in _groups(model_name, fingerprint, cls).items():
            _, model = cache.model(name, fp)
            q = _class(model, c).quantized
            per_motion = {}
            with cache.cursor() as cur:
                for docs, failed in iter_documents(cur, np.unique(motion[rows[known[rows]]]), skip_unknown=True,
                                                   max_frames=cache.batch_frames):
                    _refuse(failed)
                    starts = np.concatenate(([0], np.cumsum(docs.lengths)))
                    for k, mid in enumerate(docs.motion_ids.tolist()):
                        per_motion[mid] = mt_distance(docs.words[starts[k]:starts[k + 1]], q)
            rows = rows[[int(motion[r]) in per_motion for r in rows]]
            if len(rows):
                got = [per_motion[int(motion[r])] for r in rows]
                parts.append((rows, pa.array(np.concatenate(got), pa.float64()), np.array([len(g) for g in got])))
        return _list_array(parts, len(motion), _nulls(parts, len(motion)), pa.float64())

    def keyframe_search_udf(model_name, fingerprint, cls, extend, index_version):
        """``mocap_keyframe_search(model, fingerprint, class, extend, version)`` → LIST(hit) per row."""
        per_row = []
        for name, fp, c, ext, version in zip(*[_column(x).to_pylist() for x in
                                               (model_name, fingerprint, cls, extend, index_version)]):
            _, model = cache.model(name, fp)
            query = _class(model, c).keyframe_query
            if query is None:
                raise SchemaError(f"class {c!r} of model {name!r} has no keyframe query; learn one with "
                                  "`mocapdb learn-keyframes`")
            left, right = annot_margins(query) if ext else (0, 0)
            per_row.append(_search(cache, query, left, right, version))
        return _hits_array(per_row)

    def keyframe_search_words_udf(masks, vals, gap_min, gap_max, extend_left, extend_right, index_version):
        """``mocap_keyframe_search_words(masks, values, d_min, d_max, left, right, version)`` → LIST(hit)."""
        per_row = []
        for m, v, lo, hi, left, right, version in zip(*[_column(x).to_pylist() for x in
                                                        (masks, vals, gap_min, gap_max, extend_left,
                                                         extend_right, index_version)]):
            query = inline_query(m, v, lo, hi)
            for name, x in (("extend_left", left), ("extend_right", right)):
                if x is None or not 0 <= x <= MAX_GAP:
                    raise ParameterError(f"keyframe_search_words: {name} must be in 0..{MAX_GAP} frames, got {x}")
            per_row.append(_search(cache, query, left, right, version))
        return _hits_array(per_row)

    def similar_udf(motion, motion_type, first, last, k, index_version):
        """``mocap_similar(motion, typeof(motion), first, last, k, version)`` → LIST(result) per row
        (sql/macros.sql).

        The motion comes as text with its SQL type: an integer is an id, text a
        name (one motion's), anything else an error — a cast would have read
        '86_09' as 8609 and 3.7 as 4. The query stretch is read here and the
        archive searched a batch of motions at a time
        (:func:`~mocapdb.storage.retrieval.search_archive`), for the same reason
        the other UDFs read their own words.
        """
        per_row = []
        for m, t, a, b, limit, version in zip(*[_column(x).to_pylist() for x in
                                                (motion, motion_type, first, last, k, index_version)]):
            if limit is None or limit < 1:
                raise ParameterError(f"similar_to: k must be a positive integer, got {limit}")
            if m is None:
                raise SchemaError("similar_to: no motion with id NULL (see: SELECT motion_id, name FROM motions)")
            if t not in _INTEGER_TYPES and t != "VARCHAR":
                raise ParameterError(f"similar_to: motion must be a motion id (an integer) or a name, got {m} ({t})")
            with cache.cursor() as cur:
                stretch = query_stretch(cur, int(m) if t in _INTEGER_TYPES else one_motion(cur, m), a, b)
            hits = search_archive(cache, [stretch], limit=int(limit), version=version)
            per_row.append(pa.StructArray.from_arrays(
                [pa.array(np.arange(1, hits.size + 1), pa.int32()), pa.array(hits["doc"], pa.int32()),
                 pa.array(hits["start"] + 1, pa.int32()), pa.array(hits["end"] + 1, pa.int32()),
                 pa.array(hits["cost"], pa.float64())], fields=list(_SIMILAR_ARROW)))
        parts = [(np.array([r]), v, np.array([len(v)])) for r, v in enumerate(per_row)]
        return _list_array(parts, len(per_row), np.zeros(len(per_row), bool), _SIMILAR_ARROW)

    return annotate_udf, mt_distance_udf, keyframe_search_udf, keyframe_search_words_udf, similar_udf


def _hits_array(per_row):
    """A ListArray of hit structs, one list per row."""
    parts = [(np.array([r]), hits, np.array([len(hits)])) for r, hits in enumerate(per_row)]
    return _list_array(parts, len(per_row), np.zeros(len(per_row), bool), _HIT_ARROW)


def _class(model, name):
    if name is None:
        raise SchemaError(f"class is NULL; model {model.name!r} has the classes {', '.join(model.class_names)}")
    for c in model.classes:
        if c.name == name:
            return c
    raise SchemaError(f"model {model.name!r} has no class {name!r}; its classes: {', '.join(model.class_names)}")


def _search(cache, query, left, right, version):
    """Hits of a keyframe query on the stored index (a batch of motions at a time) as an Arrow struct array."""
    motion, start, end = cache.keyframe_search(query, extend_left=int(left), extend_right=int(right), version=version)
    return pa.StructArray.from_arrays(
        [pa.array(motion, pa.int32()), pa.array(start + 1, pa.int32()), pa.array(end + 1, pa.int32())],
        fields=list(_HIT_ARROW))


def inline_query(masks, values, gap_min, gap_max) -> KeyframeQuery:
    """Validate an inline keyframe query of ``keyframe_search_words`` (limits: :data:`MAX_KEYFRAMES`,
    :data:`MAX_GAP`).

    Raises
    ------
    ParameterError
        Naming what is malformed.
    """
    what = "keyframe_search_words"
    if masks is None or values is None:
        raise ParameterError(f"{what}: masks and values must not be NULL")
    K = len(masks)
    if not 1 <= K <= MAX_KEYFRAMES:
        raise ParameterError(f"{what}: a query has 1..{MAX_KEYFRAMES} keyframes, got {K}")
    if len(values) != K:
        raise ParameterError(f"{what}: {K} masks but {len(values)} values; give one value per mask")
    gap_min, gap_max = list(gap_min or []), list(gap_max or [])
    if len(gap_min) != K - 1 or len(gap_max) != K - 1:
        raise ParameterError(f"{what}: a query of {K} keyframes needs {K - 1} gap bounds, "
                             f"got {len(gap_min)} d_min and {len(gap_max)} d_max")
    full = (1 << N_FEATURES) - 1
    for k, (m, v) in enumerate(zip(masks, values)):
        if m is None or v is None or m & ~full or v & ~m:
            raise ParameterError(f"{what}: keyframe {k + 1} (mask {m}, value {v}) must be 40-bit words "
                                 "with value bits only where the mask has bits")
    for g, (lo, hi) in enumerate(zip(gap_min, gap_max)):
        if lo is None or not 0 <= lo <= MAX_GAP or (hi is not None and not lo <= hi <= MAX_GAP):
            raise ParameterError(f"{what}: gap {g + 1} must have 0 <= d_min <= d_max <= {MAX_GAP} frames "
                                 f"(d_max NULL = unbounded), got d_min={lo}, d_max={hi}")
    return KeyframeQuery(np.array(masks, np.uint64), np.array(values, np.uint64), np.arange(K, dtype=np.int64),
                         np.array(gap_min, np.float64),
                         np.array([UNBOUNDED if x is None else x for x in gap_max], np.float64), K)


#: how every UDF is registered: Arrow in and out, NULLs passed in (a NULL motion is a NULL answer)
_UDF_OPTIONS = {"type": "arrow", "null_handling": "special", "side_effects": False}


def register(con, *, cache=None, native=False):
    """Register the mocapdb UDFs and temporary macros on a connection.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    cache : ConnectionCache, optional, keyword-only
        The cache the UDFs answer from (default: the connection's own).
    native : bool, keyword-only
        The database loaded the native extension (:mod:`mocapdb.extension.connection`): no UDF is
        registered, and the macros call the native functions. False: every function is a Python
        UDF (the fallback, and the reference the native functions are tested against).

    Returns
    -------
    tuple of callable
        The UDFs registered (none when native). DuckDB registers them with the database instance,
        for every connection of it, but lets go of the Python functions when
        ``con`` closes: whoever keeps the instance open keeps them alive
        (:mod:`mocapdb.extension.connection`).
    """
    if native:
        register_macros(con, native=True)
        return ()
    udfs = make_udfs(connection_cache(con) if cache is None else cache)
    register_python_functions(con, udfs)
    register_macros(con)
    return udfs


def register_python_functions(con, udfs) -> None:
    """Register the Python UDFs of the functions the native extension has (all of ``make_udfs``'s)."""
    annotate_udf, mt_distance_udf, keyframe_search_udf, keyframe_search_words_udf, similar_udf = udfs
    con.create_function("mocap_annotate", annotate_udf,
                        [T.INTEGER, T.VARCHAR, T.VARCHAR, T.DOUBLE, T.BOOLEAN, T.BIGINT],
                        duckdb.list_type(SEGMENT_TYPE), **_UDF_OPTIONS)
    con.create_function("mocap_mt_distance", mt_distance_udf, [T.INTEGER, T.VARCHAR, T.VARCHAR, T.VARCHAR],
                        duckdb.list_type(T.DOUBLE), **_UDF_OPTIONS)
    con.create_function("mocap_keyframe_search", keyframe_search_udf,
                        [T.VARCHAR, T.VARCHAR, T.VARCHAR, T.BOOLEAN, T.BIGINT], duckdb.list_type(HIT_TYPE),
                        **_UDF_OPTIONS)
    con.create_function("mocap_keyframe_search_words", keyframe_search_words_udf,
                        [duckdb.list_type(T.UBIGINT), duckdb.list_type(T.UBIGINT), duckdb.list_type(T.BIGINT),
                         duckdb.list_type(T.BIGINT), T.BIGINT, T.BIGINT, T.BIGINT],
                        duckdb.list_type(HIT_TYPE), **_UDF_OPTIONS)
    con.create_function("mocap_similar", similar_udf,
                        [T.VARCHAR, T.VARCHAR, T.INTEGER, T.INTEGER, T.INTEGER, T.BIGINT],
                        duckdb.list_type(SIMILAR_TYPE), **_UDF_OPTIONS)


def register_macros(con, *, native=False) -> None:
    """Install the temporary macros (``annotate``, ``mt_distance``, …) on a connection whose
    database instance has the functions (macros are per connection, UDFs per instance): over the
    native functions (``native``) or the Python UDFs."""
    con.execute(statement("similar_rows.sql", "view"))
    if native:
        con.execute(sql_text("native_macros.sql"))
    else:
        con.execute(sql_text("macros.sql"))
        con.execute(sql_text("similar_macros.sql"))
    con.execute(statement("similar_rows.sql", "overloads"))


__all__ = ["register", "register_macros", "register_python_functions", "make_udfs", "inline_query", "SEGMENT_TYPE", "HIT_TYPE", "SIMILAR_TYPE",
           "MAX_KEYFRAMES", "MAX_GAP"]
