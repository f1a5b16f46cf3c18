"""Models in the database: one loader for a stored model and for a shipped model a database lacks,
through the SQL functions, ``mocapdb.annotate`` and the connection's cache (on the shipped sample)."""
import dataclasses

import pytest

import mocapdb
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.model_store import (FROM_PACKAGE, MODEL_TABLES, load_model, model_fingerprint,
                                         model_version, save_model)
from mocapdb.storage.sqltext import statement


def sql_segments(con, model):
    return con.execute("""SELECT m.motion_id, s.* FROM motions m,
                          LATERAL (SELECT unnest(annotate(m.motion_id, model := $model), recursive := true)) s
                          ORDER BY ALL""", {"model": model}).fetchall()


def api_segments(con, model):
    table = mocapdb.annotate(con, model=model, store=False)
    return sorted(zip(*(table.column(c).to_pylist() for c in ("motion_id", "label", "start_frame", "end_frame"))))


@pytest.mark.slow
def test_a_read_only_database_without_a_shipped_model_reads_the_package_s(tmp_path):
    path = tmp_path / "old.duckdb"
    con = mocapdb.connect(path)
    report = mocapdb.ingest(con, sample=True)
    assert not report.failed
    toolbox = load_model(con, "toolbox")
    # a stored model of the user's own: the toolbox's templates with another τ
    save_model(con, dataclasses.replace(toolbox, name="mine", classes=tuple(
        dataclasses.replace(c, tau=c.tau * 1.5) for c in toolbox.classes)))
    want = {m: (sql_segments(con, m), api_segments(con, m)) for m in ("toolbox", "mine")}
    assert want["toolbox"][0] and want["toolbox"] != want["mine"]
    # a database made before the toolbox model shipped
    for table in MODEL_TABLES:
        con.execute(statement("models.sql", "delete_" + table), {"model": "toolbox"})
    con.close()

    ro = mocapdb.connect(path, read_only=True)
    try:
        assert model_fingerprint(ro, "toolbox") is None and model_version("toolbox", None) == FROM_PACKAGE
        assert model_version("mine", model_fingerprint(ro, "mine")) == model_fingerprint(ro, "mine")
        for m in ("toolbox", "mine"):
            assert (sql_segments(ro, m), api_segments(ro, m)) == want[m], m
        assert load_model(ro, "toolbox").class_names == toolbox.class_names
        key, parsed = connection_cache(ro).model("toolbox")
        assert key == ("toolbox", FROM_PACKAGE) and connection_cache(ro).model("toolbox")[1] is parsed
        with pytest.raises(mocapdb.SchemaError, match="no model 'nope' .*stored models: default, mine"):
            load_model(ro, "nope")
        with pytest.raises(mocapdb.SchemaError, match="no model 'nope'"):
            connection_cache(ro).model("nope")
    finally:
        ro.close()


def test_the_cache_rereads_a_model_when_its_fingerprint_changes(tmp_path):
    con = mocapdb.connect(tmp_path / "a.duckdb")
    try:
        toolbox = load_model(con, "toolbox")
        save_model(con, dataclasses.replace(toolbox, name="mine"))
        cache = connection_cache(con)
        key, first = cache.model("mine")
        assert key == ("mine", model_fingerprint(con, "mine")) and cache.model("mine")[1] is first
        save_model(con, dataclasses.replace(toolbox, name="mine", classes=toolbox.classes[:2]), replace=True)
        key2, second = cache.model("mine")
        assert key2 != key and second.class_names == toolbox.class_names[:2]
    finally:
        con.close()
