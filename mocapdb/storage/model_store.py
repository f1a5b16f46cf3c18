"""Class models in the database: one codec, save, load, and the models shipped with the package.

A model occupies rows of ``models``, ``classes``, ``templates``,
``keyframe_queries``, ``keyframes``, ``confidence_maps`` and ``ga_statistics`` (sql/schema.sql),
all keyed by the model name. :func:`model_tables` encodes a
:class:`~mocapdb.annotation.Model` as Arrow tables of exactly those rows and
:func:`model_from_tables` decodes them — the one codec, used for the
database, for the Parquet files of the shipped models
(``mocapdb/shipped_models/<name>/<table>.parquet``) and for the SQL functions. An
unbounded keyframe gap is NULL in rows and :data:`mocapdb.keyframes.UNBOUNDED`
in memory.

The shipped models (:data:`SHIPPED_MODELS`) are installed with the schema
(:func:`install_shipped_models`) and refreshed when the package brings a new
version; a read-only database without them reads them from the package.
"""
from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mocapdb.annotation import ClassModel, ConfidenceMap, Model
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction
from mocapdb.templates import MotionTemplate, QuantizedTemplate

DEFAULT_MODEL = "default"
#: models that ship with the package, installed into every database
SHIPPED_MODELS = ("default", "toolbox")
#: the model tables, in dependency order
MODEL_TABLES = ("models", "classes", "templates", "keyframe_queries", "keyframes", "confidence_maps", "ga_statistics")


def _sql(name):
    return statement("models.sql", name)


# -- the codec ----------------------------------------------------------------

def fingerprint(model: Model) -> str:
    """A digest of everything annotation reads from a model (changes when it changes)."""
    h = hashlib.sha256()
    h.update(repr(model.labels).encode())
    if model.margin:  # models without the segment filters keep their fingerprints
        h.update(f"margin={model.margin!r}".encode())
    if model.concurrent_labels:  # as may models without concurrent labels
        h.update(f"concurrent={model.concurrent_labels!r}".encode())
    for c in model.classes:
        q = c.quantized
        h.update(f"{c.name}|{c.label}|{c.delta!r}|{c.tau!r}".encode())
        if c.min_frames:
            h.update(f"min_frames={c.min_frames}".encode())
        for a in (q.mask, q.value, q.weights):
            h.update(np.ascontiguousarray(a).tobytes())
        kq = c.keyframe_query
        if kq is not None:
            h.update(repr(kq.feature_sets).encode() + str(kq.template_length).encode())
            for a in (kq.mask, kq.value, kq.positions, kq.d_min, kq.d_max):
                h.update(np.ascontiguousarray(a).tobytes())
    for m in model.confidence_maps:  # models without maps keep their fingerprints
        h.update(f"confidence|{m.label}|{m.min_length}|{m.cuts!r}|{m.values!r}".encode())
        if m.length_weight:  # and maps of the raw score alone theirs
            h.update(f"length|{m.length_weight!r}|{m.full_length}".encode())
            if m.length_product:  # and maps of the length added, as before
                h.update(b"product")
    return h.hexdigest()[:16]


