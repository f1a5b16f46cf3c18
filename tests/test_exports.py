"""Annotation exports (ELAN, Parquet) and ELAN files read wherever a label CSV is."""
from importlib import resources

import numpy as np
import pyarrow.parquet as pq
import pyarrow as pa
import pyarrow.compute  # noqa: F401
import pytest
from click.testing import CliRunner

import mocapdb
from mocapdb.annotation import EAF_FPS_PROPERTY, read_eaf, read_labels
from mocapdb.cli import main
from mocapdb.errors import ParseError

from conftest import DATA, eval_scores, run, truth_86_09_rows, write_truth_86_09

CMU86_MAP = resources.files("mocapdb.shipped_models").joinpath("cmu86_labels.csv")
AMC_86_09 = DATA / "cmu" / "86" / "86_09.amc"
HOPS = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("HDM_bd_*.amc"))[:2]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("exports") / "exports.duckdb"
    con = mocapdb.connect(path)
    mocapdb.ingest(con, [AMC_86_09, *HOPS])
    con.close()
    return path


def _eaf(path, tiers, *, media=None, fps=None):
    """An ELAN file written with pympi directly: tiers = {name: [(t0_ms, t1_ms, value), ...]}."""
    import pympi

    eaf = pympi.Elan.Eaf()
    eaf.remove_tier("default")
    if media is not None:
        eaf.add_linked_file(media, mimetype="video/mp4")
    if fps is not None:
        eaf.add_property(EAF_FPS_PROPERTY, str(fps))
    for name, anns in tiers.items():
        eaf.add_tier(name)
        for a, b, v in anns:
            eaf.add_annotation(name, a, b, v)
    pympi.Elan.to_eaf(str(path), eaf)
    return path


@pytest.mark.shared
def test_annotate_eaf_then_evaluate_against_the_same_annotation_is_perfect(db, tmp_path):
    """The export/import path: annotate → .eaf → evaluate against the same segments gives F = 1.
    (Not a quality score: it checks that the ELAN file carries exactly the segments.)"""
    eaf, pred = tmp_path / "86_09.eaf", tmp_path / "pred.csv"
    r = run(db, "annotate", "86_09", "--format", "eaf", "--out", eaf, "--silent")
    n = int(r.output.split()[0])
    assert n >= 3 and eaf.is_file()
    run(db, "annotate", "86_09", "--format", "csv", "--out", pred)
    # from the file alone (its frame rate comes from the file's header property)
    r = CliRunner().invoke(main, ["evaluate", "--truth", str(eaf), "--pred", str(pred)])
    assert r.exit_code == 0, r.output
    assert eval_scores(r.output) == [1.0] * 6
    # from the database (re-annotated; the frame rate comes from motions.source_fps)
    assert eval_scores(run(db, "evaluate", "--truth", eaf).output) == [1.0] * 6
    # a different τ gives a different annotation: the round trip is not self-scoring everything to 1
    assert eval_scores(run(db, "evaluate", "--truth", eaf, "--tau", "0.05").output) != [1.0] * 6


@pytest.mark.shared
def test_eaf_file_layout(db, tmp_path):
    """ELAN's conventions: one tier per label, ms times, the recording as linked media."""
    import pympi

    with mocapdb.connect(db, read_only=True) as con:
        table = mocapdb.annotate(con, ["86_09"], store=False)
    out = tmp_path / "86_09.eaf"
    run(db, "annotate", "86_09", "--format", "eaf", "--out", out)
    eaf = pympi.Elan.Eaf(str(out))
    assert [m["MEDIA_URL"] for m in eaf.media_descriptors] == [AMC_86_09.resolve().as_uri()]
    labels = sorted(set(table.column("label").to_pylist()))
    # a time-aligned tier per label, and under each a tier of the segments' confidences (references)
    assert sorted(eaf.get_tier_names()) == sorted(labels + [lab + " confidence" for lab in labels])
    for lab in labels:
        conf = sorted(float(a[2]) for a in eaf.get_ref_annotation_data_for_tier(lab + " confidence"))
        mine = table.filter(pa.compute.equal(table.column("label"), lab))
        assert conf == sorted(round(x, 3) for x in mine.column("confidence").to_pylist())
    got = sorted((t, a, b, v) for t in labels for a, b, v in eaf.get_annotation_data_for_tier(t))
    # times in ms; a segment ending with the last 30 Hz frame ends with the recording (4794 frames at 120 Hz)
    want = sorted((lab, round(s * 1000), round(min(e, 4794 / 120) * 1000), lab) for lab, s, e in
                  zip(*(table.column(c).to_pylist() for c in ("label", "start_s", "end_s"))))
    assert got == want
    assert dict(eaf.properties)[EAF_FPS_PROPERTY] == "120.0"


