"""Small things the commands must get right (issue 27 item 8), on the shipped sample.

A name of two motions is refused by `view` as by `similar` and `delete`, and
`view` without --out writes `<name>.html`; a zip member named twice is read
once (its last copy) and its earlier copy reported, not skipped as the same
bytes as itself; a damaged archive named on the command line fails the
ingest; `attach` of a folder that is no archive leaves no database file;
every annotation file format says what it wrote, and the Parquet one
carries its frames' grid; a query shorter than half a second is refused with
the reason; the Δ figure's colour bar does not call every tick τ. The SQL
`similar_to` points (a name cast to an id, 3.7 run as 4, a NULL range) are
in tests/sql/similar.test; the viewer's header in tests/test_viewer.py.
"""
import json
import lzma
import zipfile

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import SAMPLE_BVH, run


@pytest.fixture(scope="module")
def walks():
    """The shipped walk, and the same walk at half the rate (other bytes, the same name)."""
    text = lzma.decompress(SAMPLE_BVH.read_bytes())
    head, _, body = text.partition(b"MOTION")
    frames = [ln for ln in body.split(b"\n")[3:] if ln.strip()][::2]
    half = head + b"MOTION\nFrames: %d\nFrame Time: 0.0166667\n" % len(frames) + b"\n".join(frames) + b"\n"
    return text, half


@pytest.fixture(scope="module")
def sample_db(tmp_path_factory):
    db = tmp_path_factory.mktemp("details") / "d.duckdb"
    run(db, "ingest", "--sample", "--silent")
    return db


def test_a_name_of_two_motions_is_refused_and_view_has_a_default_page(tmp_path, walks, monkeypatch):
    for folder, data in (("a", walks[0]), ("b", walks[1])):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "walk.bvh").write_bytes(data)
    db = tmp_path / "two.duckdb"
    run(db, "ingest", tmp_path / "a", tmp_path / "b", "--silent")
    r = run(db, "view", "walk", "--out", tmp_path / "x.html", code=1)
    assert r.output.strip() == "Error: 'walk' names 2 motions (ids 1, 2); give the id"
    assert not (tmp_path / "x.html").exists()
    monkeypatch.chdir(tmp_path)
    r = run(db, "view", "2", "--silent")
    assert r.output.strip() == "written walk.html" and (tmp_path / "walk.html").read_text().startswith("<!DOCTYPE")
    assert run(db, "view", code=1).output.startswith("Error: give a motion")


@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")
def test_zip_members_named_twice_damaged_archives_and_attach_leave_nothing_behind(tmp_path, walks):
    archive = tmp_path / "twice.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("takes/walk.bvh", walks[0])
        z.writestr("takes/walk.bvh", walks[1])   # a duplicate name, as some tools write them
    db = tmp_path / "z.duckdb"
    r = run(db, "ingest", archive, "--silent", code=1)
    member = archive / "takes" / "walk.bvh"
    assert f"failed  {member}: refused: the archive holds 2 members of this name; only the last is read" in r.output
    assert "same bytes" not in r.output and "1 ingested, 0 skipped, 1 failed" in r.output
    n_frames = len([ln for ln in walks[1].partition(b"MOTION")[2].split(b"\n")[3:] if ln.strip()])
    out = run(db, "sql", "SELECT source_path, n_source_frames FROM motions", "--format", "json").output
    assert json.loads(out) == [{"source_path": str(member), "n_source_frames": n_frames}]   # the last copy
    # a damaged archive named on the command line fails the ingest (it exited 0)
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"PK\x03\x04 not a zip archive")
    r = run(db, "ingest", bad, "--silent", code=1)
    assert f"failed  {bad}: unreadable archive (not a readable zip archive" in r.output
    # attach of a folder that is no archive refuses and leaves no database file
    views = tmp_path / "views.duckdb"
    r = run(views, "attach", tmp_path, code=1)
    assert "has no motions.parquet or motions/" in r.output
    assert not views.exists() and not list(tmp_path.glob("views.duckdb*"))


@pytest.mark.slow
def test_every_output_format_says_what_it_wrote_and_parquet_has_the_grid(sample_db, tmp_path):
    for fmt in ("csv", "json", "parquet"):
        out = tmp_path / f"segments.{fmt}"
        r = run(sample_db, "annotate", "--format", fmt, "--out", out, "--no-store", "--silent")
        n = int(r.output.split()[0])
        assert r.output.strip() == f"{n} segment(s) written to {out}" and n >= 3, (fmt, r.output)
    table = pq.read_table(tmp_path / "segments.parquet")
    names = table.column_names
    assert names[names.index("end_frame") + 1] == "fps" and set(table.column("fps").to_pylist()) == {30.0}


@pytest.mark.slow
def test_a_query_shorter_than_half_a_second_is_refused_with_the_reason(sample_db):
    r = run(sample_db, "similar", "86_09", "--start-frame", "5", "--end-frame", "6", code=1)
    assert r.output.strip() == ("Error: the query stretch 5–6 of motion 1 ('86_09') is 2 frame(s), 0.07 s; a query "
                                "needs at least 0.5 s (15 frames at 30 Hz): a shorter one is a few words found "
                                "everywhere, and every match would be as short")
    assert run(sample_db, "similar", "86_09", "--start-frame", "5", "--end-frame", "19", "--format", "csv").exit_code == 0


def test_the_delta_colour_bar_marks_the_taus_without_naming_every_tick():
    pytest.importorskip("matplotlib")
    from mocapdb.evaluation.figures import plot_delta

    rng = np.random.default_rng(0)
    taus = np.array([0.11, 0.13, 0.13, 0.2])
    delta = np.where(rng.random((4, 90)) < 0.5, rng.random((4, 90)) * 0.1, np.inf)
    fig = plot_delta(delta, ["a", "b", "c", "d"], taus)
    bar = fig.axes[-1]
    ticks = [t.get_text() for t in bar.get_yticklabels()]
    assert ticks and not any(t.startswith("τ") for t in ticks)
    assert bar.get_ylabel() == "Δ̄^τ (lines: the classes' τ, 0.11–0.2; white: above a class's τ)"
    assert sorted(round(line.get_ydata()[0], 6) for line in bar.lines) == [0.11, 0.13, 0.2]
    one = plot_delta(delta, ["a", "b", "c", "d"], np.full(4, 0.13)).axes[-1]
    assert one.get_ylabel() == "Δ̄^τ (line: τ = 0.13; white: above it)"