def model_tables(model: Model, *, description=None, source=None, keyframe_stats=None, ga_statistics=None,
                 shipped=False) -> dict:
    """Encode a model as the rows of the model tables.

    Parameters
    ----------
    model : Model
    description, source : str, optional
        Free text kept in ``models``.
    keyframe_stats : dict, optional
        class name -> dict(source=…, fitness=…, precision=…, recall=…) kept in
        ``keyframe_queries`` (default source ``"manual"``).
    ga_statistics : list of tuple, optional
        Rows ``(class, run, generation, mean_precision, mean_recall,
        mean_fitness, best_fitness, mean_keyframes)``.
    shipped : bool
        Whether the model is one of the package's (refreshed on upgrade).

    Returns
    -------
    dict of str to pyarrow.Table
        One table per name of :data:`MODEL_TABLES`, columns named as in the schema.
    """
    name = model.name
    label_id = {lab: i + 1 for i, lab in enumerate(model.labels)}
    classes, templates, queries, keyframes = [], [], [], []
    for cid, c in enumerate(model.classes, start=1):
        q = c.quantized
        n_clips = getattr(c.template, "n_clips", None) if c.template is not None else None
        classes.append((name, c.name, cid, c.label, label_id[c.label], float(c.delta), float(c.tau), n_clips,
                        int(c.min_frames)))
        real = c.template.real if c.template is not None and len(c.template) == len(q) else None
        for col in range(len(q)):
            templates.append((name, c.name, col + 1, int(q.mask[col]), int(q.value[col]), float(q.weights[col]),
                              None if real is None else real[col].tolist(),
                              None if real is None else float(c.template.weights[col])))
        kq = c.keyframe_query
        if kq is None:
            continue
        st = (keyframe_stats or {}).get(c.name, {})
        queries.append((name, c.name, kq.n_keyframes, int(kq.template_length), st.get("source", "manual"),
                        st.get("fitness"), st.get("precision"), st.get("recall")))
        for k in range(kq.n_keyframes):
            last = k == kq.n_keyframes - 1
            d_max = None if last or kq.d_max[k] >= UNBOUNDED else int(kq.d_max[k])
            keyframes.append((name, c.name, k + 1, kq.feature_sets[k], int(kq.mask[k]), int(kq.value[k]),
                              int(kq.positions[k]) + 1, None if last else int(kq.d_min[k]), d_max))

    maps = [(name, m.label, m.min_length, k + 1, cut, value, m.length_weight, m.full_length, m.length_product)
            for m in model.confidence_maps
            for k, (cut, value) in enumerate(zip(m.cuts, m.values))]

    def table(rows, schema):
        return pa.Table.from_pylist([dict(zip(schema.names, r)) for r in rows], schema=schema)

    return {
        "models": table([(name, description, source, fingerprint(model), shipped, float(model.margin),
                         list(model.concurrent_labels))],
                        _SCHEMAS["models"]),
        "classes": table(classes, _SCHEMAS["classes"]),
        "templates": table(templates, _SCHEMAS["templates"]),
        "keyframe_queries": table(queries, _SCHEMAS["keyframe_queries"]),
        "keyframes": table(keyframes, _SCHEMAS["keyframes"]),
        "confidence_maps": table(maps, _SCHEMAS["confidence_maps"]),
        "ga_statistics": table([(name, *r) for r in (ga_statistics or [])], _SCHEMAS["ga_statistics"]),
    }


_U64, _I32, _F64, _STR = pa.uint64(), pa.int32(), pa.float64(), pa.string()
#: Arrow types of the rows the codec writes (names as in sql/schema.sql)
_SCHEMAS = {
    "models": pa.schema([("model", _STR), ("description", _STR), ("source", _STR), ("fingerprint", _STR),
                         ("shipped", pa.bool_()), ("margin", _F64), ("concurrent_labels", pa.list_(_STR))]),
    "classes": pa.schema([("model", _STR), ("class", _STR), ("class_id", _I32), ("label", _STR),
                          ("label_id", _I32), ("delta", _F64), ("tau", _F64), ("n_clips", _I32),
                          ("min_frames", _I32)]),
    "templates": pa.schema([("model", _STR), ("class", _STR), ("col", _I32), ("mask", _U64), ("value", _U64),
                            ("weight", _F64), ("real", pa.list_(_F64)), ("real_weight", _F64)]),
    "keyframe_queries": pa.schema([("model", _STR), ("class", _STR), ("n_keyframes", _I32),
                                   ("template_length", _I32), ("source", _STR), ("fitness", _F64),
                                   ("precision", _F64), ("recall", _F64)]),
    "keyframes": pa.schema([("model", _STR), ("class", _STR), ("k", _I32), ("feature_set", _STR), ("mask", _U64),
                            ("value", _U64), ("position", _I32), ("d_min", _I32), ("d_max", _I32)]),
    "confidence_maps": pa.schema([("model", _STR), ("label", _STR), ("min_length", _I32), ("k", _I32),
                                  ("cut", _F64), ("value", _F64), ("length_weight", _F64),
                                  ("full_length", _I32), ("length_product", pa.bool_())]),
    "ga_statistics": pa.schema([("model", _STR), ("class", _STR), ("run", _I32), ("generation", _I32),
                                ("mean_precision", _F64), ("mean_recall", _F64), ("mean_fitness", _F64),
                                ("best_fitness", _F64), ("mean_keyframes", _F64)]),
}


