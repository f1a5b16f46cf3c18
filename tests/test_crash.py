"""Crash consistency (issue 22): ingest, annotate, import-features and ray-annotate killed with SIGKILL
at seeded random moments of their work; the database reopened keeps its invariants (tests/crash.py):
feature rows equal n_frames with frames 1…n, postings cover every motion, no dangling annotation or model
rows. A few trials per command here; ``benchmarks/bench_crash.py --trials N`` runs more."""
import pytest

from crash import WINDOWS, CrashHarness, summary

from conftest import DATA

pytestmark = [pytest.mark.shared, pytest.mark.slow]

#: kills per command in the suite (about a minute in all); the benchmark runs more
TRIALS = {"ingest": 2, "annotate": 2, "import-features": 2, "ray-annotate": 1}


@pytest.fixture(scope="module")
def harness(tmp_path_factory):
    return CrashHarness(tmp_path_factory.mktemp("crash"), DATA)


@pytest.mark.parametrize("command", list(TRIALS))
def test_a_killed_command_leaves_a_consistent_database(harness, command):
    import random

    rng = random.Random(f"{command}-22")  # seeded: the same delays every run
    results = [harness.trial(command, rng, k) for k in range(TRIALS[command])]
    assert all(r.consistent for r in results), summary(results) + "\n" + "\n".join(
        f"{r.command} killed {r.delay} s into its work: {r.broken}" for r in results if r.broken)
    assert all(0 <= r.delay <= WINDOWS[command] for r in results)


def test_the_check_sees_a_broken_database(harness, tmp_path):
    """The invariants can fail: rows removed behind the database's back are found."""
    import shutil

    import duckdb

    from crash import invariants

    db = tmp_path / "broken.duckdb"
    shutil.copy(harness.base, db)
    con = duckdb.connect(str(db))
    con.execute("DELETE FROM features WHERE motion_id = 1 AND frame = 3")
    con.execute("DELETE FROM mocap_index.postings WHERE motion_id = 2 AND feature_set = 'lower' AND seg = 1")
    con.execute("INSERT INTO annotations (motion_id, model, label, start_frame, end_frame, cost, start_s, end_s) "
                "VALUES (999, 'default', 'x', 1, 2, 0, 0, 0.1)")
    con.execute("INSERT INTO classes (model, class, class_id, label, label_id, delta, tau) "
                "VALUES ('gone', 'c', 1, 'x', 1, 0.05, 0.13)")
    con.close()
    broken = invariants(db)
    assert [b.split(":")[0] for b in broken] == [
        "feature rows equal n_frames, frames 1…n", "postings cover every motion (each feature set, frames 1…n)",
        "no dangling annotation rows", "no dangling model rows", "annotate() on the first motion"]
