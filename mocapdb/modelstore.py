"""Class models in the database: save, load, list, and the shipped default model.

A model occupies rows of ``models``, ``classes``, ``templates``,
``keyframe_queries`` and ``keyframes`` (sql/schema.sql), all keyed by the
model name. The default model ships with the package as Parquet files of
those rows (``mocapdb/models/default/``) and is loaded into a database the
first time it is needed.
"""
from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import ParameterError, SchemaError
from .keyframes import UNBOUNDED, KeyframeQuery
from .model import ClassModel, Model
from .templates import MotionTemplate, QuantizedTemplate

DEFAULT_MODEL = "default"
MODEL_TABLES = ("models", "classes", "templates", "keyframe_queries", "keyframes", "ga_statistics")


def fingerprint(model: Model) -> str:
    """A digest of everything annotation reads from a model (changes when it changes)."""
    h = hashlib.sha256()
    h.update(repr(model.labels).encode())
    for c in model.classes:
        q = c.quantized
        h.update(f"{c.name}|{c.label}|{c.delta!r}|{c.tau!r}".encode())
        for a in (q.mask, q.value, q.weights):
            h.update(np.ascontiguousarray(a).tobytes())
        kq = c.keyframe_query
        if kq is not None:
            h.update(repr(kq.feature_sets).encode() + str(kq.template_length).encode())
            for a in (kq.mask, kq.value, kq.positions, kq.d_min, kq.d_max):
                h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def model_names(con) -> list[str]:
    """Names of the models stored in the database."""
    return [r[0] for r in con.execute("SELECT model FROM models ORDER BY model").fetchall()]


def drop_model(con, name: str) -> None:
    """Delete a model's rows from every model table (inside the caller's transaction)."""
    for table in MODEL_TABLES:
        con.execute(f"DELETE FROM {table} WHERE model = ?", [name])


def save_model(con, model: Model, *, description=None, source=None, replace=False,
               keyframe_stats=None, ga_statistics=None) -> str:
    """Store a model (one transaction).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : Model
    description, source : str, optional, keyword-only
        Free text kept in ``models``.
    replace : bool, keyword-only
        Overwrite a stored model of the same name (otherwise an error).
    keyframe_stats : dict, optional, keyword-only
        class name -> dict(source=…, fitness=…, precision=…, recall=…) kept in
        ``keyframe_queries`` (default source ``"manual"``).
    ga_statistics : list of tuple, optional, keyword-only
        Rows ``(class, run, generation, mean_precision, mean_recall,
        mean_fitness, best_fitness, mean_keyframes)`` for ``ga_statistics``.

    Returns
    -------
    str
        The model's fingerprint.
    """
    exists = con.execute("SELECT count(*) FROM models WHERE model = ?", [model.name]).fetchall()[0][0]
    if exists and not replace:
        raise ParameterError(f"model {model.name!r} already exists; pass replace=True (--replace) "
                             "or choose another name")
    fp = fingerprint(model)
    label_id = {lab: i + 1 for i, lab in enumerate(model.labels)}
    classes, templates, queries, keyframes = [], [], [], []
    for cid, c in enumerate(model.classes, start=1):
        q = c.quantized
        n_clips = getattr(c.template, "n_clips", None) if c.template is not None else None
        classes.append((model.name, c.name, cid, c.label, label_id[c.label], float(c.delta), float(c.tau), n_clips))
        real = c.template.real if c.template is not None and len(c.template) == len(q) else None
        for col in range(len(q)):
            templates.append((model.name, c.name, col + 1, int(q.mask[col]), int(q.value[col]),
                              float(q.weights[col]),
                              None if real is None else real[col].tolist(),
                              None if real is None else float(c.template.weights[col])))
        kq = c.keyframe_query
        if kq is not None:
            st = (keyframe_stats or {}).get(c.name, {})
            queries.append((model.name, c.name, kq.n_keyframes, int(kq.template_length),
                            st.get("source", "manual"), st.get("fitness"), st.get("precision"), st.get("recall")))
            for k in range(kq.n_keyframes):
                last = k == kq.n_keyframes - 1
                d_max = None if last or kq.d_max[k] >= UNBOUNDED else int(kq.d_max[k])
                keyframes.append((model.name, c.name, k + 1, kq.feature_sets[k], int(kq.mask[k]), int(kq.value[k]),
                                  int(kq.positions[k]) + 1, None if last else int(kq.d_min[k]), d_max))
    con.begin()
    try:
        drop_model(con, model.name)
        con.execute("INSERT INTO models (model, description, source, fingerprint) VALUES (?, ?, ?, ?)",
                    [model.name, description, source, fp])
        _insert(con, "classes", classes)
        _insert(con, "templates", templates)
        _insert(con, "keyframe_queries", queries)
        _insert(con, "keyframes", keyframes)
        _insert(con, "ga_statistics", [(model.name, *r) for r in (ga_statistics or [])])
        con.commit()
    except BaseException:
        con.rollback()
        raise
    return fp