def _groups(table: pa.Table, order: tuple) -> dict:
    """Rows of ``table`` as numpy columns grouped by class, each group sorted by ``order``."""
    if table.num_rows == 0:
        return {}
    table = table.sort_by([("class", "ascending")] + [(c, "ascending") for c in order])
    cls = np.asarray(table.column("class").to_pylist(), dtype=object)
    starts = np.flatnonzero(np.r_[True, cls[1:] != cls[:-1]])
    bounds = np.r_[starts, len(cls)]
    cols = {c: table.column(c) for c in table.column_names}
    return {cls[a]: {c: v.slice(a, b - a) for c, v in cols.items()} for a, b in zip(bounds[:-1], bounds[1:])}


def _np(col, dtype):
    return np.asarray(col.to_numpy(zero_copy_only=False), dtype=dtype)


def model_from_tables(tables: dict) -> Model:
    """Decode the rows of one model (as written by :func:`model_tables`) into a :class:`Model`.

    Parameters
    ----------
    tables : dict of str to pyarrow.Table
        At least ``models``, ``classes``, ``templates``, ``keyframe_queries``
        and ``keyframes``, each holding the rows of one model only.
    """
    name = tables["models"].column("model")[0].as_py()
    cls = tables["classes"].sort_by("class_id").to_pylist()
    labels = [label for _, label in sorted({(r["label_id"], r["label"]) for r in cls})]
    if len(set(labels)) != len({r["label_id"] for r in cls}):
        raise SchemaError(f"model {name!r}: labels and label ids of its classes disagree")
    templates = _groups(tables["templates"], ("col",))
    queries = {r["class"]: r for r in tables["keyframe_queries"].to_pylist()}
    keyframes = _groups(tables["keyframes"], ("k",))
    out = []
    for r in cls:
        t = templates.get(r["class"])
        if t is None:
            raise SchemaError(f"model {name!r}: class {r['class']!r} has no template rows")
        quantized = QuantizedTemplate(_np(t["mask"], np.uint64), _np(t["value"], np.uint64),
                                      _np(t["weight"], np.float64))
        template = None
        if t["real"].null_count == 0 and t["real_weight"].null_count == 0:
            template = MotionTemplate(np.array(t["real"].to_pylist(), np.float64), _np(t["real_weight"], np.float64))
        query = None
        if r["class"] in queries:
            k = keyframes.get(r["class"])
            if k is None:
                raise SchemaError(f"model {name!r}: the keyframe query of {r['class']!r} has no keyframes")
            d_max = k["d_max"].to_pylist()[:-1]
            query = KeyframeQuery(
                _np(k["mask"], np.uint64), _np(k["value"], np.uint64), _np(k["position"], np.int64) - 1,
                np.array([0 if x is None else x for x in k["d_min"].to_pylist()[:-1]], np.float64),
                np.array([UNBOUNDED if x is None else x for x in d_max], np.float64),
                int(queries[r["class"]]["template_length"]), tuple(k["feature_set"].to_pylist()))
        out.append(ClassModel(r["class"], r["label"], template=template, quantized=quantized, delta=r["delta"],
                              tau=r["tau"], keyframe_query=query, min_frames=int(r.get("min_frames") or 0)))
    models = tables["models"]
    margin = models.column("margin")[0].as_py() if "margin" in models.column_names else None
    # models stored before concurrent labels have none (the paper's segmenter)
    concurrent = (models.column("concurrent_labels")[0].as_py() if "concurrent_labels" in models.column_names
                  else None)
    # models stored before calibrated confidence have no maps (the raw score)
    maps = tables.get("confidence_maps")
    steps = {}   # (label, min_length) -> [(cut, value, length_weight, full_length, length_product)] in order
    order = [(c, "ascending") for c in ("label", "min_length", "k")]
    for r in (maps.sort_by(order).to_pylist() if maps is not None else ()):
        # maps stored before the length entered the score weigh the raw score alone, and those stored before
        # it multiplied the match add it
        score = (r.get("length_weight", 0.0), r.get("full_length", ConfidenceMap.full_length),
                 r.get("length_product", False))
        if None in score:
            raise SchemaError(f"model {name!r}: a confidence map of {r['label']!r} has no length_weight, "
                              f"full_length or length_product")
        steps.setdefault((r["label"], r["min_length"]), []).append((r["cut"], r["value"], *score))
    stray = sorted({lab for lab, _ in steps} - set(labels))
    if stray:
        raise SchemaError(f"model {name!r}: confidence maps of labels it lacks: {stray}")
    mixed = sorted(key for key, rows in steps.items() if len({row[2:] for row in rows}) > 1)
    if mixed:
        raise SchemaError(f"model {name!r}: the steps of a confidence map disagree on its length_weight, "
                          f"full_length or length_product: {mixed}")
    conf = tuple(ConfidenceMap(lab, [x[0] for x in rows], [x[1] for x in rows], min_length=lo,
                               length_weight=rows[0][2], full_length=rows[0][3], length_product=rows[0][4])
                 for (lab, lo), rows in steps.items())
    return Model(name, tuple(out), labels=tuple(labels), margin=float(margin or 0.0),
                 concurrent_labels=tuple(concurrent or ()), confidence_maps=conf)


