"""Label CSVs, the native ↔ 30 Hz frame conversion and class → label mappings."""
import io
import re

import numpy as np
import pytest

from lab.recipe import PAPER_LABELS

from mocapdb.errors import ParameterError, ParseError
from mocapdb.features import motion_features
from mocapdb.annotation.labels import (
    LABEL_DTYPE, class_labels, feature_to_native_frames, label_rows, map_labels,
    native_to_feature_frames, read_class_labels, read_labels, segments_to_rows,
    to_feature_grid, to_native_grid, write_class_labels, write_labels)
from mocapdb.readers import read_motion

from conftest import DATA, SAMPLE_86_09, run

SEGMENTS_86 = DATA / "labels" / "cmu86_segmentation" / "cmu86_09_segments.csv"


def _covered_30hz(s, e):
    """30 Hz frames (0-based) whose native block 4k+1..4k+4 (1-based) meets [s, e]."""
    return [k for k in range(e // 4 + 2) if 4 * k + 1 <= e and 4 * k + 4 >= s]


def _rows_86():
    import csv
    with open(SEGMENTS_86, newline="") as fh:
        return [(r["trial"], r["label"], int(r["start_frame"]), int(r["end_frame"]))
                for r in csv.DictReader(fh)]


@pytest.mark.shared
def test_native_to_30hz_on_the_86_09_segments(tmp_path):
    rows = _rows_86()
    path = tmp_path / "gt.csv"
    path.write_text("document,label,start_frame,end_frame\r\n"
                    + "".join(f"{d},{lab},{s},{e}\r\n" for d, lab, s, e in rows))
    motion = read_motion(DATA / "cmu" / "86" / "86_09.amc")
    native = read_labels(path, n_frames={"86_09": motion.n_frames})
    assert [tuple(r) for r in native] == rows
    grid = to_feature_grid(native)
    n30 = motion_features(motion).size
    for (d, lab, s, e), g in zip(rows, grid):
        cov = _covered_30hz(s, e)
        assert (g["start"], g["end"]) == (cov[0], cov[-1]) and len(cov) == cov[-1] - cov[0] + 1
        # the first 30 Hz frame is the feature sampled at or before the first native frame
        assert 4 * g["start"] + 1 <= s <= 4 * g["start"] + 4
    # walk ends at native 880 = 4·220: 30 Hz frames 0..219; the last segment ends at the
    # document's last native frame, i.e. at the last 30 Hz word of the feature pipeline
    assert (grid[0]["start"], grid[0]["end"]) == (0, 219)
    assert grid[-1]["end"] == n30 - 1 == (motion.n_frames - 1) // 4
    back = to_native_grid(grid, n_native={"86_09": motion.n_frames})
    assert back[-1]["end"] == motion.n_frames
    assert (back["start"] <= native["start"]).all() and (back["end"] >= native["end"]).all()
    np.testing.assert_array_equal(to_feature_grid(back)["start"], grid["start"])
    np.testing.assert_array_equal(to_feature_grid(back)["end"], grid["end"])


def test_feature_grid_round_trip_is_identity():
    rng = np.random.default_rng(3)
    a = rng.integers(0, 5000, 1000)
    b = a + rng.integers(0, 300, 1000)
    s, e = feature_to_native_frames(a, b)
    assert ((s - 1) % 4 == 0).all() and (e % 4 == 0).all()
    a2, b2 = native_to_feature_frames(s, e)
    np.testing.assert_array_equal(a2, a)
    np.testing.assert_array_equal(b2, b)
    # native → grid → native covers the original (whole blocks of 4)
    s = rng.integers(1, 20000, 1000)
    e = s + rng.integers(0, 999, 1000)
    s2, e2 = feature_to_native_frames(*native_to_feature_frames(s, e))
    assert (s2 <= s).all() and (s - s2 < 4).all() and (e2 >= e).all() and (e2 - e < 4).all()
    # clipping to the document's length
    assert feature_to_native_frames(10, 11, n_native=45) == (41, 45)
    with pytest.raises(ParameterError, match="beyond"):
        feature_to_native_frames(12, 12, n_native=45)
    with pytest.raises(ParameterError, match="1 <= start <= end"):
        native_to_feature_frames(0, 3)


def test_write_read_round_trip(tmp_path):
    rows = label_rows(["a", "a", "b"], ["move", "kick", "exercise"], [1, 50, 7], [40, 90, 7])
    p = tmp_path / "l.csv"
    write_labels(p, rows)
    assert p.read_text().splitlines()[0] == "document,label,start_frame,end_frame"
    back = read_labels(p)
    assert back.dtype == LABEL_DTYPE and [tuple(r) for r in back] == [tuple(r) for r in rows]
    buf = io.StringIO()
    write_labels(buf, [("x", "y", 1, 2)])
    assert buf.getvalue() == "document,label,start_frame,end_frame\nx,y,1,2\n"
    with pytest.raises(ParameterError, match="to_native_grid"):
        write_labels(tmp_path / "z.csv", [("x", "y", 0, 2)])


def test_header_variants_comments_and_extra_columns(tmp_path):
    p = tmp_path / "l.csv"
    p.write_bytes("\ufeff# ground truth\r\nLabel,Document,End_Frame,Start_Frame,note\r\n\r\n"
                  "walk,86_09,880,1,caf\xe9\r\n".encode("utf-8"))
    assert [tuple(r) for r in read_labels(p)] == [("86_09", "walk", 1, 880)]
    p.write_bytes(b"document,label,start_frame,end_frame\nd\xe9,a,1,2\n")   # Latin-1
    assert read_labels(p)[0]["document"] == "d\xe9"


@pytest.mark.parametrize("body, message", [
    ("doc,label,start_frame,end_frame\n", r"l\.csv:1: expected a header .* missing document"),
    ("document,label,start_frame,end_frame\nd,a,1\n", r"l\.csv:2: expected 4 fields, got 3"),
    ("document,label,start_frame,end_frame\nd,a,1,2\nd,a,x,2\n",
     r"l\.csv:3: start_frame must be an integer frame number, got 'x'"),
    ("document,label,start_frame,end_frame\n\nd,a,0,2\n", r"l\.csv:3: start_frame must be >= 1"),
    ("document,label,start_frame,end_frame\nd,a,9,2\n", r"l\.csv:2: end_frame 2 is before"),
    ("document,label,start_frame,end_frame\n,a,1,2\n", r"l\.csv:2: empty document name"),
    ("document,label,start_frame,end_frame\nd, ,1,2\n", r"l\.csv:2: empty label"),
    ("document,label,start_frame,end_frame\nd,a,1,101\n",
     r"l\.csv:2: end_frame 101 is beyond the last frame of document 'd' \(100 frames"),
    ("", r"l\.csv: empty file"),
])
def test_bad_label_files_name_file_and_line(tmp_path, body, message):
    p = tmp_path / "l.csv"
    p.write_text(body)
    with pytest.raises(ParseError, match=message):
        read_labels(p, n_frames={"d": 100})


def test_missing_file_is_a_parse_error(tmp_path):
    with pytest.raises(ParseError, match=r"nope\.csv: cannot read"):
        read_labels(tmp_path / "nope.csv")


@pytest.mark.shared
def test_shipped_hdm05_mapping_is_the_data_readme_table():
    table = {}
    for line in (DATA / "README.md").read_text().splitlines():
        m = re.match(r"\|\s*([A-Za-z0-9]+)\s*\|\s*\d+\s*\|\s*\d+\s*\|\s*([A-Za-z]+)", line)
        if m:
            table[m.group(1)] = m.group(2)
    mapping = class_labels("hdm05")
    assert mapping == table and len(mapping) == 11
    assert set(mapping) == {p.name for p in (DATA / "hdm05_cut").iterdir() if p.is_dir()}
    assert mapping["squat1Reps"] == "exercise" and mapping["throwBasketball"] == "throwR"
    # the row order is the label order of the toolbox oracle's annotation
    assert tuple(dict.fromkeys(mapping.values())) == (
        "move", "sitLieDown", "jump", "kick", "rotateArms", "throwR", "grabDepR", "exercise")


@pytest.mark.shared
def test_shipped_cmu_mappings_name_real_actions():
    actions = {line.split("\t")[1].strip() for line in
               (DATA / "labels" / "cmu_mocap6" / "action_names.txt").read_text().splitlines()
               if line and not line.startswith("#")}
    m6 = class_labels("cmu_mocap6")
    assert set(m6) <= actions and set(m6.values()) <= set(PAPER_LABELS)
    assert m6 == {"Squat": "exercise", "Jog": "move", "JumpJack": "jump", "ArmCircle": "rotateArms",
                  "Box": "punch", "KneeRaise": "exercise", "SideBend": "exercise", "ToeTouchOneHand": "exercise",
                  "ToeTouchTwoHands": "exercise"}
    assert actions - set(m6) == {"Twist", "SideReach", "UpDown"}           # 'others': no label fits
    assert class_labels("cmu86") == {"walk": "move"}
    assert {lab for _, lab, _, _ in _rows_86()} >= set(class_labels("cmu86"))
    with pytest.raises(ParameterError, match="name must be one of"):
        class_labels("nope")


def test_class_label_files(tmp_path):
    p = tmp_path / "m.csv"
    write_class_labels(p, {"squat1Reps": "exercise", "kickLFront1Reps": "kick"})
    assert list(read_class_labels(p).items()) == [("squat1Reps", "exercise"),
                                                  ("kickLFront1Reps", "kick")]
    p.write_text("class,label\na,x\nb,y\na,z\n")
    with pytest.raises(ParseError, match=r"m\.csv:4: class 'a' is listed twice"):
        read_class_labels(p)
    p.write_text("klass,label\n")
    with pytest.raises(ParseError, match=r"m\.csv:1: .*missing class"):
        read_class_labels(p)


def test_map_labels_keeps_unmapped_and_segments_to_rows():
    rows = label_rows("86_09", ["walk", "clap", "walk"], [1, 100, 200], [50, 150, 300])
    mapped = map_labels(rows, class_labels("cmu86"))
    assert list(mapped["label"]) == ["move", "clap", "move"] and list(rows["label"])[0] == "walk"
    seg = np.array([("move", 1, 3, 9, 0.1)], dtype=[("label", "U64"), ("doc", np.int64),
                                                   ("start", np.int64), ("end", np.int64),
                                                   ("cost", np.float64)])
    assert [tuple(r) for r in segments_to_rows(seg, ["x", "y"])] == [("y", "move", 3, 9)]
    with pytest.raises(ParameterError, match="document names"):
        segments_to_rows(seg, ["x"])


@pytest.mark.parametrize("fps", [24.0, 25.0, 30.0, 50.0, 59.94, 60.0, 100.0, 120.0, 200.0, 240.0])
def test_grids_at_any_source_rate(fps):
    """Native frame s (time (s-1)/fps) belongs to the 30 Hz frame of the grid time
    at or before it; feature → native → feature is the identity at every rate, and
    at 120 Hz the factor-4 rules hold exactly."""
    from mocapdb.annotation.labels import feature_to_native_frames, native_factor, native_to_feature_frames
    from mocapdb.features import feature_frame_count

    f = native_factor(fps)
    n = 5000
    s = np.arange(1, n + 1)
    k, _ = native_to_feature_frames(s, s, factor=f)
    np.testing.assert_array_equal(k, np.floor((s - 1) * 30 / fps + 1e-9).astype(int))
    assert k.max() == feature_frame_count(n, fps) - 1
    if fps < 30:
        return  # below 30 Hz some feature frames lie between two native frames
    a = np.arange(0, k.max() + 1)
    lo, hi = feature_to_native_frames(a, a, factor=f, n_native=n)
    back, _ = native_to_feature_frames(lo, hi, factor=f)
    np.testing.assert_array_equal(back, a)
    # the native ranges tile the take without gaps or overlaps
    assert lo[0] == 1 and hi[-1] == n and (lo[1:] == hi[:-1] + 1).all()
    if fps == 120.0:
        np.testing.assert_array_equal(k, (s - 1) // 4)
        np.testing.assert_array_equal(lo, 4 * a + 1)


def test_rows_with_an_fps_column_read_onto_their_own_frames(tmp_path):
    """30 Hz rows (fps column) of a 120 Hz document: native frames 4a−3 … 4b, and back to the same 30 Hz frames."""
    from mocapdb.annotation.labels import read_truth

    path = tmp_path / "x.csv"
    path.write_text("document,label,start_frame,end_frame,fps\nd,walk,1,10,30\nd,jump,11,11,30\nd,run,5,8,\n")
    rows = read_labels(path, fps={"d": 120.0})
    assert [tuple(r)[1:] for r in rows] == [("walk", 1, 40), ("jump", 41, 44), ("run", 5, 8)]
    truth = read_truth(path, fps={"d": 120.0})
    assert [(r["start"], r["end"]) for r in truth] == [(0, 9), (10, 10), (1, 1)]
    # mocapdb's annotation output without the fps column (before it had one) is recognised: 30 Hz
    old = tmp_path / "old.csv"
    old.write_text("document,label,start_frame,end_frame,start_s,end_s,cost\nd,walk,1,10,0.0,0.3333,0.01\n")
    assert [(r["start"], r["end"]) for r in read_truth(old, fps={"d": 120.0})] == [(0, 9)]
    with pytest.raises(ParseError, match=r"x\.csv:2: frames at 30 Hz .*native rate of document 'd' is unknown"):
        read_labels(path)
    bad = tmp_path / "bad.csv"
    bad.write_text("document,label,start_frame,end_frame,fps\nd,walk,1,10,fast\n")
    with pytest.raises(ParseError, match=r"bad\.csv:2: fps must be a positive frame rate, got 'fast'"):
        read_labels(bad, fps=120.0)


def test_label_errors_speak_in_the_files_own_frames(tmp_path):
    """An end beyond the recording is said in the file's frames (native, or the row's fps), with file and line."""
    path = tmp_path / "x.csv"
    path.write_text("document,label,start_frame,end_frame\nd,walk,1,4795\n")
    with pytest.raises(ParseError, match=r"x\.csv:2: end_frame 4795 is beyond the last frame of document 'd' "
                                         r"\(4794 frames at the native rate\)"):
        read_labels(path, n_frames={"d": 4794}, fps=120.0)
    path.write_text("document,label,start_frame,end_frame,fps\nd,walk,1,1200,30\nd,walk,1,1199,30\n")
    with pytest.raises(ParseError, match=r"x\.csv:2: end_frame 1200 is beyond the last frame of document 'd' "
                                         r"\(1199 frames at 30 Hz"):
        read_labels(path, n_frames={"d": 4794}, fps=120.0)
    path.write_text("document,label,start_frame,end_frame,fps\nd,walk,1199,1199,30\n")
    assert tuple(read_labels(path, n_frames={"d": 4794}, fps=120.0)[0])[2:] == (4793, 4794)  # clipped to the end


def test_train_labels_beyond_a_document_name_the_file_line_and_native_frames(tmp_path):
    import mocapdb

    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        mocapdb.ingest(con, [SAMPLE_86_09])
        path = tmp_path / "labels.csv"
        path.write_text("document,label,start_frame,end_frame\n86_09,walk,1,880\n86_09,clap,4000,4800\n")
        with pytest.raises(ParseError, match=r"labels\.csv:3: end_frame 4800 is beyond the last frame of document "
                                             r"'86_09' \(4794 frames at the native rate\)"):
            mocapdb.train(con, model="m", labels=path)


def test_labels_of_any_length_annotate(tmp_path):
    """Labels longer than 64 characters are kept whole, with several of them (a designed model)."""
    import mocapdb

    long_a, long_b = "a" * 70 + "_standing", "b" * 100 + "_knees_straight"
    toml = tmp_path / "long.toml"
    # two designed classes: a still stand (both knees straight), and one of the left knee only
    toml.write_text("".join(f'[[class]]\nname = "stand{k}"\nlabel = "{label}"\n[[class.phase]]\n'
                            f'seconds = [0.5, 2]\n{features}\n\n'
                            for k, (label, features) in enumerate([
                                (long_a, "knee_left_bent = 0\nknee_right_bent = 0"),
                                (long_b, "knee_left_bent = 0")], 1)))
    with mocapdb.connect(tmp_path / "l.duckdb") as con:
        mocapdb.ingest(con, [SAMPLE_86_09])
        mocapdb.api.define_class(con, [toml], model="long")
        table = mocapdb.annotate(con, model="long")
        assert table.num_rows and set(table.column("label").to_pylist()) <= {long_a, long_b}
        assert long_a in table.column("label").to_pylist()
        sql = con.sql("SELECT DISTINCT s.label FROM motions m, LATERAL (SELECT unnest(annotate(m.motion_id, "
                      "model := 'long'), recursive := true)) s").fetchall()
        assert {r[0] for r in sql} == set(table.column("label").to_pylist())


def test_an_elan_annotation_with_a_bad_time_slot_is_an_error(tmp_path):
    from mocapdb.annotation.elan import read_eaf

    path = tmp_path / "t.eaf"
    path.write_text("""<?xml version="1.0" encoding="UTF-8"?>
<ANNOTATION_DOCUMENT AUTHOR="" DATE="2024-01-01T00:00:00+00:00" FORMAT="3.0" VERSION="3.0"
 xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
 xsi:noNamespaceSchemaLocation="http://www.mpi.nl/tools/elan/EAFv3.0.xsd">
<HEADER MEDIA_FILE="" TIME_UNITS="milliseconds"/>
<TIME_ORDER>
<TIME_SLOT TIME_SLOT_ID="ts1" TIME_VALUE="0"/>
<TIME_SLOT TIME_SLOT_ID="ts2" TIME_VALUE="1000"/>
<TIME_SLOT TIME_SLOT_ID="ts3"/>
</TIME_ORDER>
<TIER LINGUISTIC_TYPE_REF="default-lt" TIER_ID="actions">
<ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID="a1" TIME_SLOT_REF1="ts1" TIME_SLOT_REF2="ts2">
<ANNOTATION_VALUE>walk</ANNOTATION_VALUE></ALIGNABLE_ANNOTATION></ANNOTATION>
<ANNOTATION><ALIGNABLE_ANNOTATION ANNOTATION_ID="a2" TIME_SLOT_REF1="ts2" TIME_SLOT_REF2="ts3">
<ANNOTATION_VALUE>unaligned</ANNOTATION_VALUE></ALIGNABLE_ANNOTATION></ANNOTATION>
</TIER>
<LINGUISTIC_TYPE GRAPHIC_REFERENCES="false" LINGUISTIC_TYPE_ID="default-lt" TIME_ALIGNABLE="true"/>
</ANNOTATION_DOCUMENT>
""")
    assert read_eaf(path, fps=120.0) == [("t", "walk", 1, 120)]  # the unaligned one is skipped (and logged)
    path.write_text(path.read_text().replace('TIME_SLOT_REF2="ts3"', 'TIME_SLOT_REF2="ts9"'))
    with pytest.raises(ParseError, match=r"t\.eaf: annotation a2 on tier 'actions' refers to the time slot 'ts9', "
                                         r"which the file's TIME_ORDER does not define"):
        read_eaf(path, fps=120.0)


def test_a_huge_name_is_not_echoed_whole():
    from mocapdb.errors import SchemaError, clip_message

    name = "x" * 10_000_000
    err = SchemaError(f"model 'default' has no class {name!r}; its classes: a, b, c")
    assert len(str(err)) < 300 and "(10,000,003 characters)" in str(err)
    assert str(err).endswith("x'; its classes: a, b, c")
    assert len(clip_message("y " * 100_000)) < 4100


@pytest.mark.shared
def test_convert_labels_reads_the_published_label_files_as_the_development_evaluation_does(tmp_path):
    """The CMU segment table and the mocap6 per-frame labels, converted, are the truth the
    development evaluation reads (lab.documents), frame for frame."""
    from click.testing import CliRunner

    import mocapdb
    from mocapdb.cli import main
    from lab.documents import cmu86_documents, mocap6_documents

    out = tmp_path / "86_09.csv"
    r = CliRunner().invoke(main, ["convert-labels", str(SEGMENTS_86), "--document-column", "trial", "--out", str(out)])
    assert r.exit_code == 0, r.output
    want = cmu86_documents(DATA, class_labels={}).truth_native
    assert [tuple(x) for x in read_labels(out)] == [tuple(x) for x in want]
    db = tmp_path / "m.duckdb"
    con = mocapdb.connect(db)
    mocapdb.ingest(con, [DATA / "cmu" / "13" / "13_29.amc"], asf=DATA / "cmu" / "02" / "02.asf")
    con.close()
    lab = DATA / "labels" / "cmu_mocap6"
    out = tmp_path / "13_29.csv"
    run(db, "convert-labels", lab / "13_29.txt", "--frames-per-label", "12", "--names", lab / "action_names.txt",
        "--out", out)
    want = mocap6_documents(DATA, trials=("13_29",), class_labels={}).truth_native
    assert [tuple(x) for x in read_labels(out)] == [tuple(x) for x in want]
    assert read_labels(out)["end"].max() == 4592  # the last block of 12 ends at the take's last frame
    # the converted file is ground truth as it is
    r = run(db, "evaluate", "--truth", out)
    assert "all " in r.output, r.output


def test_evaluate_reads_a_truth_at_the_source_rate_the_database_knows(tmp_path):
    """Issue 27 item 7: `evaluate --pred P.csv --truth T.csv --db D` read a truth without an fps column
    at 120 Hz even when the database knew the document (a 30 fps studio take scored F1 0.309 instead of
    0.785). The shipped walk at 30 fps (every 4th frame): its own annotation as truth on native frames
    scores 1 only at 30 fps."""
    import csv
    import lzma

    from conftest import SAMPLE_BVH, eval_scores

    head, _, body = lzma.decompress(SAMPLE_BVH.read_bytes()).partition(b"MOTION")
    frames = [ln for ln in body.split(b"\n")[3:] if ln.strip()][::4]
    take = tmp_path / "walk30.bvh"
    take.write_bytes(head + b"MOTION\nFrames: %d\nFrame Time: 0.0333333\n" % len(frames) + b"\n".join(frames) + b"\n")
    db, pred, truth = tmp_path / "r.duckdb", tmp_path / "pred.csv", tmp_path / "truth.csv"
    run(db, "ingest", take, "--silent")
    run(db, "annotate", "--format", "csv", "--out", pred, "--silent")
    with open(pred, newline="") as src, open(truth, "w", newline="") as dst:
        w = csv.writer(dst)
        w.writerow(["document", "label", "start_frame", "end_frame"])   # no fps column
        rows = list(csv.DictReader(src))
        for r in rows:   # at 30 fps, 30 Hz frame k is native frame k
            w.writerow([r["document"], r["label"], r["start_frame"], r["end_frame"]])
    assert rows
    assert eval_scores(run(db, "evaluate", "--pred", pred, "--truth", truth).output) == [1.0] * 6
    from click.testing import CliRunner

    from mocapdb.cli import main
    alone = CliRunner().invoke(main, ["evaluate", "--pred", str(pred), "--truth", str(truth)])
    assert alone.exit_code == 0 and eval_scores(alone.output)[2] < 0.9   # no database: 120 Hz, as before