_COLUMNS = {
    "classes": "model, class, class_id, label, label_id, delta, tau, n_clips",
    "templates": "model, class, col, mask, value, weight, real, real_weight",
    "keyframe_queries": "model, class, n_keyframes, template_length, source, fitness, precision, recall",
    "keyframes": "model, class, k, feature_set, mask, value, position, d_min, d_max",
    "ga_statistics": "model, class, run, generation, mean_precision, mean_recall, mean_fitness, best_fitness, "
                     "mean_keyframes",
}


def _insert(con, table, rows):
    if rows:
        cols = _COLUMNS[table]
        marks = ", ".join("?" * len(cols.split(",")))
        con.executemany(f"INSERT INTO {table} ({cols}) VALUES ({marks})", rows)


def ensure_model(con, name: str) -> None:
    """Make sure a model is in the database, loading the shipped default on first use.

    Raises
    ------
    SchemaError
        If ``name`` is neither stored nor the shipped default.
    """
    if con.execute("SELECT count(*) FROM models WHERE model = ?", [name]).fetchall()[0][0]:
        return
    if name == DEFAULT_MODEL:
        load_packaged_model(con)
        return
    known = ", ".join(model_names(con)) or "none"
    raise SchemaError(f"no model {name!r} in the database (stored models: {known}); "
                      "train one with `mocapdb train` or use the default model")


def load_model(con, name: str = DEFAULT_MODEL) -> Model:
    """Read a stored model back into a :class:`~mocapdb.model.Model`."""
    ensure_model(con, name)
    cls_rows = con.execute(
        "SELECT class, label, label_id, delta, tau FROM classes WHERE model = ? ORDER BY class_id", [name]).fetchall()
    labels = [r[0] for r in con.execute(
        "SELECT DISTINCT label, label_id FROM classes WHERE model = ? ORDER BY label_id", [name]).fetchall()]
    classes = []
    for cname, label, _, delta, tau in cls_rows:
        t = con.execute("SELECT mask, value, weight, real, real_weight FROM templates "
                        "WHERE model = ? AND class = ? ORDER BY col", [name, cname]).fetchall()
        quantized = QuantizedTemplate(np.array([r[0] for r in t], np.uint64), np.array([r[1] for r in t], np.uint64),
                                      np.array([r[2] for r in t], np.float64))
        template = None
        if t and all(r[3] is not None for r in t):
            template = MotionTemplate(np.array([r[3] for r in t], np.float64), np.array([r[4] for r in t], np.float64))
        classes.append(ClassModel(cname, label, template=template, quantized=quantized, delta=delta, tau=tau,
                                  keyframe_query=_load_query(con, name, cname)))
    return Model(name, tuple(classes), labels=tuple(labels))


def keyframe_query_stats(con, name: str) -> dict:
    """class -> dict(source, fitness, precision, recall) of a stored model's keyframe queries."""
    rows = con.execute("SELECT class, source, fitness, precision, recall FROM keyframe_queries WHERE model = ?",
                       [name]).fetchall()
    return {r[0]: dict(zip(("source", "fitness", "precision", "recall"), r[1:])) for r in rows}


def _load_query(con, model, cname):
    q = con.execute("SELECT template_length FROM keyframe_queries WHERE model = ? AND class = ?",
                    [model, cname]).fetchall()
    if not q:
        return None
    rows = con.execute("SELECT feature_set, mask, value, position, d_min, d_max FROM keyframes "
                       "WHERE model = ? AND class = ? ORDER BY k", [model, cname]).fetchall()
    return query_from_rows(rows, q[0][0])


