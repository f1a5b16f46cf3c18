"""Python UDFs behind the SQL functions, and their registration.

Each UDF is Arrow in / Arrow out and a thin call of the library function of
the same job; a UDF never queries its connection — the temporary macros of
``sql/macros.sql`` pass everything in (the motion's words as a list, the model
as one struct from the ``model_payload`` view). DuckDB calls a Python UDF from
one thread with up to 2048 rows; the numba kernels underneath parallelise.
"""
from __future__ import annotations

from collections import OrderedDict

import duckdb
import numpy as np
import pyarrow as pa
from duckdb import sqltypes as T

from mocapdb.api import segments_of_documents
from mocapdb.database import sql_text
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.keyframes import KeyframeQuery, chain_search, intervals_from_runs
from mocapdb.modelstore import model_from_payload
from mocapdb.postings import motion_positions
from mocapdb.sdtw import mt_distance
from mocapdb.templates import QuantizedTemplate

#: SQL type of one annotation segment (frames 1-based at 30 Hz)
SEGMENT_TYPE = duckdb.struct_type({
    "label": T.VARCHAR, "start_frame": T.INTEGER, "end_frame": T.INTEGER, "cost": T.DOUBLE,
    "start_s": T.DOUBLE, "end_s": T.DOUBLE})
_SEGMENT_ARROW = pa.struct([("label", pa.string()), ("start_frame", pa.int32()), ("end_frame", pa.int32()),
                            ("cost", pa.float64()), ("start_s", pa.float64()), ("end_s", pa.float64())])

# Models parsed from payloads, keyed by fingerprint (a content hash, so an
# entry never goes stale); small because a database holds few models.
_MODELS: OrderedDict = OrderedDict()
_MODEL_CACHE_SIZE = 8


def _model(payload_row: dict):
    fp = payload_row["fingerprint"]
    m = _MODELS.get(fp)
    if m is None:
        m = model_from_payload(payload_row)
        _MODELS[fp] = m
        while len(_MODELS) > _MODEL_CACHE_SIZE:
            _MODELS.popitem(last=False)
    else:
        _MODELS.move_to_end(fp)
    return m


def _lists(arr):
    """A LIST(UBIGINT) Arrow column as (flat words, lengths, null mask)."""
    arr = arr.combine_chunks() if isinstance(arr, pa.ChunkedArray) else arr
    nulls = arr.is_null().to_numpy(zero_copy_only=False)
    offsets = arr.offsets.to_numpy()
    lengths = np.diff(offsets).astype(np.int64)
    lengths[nulls] = 0
    flat = arr.flatten().to_numpy(zero_copy_only=False).astype(np.uint64, copy=False)
    return flat, lengths, nulls


def _column(arr):
    arr = arr.combine_chunks() if isinstance(arr, pa.ChunkedArray) else arr
    return arr


def _groups(*columns):
    """Row indices grouped by the values of small per-row parameters."""
    keys = list(zip(*[c.to_pylist() for c in columns]))
    out = {}
    for i, k in enumerate(keys):
        out.setdefault(k, []).append(i)
    return out


