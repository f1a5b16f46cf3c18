"""C3D files through the whole system (issue 10): corrupt files never escape as anything but a
ParseError (and never crash the process), a folder of good and bad files ingests the good
ones, and annotation, keyframe search and training from a label file work on C3D documents.
"""
import csv
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mocapdb
from mocapdb.features import motion_features
from mocapdb.keyframes import UNBOUNDED
from mocapdb.readers import read_motion
from mocapdb.storage.model_store import load_model

from conftest import DATA, run
from fuzzing import mutate, pack
from naive_keyframes import naive_keyframe_search

pytestmark = pytest.mark.shared

FOREIGN = DATA / "foreign" / "c3d"
GOOD = [DATA / "cmu" / "c3d" / "85_02.c3d", DATA / "cmu" / "c3d" / "85_12.c3d",
        DATA / "cmu" / "c3d" / "135_02.c3d", DATA / "hdm05_full" / "HDM_mm_01-02_03_120.c3d"]
FUZZ_SOURCES = [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d", FOREIGN / "ezc3d_Qualisys.c3d",
                DATA / "cmu" / "c3d" / "85_02.c3d", FOREIGN / "ezc3d_BTS.c3d", FOREIGN / "ezc3d_FP_Type1.c3d",
                FOREIGN / "ezc3d_Optotrak.c3d"]


def mutated_copies(folder, n, seed):
    """Copies of real files: truncated anywhere, or with 1–3 bytes changed in the header and parameter
    section, or 1–30 bytes changed anywhere, or the readers' generic mutations (tests/fuzzing.py:
    spans cut or repeated, hostile numbers, inserted tokens)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        data = bytearray(FUZZ_SOURCES[i % len(FUZZ_SOURCES)].read_bytes())
        mode = i % 4
        if mode == 0:
            data = data[:int(rng.integers(1, len(data)))]
        elif mode == 3:
            data = mutate(bytes(data), rng)
        else:
            hi = min(len(data), 512 * 20) if mode == 1 else len(data)
            for _ in range(int(rng.integers(1, 4 if mode == 1 else 31))):
                data[int(rng.integers(0, hi))] = int(rng.integers(0, 256))
        path = folder / f"m{i:03d}.c3d"
        path.write_bytes(bytes(data))
        out.append(path)
    return out


READ_ALL = textwrap.dedent(r"""
    import sys
    import numpy as np
    from mocapdb.errors import MocapdbError, ParseError
    from mocapdb.readers import read_c3d
    for path in sys.argv[1:]:
        try:
            m = read_c3d(path)
            ok = m.joints.ndim == 3 and m.joints.shape[1:] == (24, 3) and np.isfinite(m.joints).all()
            print("motion" if ok else "BAD-MOTION", path, flush=True)
        except ParseError as exc:  # one line (the CLI's "Error: ..." / "failed ..."), naming the file
            msg = str(exc)
            named = msg.startswith(path + ":") or msg.startswith(path + " (")
            print("refused" if named and "\n" not in msg and "\r" not in msg else "UNNAMED", path, flush=True)
        except BaseException as exc:
            print("LEAKED", type(exc).__name__, path, flush=True)