# -- the database ---------------------------------------------------------------

def model_names(con) -> list[str]:
    """Names of the models stored in the database."""
    return [r[0] for r in con.execute(_sql("names")).fetchall()]


def model_fingerprint(con, name: str):
    """The stored fingerprint of a model, or None if the database has no such model."""
    rows = con.execute(_sql("fingerprint"), {"model": name}).fetchall()
    return rows[0][0] if rows else None


def _write(con, tables: dict) -> None:
    """Replace the rows of the model in ``tables`` (inside the caller's transaction)."""
    name = tables["models"].column("model")[0].as_py()
    for table in MODEL_TABLES:
        con.execute(_sql(f"delete_{table}"), {"model": name})
    for table in MODEL_TABLES:
        if table in tables and tables[table].num_rows:
            with registered(con, mocap_new_rows=tables[table]):
                con.execute(_sql(f"insert_{table}"))


def save_model(con, model: Model, *, replace=False, **metadata) -> str:
    """Store a model (one transaction).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : Model
    replace : bool, keyword-only
        Overwrite a stored model of the same name (otherwise an error).
    **metadata
        ``description``, ``source``, ``keyframe_stats``, ``ga_statistics``:
        see :func:`model_tables`.

    Returns
    -------
    str
        The model's fingerprint.
    """
    if model_fingerprint(con, model.name) is not None and not replace:
        raise ParameterError(f"model {model.name!r} already exists; pass replace=True (--replace) "
                             "or choose another name")
    tables = model_tables(model, **metadata)
    with transaction(con):
        _write(con, tables)
    return tables["models"].column("fingerprint")[0].as_py()


def read_model_tables(con, name: str) -> dict:
    """The rows of a stored model as Arrow tables (the input of :func:`model_from_tables`)."""
    return {t: con.sql(_sql(f"rows_{t}"), params={"model": name}).to_arrow_table()
            for t in MODEL_TABLES}


#: the version of a shipped model that the database lacks (a read-only database made before it
#: shipped): it is read from the package; stored fingerprints are hex digits, never this
FROM_PACKAGE = "shipped"
_ASK = object()


def model_version(name: str, fingerprint):
    """Which version of model ``name`` :func:`load_model` reads, given its stored fingerprint.

    Parameters
    ----------
    name : str
    fingerprint : str or None
        As stored (:func:`model_fingerprint`); None: the database has no such model.

    Returns
    -------
    str or None
        ``fingerprint``; :data:`FROM_PACKAGE` for a shipped model the database
        lacks; None if there is no such model at all.
    """
    if fingerprint is None and name in SHIPPED_MODELS:
        return FROM_PACKAGE
    return fingerprint


def load_model(con, name: str = DEFAULT_MODEL, *, version=_ASK) -> Model:
    """A stored model; a shipped model missing from a read-only database comes from the package.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    name : str
    version : str or None, keyword-only
        The model's :func:`model_version`, when the caller knows it (a cache
        keyed by it); default: ask the database.

    Raises
    ------
    SchemaError
        If the database has no such model (the message lists the stored ones).
    """
    if version is _ASK:
        version = model_version(name, model_fingerprint(con, name))
    if version is None:
        raise unknown_model(con, name)
    tables = shipped_model_tables(name) if version == FROM_PACKAGE else read_model_tables(con, name)
    return model_from_tables(tables)