def query_from_rows(rows, template_length) -> KeyframeQuery:
    """Build a KeyframeQuery from ``(feature_set, mask, value, position, d_min, d_max)`` rows
    as stored in ``keyframes`` (1-based positions; NULL d_max = unbounded)."""
    gaps = rows[:-1]
    return KeyframeQuery(
        np.array([r[1] for r in rows], np.uint64), np.array([r[2] for r in rows], np.uint64),
        np.array([r[3] - 1 for r in rows], np.int64),
        np.array([r[4] for r in gaps], np.float64),
        np.array([np.inf if r[5] is None else r[5] for r in gaps], np.float64),
        int(template_length), tuple(r[0] for r in rows))


def model_from_payload(payload: dict) -> Model:
    """Build a Model from one row of the ``model_payload`` view (as a Python dict)."""
    labels = tuple(payload["labels"])
    classes = []
    for c in payload["classes"]:
        q = QuantizedTemplate(np.array(c["mask"], np.uint64), np.array(c["value"], np.uint64),
                              np.array(c["weights"], np.float64))
        kf = c.get("keyframes")
        query = None
        if kf is not None:
            d_max = np.array(kf["d_max"], np.float64)
            query = KeyframeQuery(np.array(kf["mask"], np.uint64), np.array(kf["value"], np.uint64),
                                  np.array(kf["positions"], np.int64) - 1, np.array(kf["d_min"], np.float64),
                                  np.where(d_max < 0, np.inf, d_max), int(kf["template_length"]),
                                  tuple(kf["feature_sets"]))
        classes.append(ClassModel(c["class"], labels[c["label_id"] - 1], quantized=q, delta=c["delta"],
                                  tau=c["tau"], keyframe_query=query))
    return Model(payload["model_name"], tuple(classes), labels=labels)


# -- the shipped default model ------------------------------------------------

def packaged_model_dir(name: str = DEFAULT_MODEL):
    """Where a model shipped with the package keeps its Parquet files."""
    return resources.files("mocapdb.models").joinpath(name)


def load_packaged_model(con, name: str = DEFAULT_MODEL) -> None:
    """Insert a model shipped with the package (Parquet rows per model table)."""
    d = packaged_model_dir(name)
    if not d.joinpath("models.parquet").is_file():
        raise SchemaError(f"the package has no model {name!r} (expected {d}/models.parquet); "
                          "reinstall mocapdb or retrain with benchmarks/train_default_model.py")
    con.begin()
    try:
        drop_model(con, name)
        for table in MODEL_TABLES:
            if not d.joinpath(f"{table}.parquet").is_file():
                continue  # e.g. a model without GA statistics
            path = str(d.joinpath(f"{table}.parquet")).replace("'", "''")
            cols = "model, description, source, fingerprint" if table == "models" else _COLUMNS[table]
            con.execute(f"INSERT INTO {table} ({cols}) SELECT {cols} FROM read_parquet('{path}')")
        con.commit()
    except BaseException:
        con.rollback()
        raise


def export_model(con, name: str, directory) -> Path:
    """Write a stored model's rows as Parquet files (the packaged-model format)."""
    ensure_model(con, name)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    for table in MODEL_TABLES:
        cols = "model, description, source, fingerprint" if table == "models" else _COLUMNS[table]
        order = {"models": "model", "classes": "class_id", "templates": "class, col",
                 "keyframe_queries": "class", "keyframes": "class, k",
                 "ga_statistics": "class, run, generation"}[table]
        path = str(d / f"{table}.parquet").replace("'", "''")
        con.execute(f"COPY (SELECT {cols} FROM {table} WHERE model = ? ORDER BY {order}) TO '{path}' "
                    f"(FORMAT parquet)", [name])
    return d


__all__ = ["DEFAULT_MODEL", "save_model", "model_from_payload", "keyframe_query_stats", "load_model", "ensure_model", "model_names", "drop_model",
           "fingerprint", "load_packaged_model", "export_model", "query_from_rows"]