""")


@pytest.mark.slow
def test_corrupt_copies_are_refused_or_read_never_crash(tmp_path):
    """Run in a child process: a crash of the C++ reader (the layout guard of
    mocapdb.readers.c3dfile exists for this) fails the test instead of killing the run. A refusal
    is one line that names the file (garbage parameter names are made printable)."""
    files = mutated_copies(tmp_path, 240, seed=10)
    run = subprocess.run([sys.executable, "-c", READ_ALL, *map(str, files)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, f"reader process died ({run.returncode}): {run.stderr[-2000:]}"
    outcomes = [line.split()[0] for line in run.stdout.splitlines()]
    assert len(outcomes) == len(files)
    assert set(outcomes) <= {"motion", "refused"}, [ln for ln in run.stdout.splitlines()
                                                     if ln.split()[0] not in ("motion", "refused")]
    # every truncated copy is refused (the cut lands inside a frame or the header), most others too
    assert all(o == "refused" for o, f in zip(outcomes, files) if int(f.stem[1:]) % 4 == 0
               and f.stat().st_size % 512)
    assert 0 < outcomes.count("motion") < len(files)


@pytest.mark.slow
def test_packed_corrupt_copies_never_crash_the_reader(tmp_path):
    """Corrupt copies packed as .gz/.bz2/.xz or zip members (the packing sometimes damaged too) reach
    ezc3d through an in-memory file: still refused or read, never a crash."""
    rng = np.random.default_rng(22)
    plain = mutated_copies(tmp_path, 60, seed=11)
    packed = []
    for path in plain:
        data = path.read_bytes()
        path.unlink()
        packed.append(pack(data, path.name, tmp_path, rng))
    run = subprocess.run([sys.executable, "-c", READ_ALL, *map(str, packed)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, f"reader process died ({run.returncode}): {run.stderr[-2000:]}"
    outcomes = [line.split()[0] for line in run.stdout.splitlines()]
    assert len(outcomes) == len(packed) and set(outcomes) <= {"motion", "refused"}, run.stdout[-2000:]


# ----------------------------------------------------------------------------
# a folder of good and bad files

def test_folder_of_good_and_bad_c3d_files(tmp_path):
    truncated = tmp_path / "cut.c3d"
    truncated.write_bytes(GOOD[0].read_bytes()[:200_000])
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        report = mocapdb.ingest(con, [FOREIGN, GOOD[0], tmp_path])
        assert sorted(p.split("/")[-1] for p, _, _ in report.ingested) == ["85_02.c3d", "ezc3d_Qualisys.c3d"]
        failed = dict(report.failed)
        assert sorted(failed) == sorted([str(truncated)] + [str(FOREIGN / n) for n in (
            "ezc3d_BTS.c3d", "ezc3d_FP_Type1.c3d", "ezc3d_Optotrak.c3d", "ezc3d_read_NOTworking2.c3d")])
        for path, reason in failed.items():
            assert reason.startswith(path + ": ")
            assert ("cannot place" in reason) != (path == str(truncated))
        assert "truncated: the file declares 810 frames" in failed[str(truncated)]
        rows = con.execute("SELECT name, format, source_fps, fps, n_source_frames, n_frames FROM motions "
                           "ORDER BY name").fetchall()
        # every source rate gives 30 Hz features (READERS.md §1): Qualisys, 340 frames at 200 Hz = 1.7 s
        assert rows == [("85_02", "c3d", 120.0, 30.0, 810, 203),
                        ("ezc3d_Qualisys", "c3d", 200.0, 30.0, 340, math.ceil(340 / 200 * 30))]


def test_cli_ingest_reports_each_refusal_in_one_line(tmp_path):
    db = tmp_path / "cli.duckdb"
    r = run(db, "ingest", FOREIGN, "--silent", code=1)
    assert "Traceback" not in r.output   # some files failed (one went in)
    assert "1 ingested, 0 skipped, 4 failed" in r.output
    lines = [ln for ln in r.output.splitlines() if ln.startswith("failed")]
    assert len(lines) == 4
    assert f"failed  {FOREIGN / 'ezc3d_Optotrak.c3d'}: no full-body marker set: cannot place root" in r.output
    r = run(db, "ingest", FOREIGN / "ezc3d_BTS.c3d", "--silent", code=1)
    assert "0 ingested, 0 skipped, 1 failed" in r.output and "Traceback" not in r.output


def test_marker_map_is_applied_and_stored_on_ingest(tmp_path):
    mapping = tmp_path / "knees.toml"
    mapping.write_text('lknee = "L_FLE"\nrknee = "R_FLE"\n', encoding="utf-8")
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        report = mocapdb.ingest(con, [FOREIGN / "ezc3d_Qualisys.c3d", GOOD[0]], marker_map=mapping)
        assert len(report.ingested) == 1   # the map applies to every C3D file: 85_02 has no L_FLE
        (path, reason), = report.failed
        assert path == str(GOOD[0]) and reason.startswith(
            f"{GOOD[0]}: marker_map: lknee = 'L_FLE', but the file has no usable marker 'L_FLE' (its markers: ")
        opts = dict(con.execute("SELECT name, reader_options FROM motions").fetchall())
        assert '"lknee": "L_FLE"' in opts["ezc3d_Qualisys"]
        stored = con.execute("SELECT bits FROM features JOIN motions USING (motion_id) WHERE name = "
                             "'ezc3d_Qualisys' ORDER BY frame").fetchnumpy()["bits"]
        expected = motion_features(read_motion(FOREIGN / "ezc3d_Qualisys.c3d", marker_map=mapping))
        np.testing.assert_array_equal(stored, expected)


# ----------------------------------------------------------------------------
# downstream: annotate, keyframe search, training on C3D documents

@pytest.fixture(scope="module")
def c3d_db(tmp_path_factory):
    con = mocapdb.connect(tmp_path_factory.mktemp("c3d") / "c3d.duckdb")
    report = mocapdb.ingest(con, GOOD)
    assert len(report.ingested) == len(GOOD) and not report.failed
    yield con
    con.close()


def stored_words(con):
    ids = [r[0] for r in con.execute("SELECT motion_id FROM motions ORDER BY motion_id").fetchall()]
    return ids, [con.execute("SELECT bits FROM features WHERE motion_id = ? ORDER BY frame", [i]).fetchnumpy()["bits"]
                 for i in ids]


@pytest.mark.slow
def test_stored_c3d_words_are_the_files_features(c3d_db):
    for name, path in c3d_db.execute("SELECT name, source_path FROM motions").fetchall():
        words = c3d_db.execute("SELECT bits FROM features JOIN motions USING (motion_id) WHERE name = ? "
                               "ORDER BY frame", [name]).fetchnumpy()["bits"]
        np.testing.assert_array_equal(words, motion_features(read_motion(path)))


def test_annotate_c3d_documents_in_python_and_sql(c3d_db):
    table = mocapdb.annotate(c3d_db, keyframes=False).to_pylist()
    assert table, "the default model finds nothing on 14,500 frames of motion"
    lengths = dict(c3d_db.execute("SELECT motion_id, n_frames FROM motions").fetchall())
    assert all(1 <= r["start_frame"] <= r["end_frame"] <= lengths[r["motion_id"]] for r in table)
    sql = c3d_db.execute("""
        SELECT m.motion_id, s.label, s.start_frame, s.end_frame
        FROM motions m, LATERAL (SELECT unnest(annotate(m.motion_id, keyframes := false), recursive := true)) s
        ORDER BY 1, 3, 2""").fetchall()
    assert sql == [(r["motion_id"], r["label"], r["start_frame"], r["end_frame"]) for r in table]
    assert c3d_db.execute("SELECT count(*) FROM annotations").fetchall()[0][0] == len(table)


@pytest.mark.slow
def test_keyframe_search_over_c3d_documents_equals_brute_force(c3d_db):
    ids, docs = stored_words(c3d_db)
    model = load_model(c3d_db, "default")
    found = 0
    for c in model.classes:
        q = c.keyframe_query
        if q is None:  # matched on whole documents: nothing to search
            continue
        d_max = [np.inf if x >= UNBOUNDED else x for x in q.d_max]
        expected = sorted((ids[d], s + 1, e + 1) for d, s, e in
                          naive_keyframe_search(docs, q.mask, q.value, q.d_min, d_max))
        got = sorted(c3d_db.execute("SELECT motion_id, start_frame, end_frame FROM keyframe_search(?)",
                                    [c.name]).fetchall())
        assert got == expected, c.name
        found += len(got)
    assert found > 0


@pytest.mark.slow
def test_train_from_a_label_file_over_a_c3d_document(c3d_db, tmp_path):
    """Two stretches of 85_12 (native 120 Hz frames) become a model; annotating 85_12 with it finds
    each stretch where it was cut, at cost 0."""
    labels = tmp_path / "labels.csv"
    stretches = {"stretchA": (481, 960), "stretchB": (2401, 3000)}
    with open(labels, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["document", "label", "start_frame", "end_frame"])
        for label, (s, e) in stretches.items():
            w.writerow(["85_12", label, s, e])
    model = mocapdb.train(c3d_db, model="c3d_stretches", labels=labels)
    assert model.class_names == ("stretchA", "stretchB")
    segs = mocapdb.annotate(c3d_db, ["85_12"], model="c3d_stretches", store=False).to_pylist()
    for label, (s, e) in stretches.items():
        s30, e30 = (s - 1) // 4 + 1, (e - 1) // 4 + 1
        hits = [r for r in segs if r["label"] == label and r["start_frame"] <= e30 and r["end_frame"] >= s30]
        assert hits and min(r["cost"] for r in hits) == 0.0, (label, segs)


def test_view_page_of_a_c3d_motion(c3d_db, tmp_path):
    """The viewer re-reads the source: a C3D document's page holds its poses."""
    out = tmp_path / "85_02.html"
    mocapdb.view(c3d_db, "85_02", out=out)
    page = out.read_text(encoding="utf-8")
    assert "85_02" in page and len(page) > 10_000
