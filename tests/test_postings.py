"""The keyframe index tables: maintained with features, equal to a rebuild, searchable."""
import numpy as np
import pytest

import mocapdb
from mocapdb.keyframes import build_index
from mocapdb import ingest
from mocapdb.storage.ingest import delete_motions
from mocapdb.storage.postings import create_index, drop_index, index_exists, load_index, motion_positions
from mocapdb.storage.sqltext import INDEX_SCHEMA

from conftest import DATA

POSTINGS = f"SELECT motion_id, feature_set, seg, word, start_frame, n_frames FROM {INDEX_SCHEMA}.postings ORDER BY ALL"


@pytest.mark.slow
@pytest.mark.shared
def test_index_follows_ingests_and_deletes(tmp_path, open_db):
    """After any sequence of ingests and deletes the index equals one rebuilt from features."""
    rng = np.random.default_rng(7)
    folders = sorted(p for p in (DATA / "hdm05_cut").iterdir() if p.is_dir())
    con = open_db(tmp_path / "t.duckdb")
    assert index_exists(con)
    for step in range(6):
        ingest(con, [folders[step * 2 % len(folders)], folders[(step * 2 + 1) % len(folders)]])
        ids = [r[0] for r in con.execute("SELECT motion_id FROM motions").fetchall()]
        delete_motions(con, rng.choice(ids, size=len(ids) // 4, replace=False).tolist())
        maintained = con.execute(POSTINGS).fetchall()
        create_index(con)
        assert con.execute(POSTINGS).fetchall() == maintained, f"step {step}"
    assert len(maintained) > 1000


@pytest.mark.shared
def test_stored_index_equals_build_index_of_the_features(tmp_path):
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        ingest(con, [DATA / "hdm05_cut" / "squat1Reps", DATA / "cmu" / "86"])
        index, ids = load_index(con)
        words = [con.execute("SELECT bits FROM features WHERE motion_id = ? ORDER BY frame", [i]).fetchnumpy()["bits"]
                 for i in ids.tolist()]
        ref = build_index(words, feature_sets=("upper", "lower", "mix", "full"))
        got, want = index.to_columns(), ref.to_columns()
        for name in want:
            np.testing.assert_array_equal(got[name], want[name], err_msg=name)
        for name in ("words", "list_offset", "list_doc", "list_seg", "list_start", "list_end"):
            np.testing.assert_array_equal(getattr(index, name), getattr(ref, name), err_msg=name)
        # runs tile every motion and their words are the 40 features (bit 40, feature 41, stays out of the index)
        bad = con.execute(f"""
            SELECT count(*) FROM {INDEX_SCHEMA}.postings p JOIN features f
              ON f.motion_id = p.motion_id AND f.frame BETWEEN p.start_frame AND p.start_frame + p.n_frames - 1
            WHERE p.feature_set = 'full' AND f.bits & {(1 << 40) - 1} <> p.word""").fetchall()[0][0]
        assert bad == 0
        covered = con.execute(f"""SELECT feature_set, sum(n_frames) FROM {INDEX_SCHEMA}.postings
                                  GROUP BY 1 ORDER BY 1""").fetchall()
        total = con.execute("SELECT count(*) FROM features").fetchall()[0][0]
        assert covered == [(s, total) for s in ("full", "lower", "mix", "upper")]


@pytest.mark.shared
def test_drop_and_create(tmp_path):
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        ingest(con, [DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps"])
        before = con.execute(POSTINGS).fetchall()
        drop_index(con)
        assert not index_exists(con)
        ingest(con, [DATA / "hdm05_cut" / "hopBothLegs1hops"])  # without the index: features only
        assert not index_exists(con)
        n = create_index(con)
        after = con.execute(POSTINGS).fetchall()
        assert n == len(after) > len(before)
        assert set(before) <= set(after)
    # reopening keeps the owner's choice
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        assert index_exists(con)


@pytest.mark.shared
@pytest.mark.parametrize("parts", [("full",), ("upper", "lower", "mix")])
def test_load_index_parts(tmp_path, parts, open_db):
    con = open_db(tmp_path / "t.duckdb")
    ingest(con, [DATA / "hdm05_cut" / "kickLFront1Reps"])
    index, ids = load_index(con, parts=parts)
    assert index.parts == parts and len(ids) == 24
    assert index.n_frames == con.execute("SELECT count(*) FROM features").fetchall()[0][0]


@pytest.mark.parametrize("ids", [[1, 2, 3, 7, 9], [0, 5, 3_000_000_000]])  # dense, sparse
def test_motion_positions(ids):
    rng = np.random.default_rng(3)
    rows = rng.integers(0, len(ids), 50)
    got = motion_positions(ids, np.asarray(ids)[rows].astype(np.int32 if max(ids) < 2**31 else np.int64))
    assert got.tolist() == rows.tolist()