def annotate_udf(words, fps, payload, model_name, tau, keyframes):
    """``mocap_annotate(words, fps, payload, model, tau, keyframes)`` → LIST(segment) per row."""
    flat, lengths, nulls = _lists(words)
    fps = _column(fps).to_numpy(zero_copy_only=False)
    payload = _column(payload)
    fingerprints = payload.field("fingerprint") if len(payload) else pa.array([], pa.string())
    starts = np.concatenate(([0], np.cumsum(lengths)))
    per_row = [None] * len(lengths)
    for (fp, name, t, kf), rows in _groups(fingerprints, _column(model_name), _column(tau),
                                           _column(keyframes)).items():
        if fp is None:
            raise SchemaError(f"no model {name!r} in the database; train one with `mocapdb train` "
                              "or use the default model")
        model = _model(payload[rows[0]].as_py())
        rows = [r for r in rows if not nulls[r]]
        if not rows:
            continue
        sel = np.concatenate([np.arange(starts[r], starts[r + 1]) for r in rows]) if rows else np.zeros(0, int)
        segs = segments_of_documents(flat[sel], lengths[rows], model, tau=t, keyframes=kf)
        segs = segs[np.lexsort((segs["label"], segs["start"], segs["doc"]))]
        cut = np.searchsorted(segs["doc"], np.arange(len(rows) + 1))
        for k, r in enumerate(rows):
            per_row[r] = segs[cut[k]:cut[k + 1]]
    # one struct array for all rows + list offsets
    counts = np.array([0 if s is None else len(s) for s in per_row], dtype=np.int64)
    out_offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
    parts = [s for s in per_row if s is not None and len(s)]
    seg = np.concatenate(parts) if parts else np.zeros(0, dtype=[("label", "U1"), ("start", int), ("end", int),
                                                                  ("cost", float)])
    seg_fps = np.repeat(fps, counts)
    values = pa.StructArray.from_arrays(
        [pa.array(seg["label"].tolist(), pa.string()), pa.array(seg["start"] + 1, pa.int32()),
         pa.array(seg["end"] + 1, pa.int32()), pa.array(seg["cost"], pa.float64()),
         pa.array(seg["start"] / seg_fps, pa.float64()), pa.array((seg["end"] + 1) / seg_fps, pa.float64())],
        fields=list(_SEGMENT_ARROW))
    return pa.ListArray.from_arrays(pa.array(out_offsets), values, mask=pa.array(nulls))


def mt_distance_udf(words, template, cls, model_name):
    """``mocap_mt_distance(words, class_payload, class, model)`` → DOUBLE[] per row (Δ, inf where undefined)."""
    flat, lengths, nulls = _lists(words)
    template, cls, model_name = _column(template), _column(cls), _column(model_name)
    starts = np.concatenate(([0], np.cumsum(lengths)))
    out = []
    templates = {}  # (model, class) -> QuantizedTemplate, parsed once per call
    for r in range(len(lengths)):
        if nulls[r]:
            out.append(None)
            continue
        key = (model_name[r].as_py(), cls[r].as_py())
        q = templates.get(key)
        if q is None:
            if not template[r].is_valid:
                raise SchemaError(f"model {key[0]!r} has no class {key[1]!r} "
                                  "(see: SELECT class FROM classes WHERE model = …)")
            t = template[r].as_py()
            q = templates[key] = QuantizedTemplate(np.array(t["mask"], np.uint64), np.array(t["value"], np.uint64),
                                                   np.array(t["weights"], np.float64))
        out.append(mt_distance(flat[starts[r]:starts[r + 1]], q))
    counts = np.array([0 if d is None else len(d) for d in out], dtype=np.int64)
    offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
    values = np.concatenate([d for d in out if d is not None]) if counts.any() else np.zeros(0)
    return pa.ListArray.from_arrays(pa.array(offsets), pa.array(values, pa.float64()), mask=pa.array(nulls))


_HIT_ARROW = pa.struct([("motion_id", pa.int32()), ("start_frame", pa.int32()), ("end_frame", pa.int32())])