@pytest.mark.shared
def test_eaf_of_several_motions_is_a_directory_of_files(db, tmp_path):
    run(db, "annotate", "--format", "eaf", "--out", tmp_path / "eaf")
    assert sorted(p.name for p in (tmp_path / "eaf").iterdir()) == sorted(
        ["86_09.eaf", *(p.stem + ".eaf" for p in HOPS)])
    assert "give a directory" in run(db, "annotate", "--format", "eaf", "--out", tmp_path / "x.eaf", code=1).output
    r = run(db, "annotate", "--format", "parquet", code=None)
    assert r.exit_code != 0 and "give --out" in r.output


@pytest.mark.shared
def test_parquet_export_holds_the_segments(db, tmp_path):
    out = tmp_path / "segments.parquet"
    r = run(db, "annotate", "--format", "parquet", "--out", out)
    with mocapdb.connect(db, read_only=True) as con:
        table = mocapdb.annotate(con, store=False)
    back = pq.read_table(out)
    assert back.equals(table) and f"{table.num_rows} segment(s) written" in r.output


def test_a_hand_written_eaf_maps_its_times_to_the_right_frames(tmp_path):
    """Times [t0, t1) ms cover native frames round(t0·fps/1000)+1 … round(t1·fps/1000)."""
    path = _eaf(tmp_path / "session.eaf", {
        "actions": [(0, 1000, "walk"), (1000, 2500, "clap"), (4000, 4050, " jump ")],
        "kick": [(5000, 6000, "")],  # an empty value: the tier name is the label
    }, media="file:///videos/86_09.mp4", fps=120)
    assert read_eaf(path) == [("86_09", "walk", 1, 120), ("86_09", "clap", 121, 300), ("86_09", "jump", 481, 486),
                              ("86_09", "kick", 601, 720)]
    rows = read_labels(path)
    assert rows["document"].tolist() == ["86_09"] * 4 and rows["start"].tolist() == [1, 121, 481, 601]
    # a caller that knows the rate (the database) wins over the header; without media the eaf's stem names it
    assert read_eaf(path, fps={"86_09": 30.0})[1] == ("86_09", "clap", 31, 75)
    bare = _eaf(tmp_path / "02_01.eaf", {"t": [(0, 100, "walk")]})
    assert read_eaf(bare, fps=120.0) == [("02_01", "walk", 1, 12)]
    with pytest.raises(ParseError, match="frame rate of document '02_01' is unknown"):
        read_labels(bare)
    bad = tmp_path / "bad.eaf"
    bad.write_text("<ANNOTATION_DOCUMENT><broken")
    with pytest.raises(ParseError, match="bad.eaf: not a readable ELAN file"):
        read_labels(bad, fps=120.0)


@pytest.mark.shared
def test_an_eaf_of_the_truth_reads_as_the_csv_and_trains_the_same_model(db, tmp_path):
    """An ELAN copy of the 86_09 ground truth (made with pympi) gives the CSV's rows, and
    train --labels / evaluate --truth accept it in place of the CSV."""
    truth_csv = write_truth_86_09(tmp_path / "truth.csv")
    tiers = {}
    for r in truth_86_09_rows():
        tiers.setdefault(r["label"], []).append((round((int(r["start_frame"]) - 1) * 1000 / 120),
                                                 round(int(r["end_frame"]) * 1000 / 120), r["label"]))
    truth_eaf = _eaf(tmp_path / "truth.eaf", tiers, media=AMC_86_09.resolve().as_uri())
    a, b = read_labels(truth_csv), read_labels(truth_eaf, fps=120.0)
    assert sorted(map(tuple, a.tolist())) == sorted(map(tuple, b.tolist()))
    run(db, "train", "--model", "from_csv", "--labels", truth_csv, "--silent")
    run(db, "train", "--model", "from_eaf", "--labels", truth_eaf, "--silent")
    with mocapdb.connect(db, read_only=True) as con:
        t = {m: con.execute("SELECT class, col, mask, value, weight FROM templates WHERE model = ? "
                            "ORDER BY class, col", [m]).fetchall() for m in ("from_csv", "from_eaf")}
    assert t["from_csv"] and t["from_csv"] == t["from_eaf"]
    by_csv = eval_scores(run(db, "evaluate", "--truth", truth_csv, "--label-map", CMU86_MAP).output)
    by_eaf = eval_scores(run(db, "evaluate", "--truth", truth_eaf, "--label-map", CMU86_MAP).output)
    assert by_csv == by_eaf and not np.allclose(by_csv, 1.0)


@pytest.mark.parametrize("fps", [30.0, 60.0, 100.0, 120.0, 240.0])
def test_eaf_times_land_on_the_same_30hz_frames_at_any_source_rate(tmp_path, fps):
    """ELAN gives times: at any native rate the truth lands on the 30 Hz frames of those times."""
    from mocapdb.annotation import read_truth

    path = _eaf(tmp_path / "take.eaf", {"t": [(0, 1000, "walk"), (2000, 3500, "clap")]}, fps=fps)
    rows = read_truth(path)
    assert [(str(r["label"]), int(r["start"]), int(r["end"])) for r in rows] == [("walk", 0, 29), ("clap", 60, 104)]
    # the database's rate wins over the file's
    assert read_truth(path, fps={"take": 2 * fps})["end"].tolist() == [29, 104]