def unknown_model(con, name) -> SchemaError:
    """The error for a model the database does not have, listing the ones it has."""
    known = ", ".join(model_names(con)) or "none"
    return SchemaError(f"no model {name!r} in the database (stored models: {known}); train one with "
                       "`mocapdb train` or use the default model")


def keyframe_query_stats(con, name: str) -> dict:
    """class -> dict(source, fitness, precision, recall) of a stored model's keyframe queries."""
    rows = con.execute(_sql("keyframe_stats"), {"model": name}).fetchall()
    return {r[0]: dict(zip(("source", "fitness", "precision", "recall"), r[1:])) for r in rows}


def ga_statistics_rows(con, name: str, *, exclude_classes=()) -> list:
    """The stored GA statistics rows of a model, without the model column."""
    rows = con.execute(_sql("ga_statistics"), {"model": name}).fetchall()
    return [r for r in rows if r[0] not in set(exclude_classes)]


def model_metadata(con, name: str) -> dict:
    """``description`` and ``source`` of a stored model."""
    rows = con.execute(_sql("metadata"), {"model": name}).fetchall()
    if not rows:
        raise unknown_model(con, name)
    return {"description": rows[0][0], "source": rows[0][1]}


# -- shipped models -------------------------------------------------------------

def shipped_model_dir(name: str = DEFAULT_MODEL):
    """Where a model shipped with the package keeps its Parquet files."""
    return resources.files("mocapdb.shipped_models").joinpath(name)


def shipped_model_tables(name: str) -> dict:
    """The rows of a shipped model, read from the package's Parquet files."""
    d = shipped_model_dir(name)
    if not d.joinpath("models.parquet").is_file():
        raise SchemaError(f"the package has no model {name!r} (expected {d}/models.parquet); "
                          "reinstall mocapdb or retrain with benchmarks/train_default_model.py")
    out = {}
    for table in MODEL_TABLES:
        f = d.joinpath(f"{table}.parquet")
        out[table] = pq.read_table(str(f)) if f.is_file() else _SCHEMAS[table].empty_table()
    return out


def install_shipped_models(con) -> list[str]:
    """Install the shipped models that are missing, or outdated where the package installed them.

    A model a user stored under a shipped name (``shipped = false``) is left alone.

    Returns
    -------
    list of str
        The models installed or refreshed.
    """
    stored = dict(con.execute(_sql("shipped_state")).fetchall())
    done = []
    for name in SHIPPED_MODELS:
        tables = None
        if name in stored:
            fp, shipped = stored[name]
            if not shipped:
                continue
            tables = shipped_model_tables(name)
            if tables["models"].column("fingerprint")[0].as_py() == fp:
                continue
        tables = tables or shipped_model_tables(name)
        tables["models"] = tables["models"].drop_columns(
            [c for c in ("shipped",) if c in tables["models"].column_names]).append_column(
            "shipped", pa.array([True]))
        with transaction(con):
            _write(con, tables)
        done.append(name)
    return done


def export_model(con, name: str, directory) -> Path:
    """Write a stored model's rows as Parquet files (the shipped-model format)."""
    if model_fingerprint(con, name) is None:
        raise unknown_model(con, name)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    for table, rows in read_model_tables(con, name).items():
        keep = [c for c in _SCHEMAS[table].names]
        # rows by class (a confidence map's: by label), then by their number
        order = [(c, "ascending") for c in ("class", "label") if c in keep][:1]
        order += [(c, "ascending") for c in ("class_id", "col", "min_length", "k", "run", "generation") if c in keep]
        pq.write_table(rows.select(keep).cast(_SCHEMAS[table]).sort_by(order) if order else
                       rows.select(keep).cast(_SCHEMAS[table]), str(d / f"{table}.parquet"))
    return d


__all__ = ["DEFAULT_MODEL", "SHIPPED_MODELS", "MODEL_TABLES", "fingerprint", "model_tables", "model_from_tables",
           "model_names", "model_fingerprint", "save_model", "read_model_tables", "FROM_PACKAGE", "model_version",
           "load_model", "unknown_model",
           "keyframe_query_stats", "ga_statistics_rows", "model_metadata", "shipped_model_dir",
           "shipped_model_tables", "install_shipped_models", "export_model"]