def keyframe_search_udf(n_keyframes, gap_min, gap_max, runs, motions, extend_left, extend_right):
    """``mocap_keyframe_search(K, d_min[], d_max[], matching runs, motion lengths, margins)``.

    ``runs`` are the postings rows (keyframe k, motion, 1-based start, length)
    whose word matches keyframe k; the chain search of KEYFRAMES.md §5 turns
    them into segments. One row per call (the macro aggregates).
    """
    out_offsets, values, nulls = [0], [], []
    for r in range(len(n_keyframes)):
        K = _column(n_keyframes)[r].as_py()
        if K is None:
            nulls.append(True)
            out_offsets.append(out_offsets[-1])
            continue
        d_min = np.array(_column(gap_min)[r].as_py() or [], np.float64)
        d_max = np.array([np.inf if x is None or x < 0 else x for x in (_column(gap_max)[r].as_py() or [])],
                         np.float64)
        if len(d_min) != K - 1 or len(d_max) != K - 1:
            raise ParameterError(f"a query of {K} keyframes needs {K - 1} gap bounds, "
                                 f"got {len(d_min)} d_min and {len(d_max)} d_max")
        query = KeyframeQuery(np.zeros(K, np.uint64), np.zeros(K, np.uint64), np.zeros(K, np.int64),
                              d_min, d_max, 1)
        mot = _column(motions)[r]
        ids = np.asarray(mot.values.field("motion_id"), dtype=np.int64) if mot.is_valid else np.zeros(0, np.int64)
        lens = np.asarray(mot.values.field("n_frames"), dtype=np.int64) if mot.is_valid else np.zeros(0, np.int64)
        order = np.argsort(ids)
        ids, lens = ids[order], lens[order]
        rr = _column(runs)[r]
        if rr.is_valid and len(rr.values):
            v = rr.values
            doc = motion_positions(ids, v.field("motion_id"))
            iv = intervals_from_runs(np.asarray(v.field("k")), doc, np.asarray(v.field("start_frame")) - 1,
                                     np.asarray(v.field("n_frames")))
            segs = chain_search(iv, query, lens, extend_left=_column(extend_left)[r].as_py() or 0,
                                extend_right=_column(extend_right)[r].as_py() or 0)
            values.append(pa.StructArray.from_arrays(
                [pa.array(ids[segs.doc], pa.int32()), pa.array(segs.start + 1, pa.int32()),
                 pa.array(segs.end + 1, pa.int32())], fields=list(_HIT_ARROW)))
            out_offsets.append(out_offsets[-1] + len(segs.doc))
        else:
            out_offsets.append(out_offsets[-1])
        nulls.append(False)
    flat = pa.concat_arrays(values) if values else pa.array([], _HIT_ARROW)
    return pa.ListArray.from_arrays(pa.array(out_offsets, pa.int32()), flat, mask=pa.array(nulls))


def register(con) -> None:
    """Register the mocapdb UDFs and temporary macros on a connection."""
    ubigint_list = duckdb.list_type(T.UBIGINT)
    # The payload types are whatever the views produce; read them from the catalog.
    payload_type = duckdb.sqltype(_payload_type(con, "model"))
    class_type = duckdb.sqltype(_payload_type(con, "class"))
    con.create_function("mocap_annotate", annotate_udf,
                        [ubigint_list, T.DOUBLE, payload_type, T.VARCHAR, T.DOUBLE, T.BOOLEAN],
                        duckdb.list_type(SEGMENT_TYPE), type="arrow", null_handling="special",
                        side_effects=False)
    con.create_function("mocap_mt_distance", mt_distance_udf,
                        [ubigint_list, class_type, T.VARCHAR, T.VARCHAR],
                        duckdb.list_type(T.DOUBLE), type="arrow", null_handling="special",
                        side_effects=False)
    run_type = duckdb.list_type(duckdb.struct_type(
        {"k": T.BIGINT, "motion_id": T.INTEGER, "start_frame": T.INTEGER, "n_frames": T.INTEGER}))
    length_type = duckdb.list_type(duckdb.struct_type({"motion_id": T.INTEGER, "n_frames": T.INTEGER}))
    hit_type = duckdb.list_type(duckdb.struct_type(
        {"motion_id": T.INTEGER, "start_frame": T.INTEGER, "end_frame": T.INTEGER}))
    con.create_function("mocap_keyframe_search", keyframe_search_udf,
                        [T.BIGINT, duckdb.list_type(T.BIGINT), duckdb.list_type(T.BIGINT), run_type, length_type,
                         T.BIGINT, T.BIGINT],
                        hit_type, type="arrow", null_handling="special", side_effects=False)
    con.execute(sql_text("macros.sql"))
    from mocapdb.postings import index_exists

    con.execute(sql_text("keyframe_macros.sql" if index_exists(con) else "keyframe_macros_missing.sql"))


def _payload_type(con, which) -> str:
    """SQL type string of the model payload (``model``) or of one class entry (``class``)."""
    cols = dict(con.execute(
        "SELECT column_name, data_type FROM duckdb_columns() WHERE table_name = 'model_payload'").fetchall())
    if which == "class":
        return cols["classes"][:-2]  # STRUCT(...)[] -> STRUCT(...)
    return (f"STRUCT(model_name {cols['model_name']}, fingerprint {cols['fingerprint']}, "
            f"labels {cols['labels']}, classes {cols['classes']})")


__all__ = ["register", "annotate_udf", "mt_distance_udf", "SEGMENT_TYPE"]
