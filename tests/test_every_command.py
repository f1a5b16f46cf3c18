"""Every command of the CLI, run once on real recordings (issue 27 item 6).

`joint-map-template` failed on every file with "internal error
(AttributeError: module 'mocapdb.api' has no attribute 'template')" while the
readers' own errors tell users to run it: some commands were only ever run
with --help. Here each command runs for real, in the order a user would go —
on a copy of the shipped sample (a CMU AMC with its ASF, a BVH walk, an HDM05
C3D), so it runs in a bare clone too — and its output is checked. The table
must name every command of `mocapdb` (a test).
"""
import csv
import json
import lzma
import shutil

import pytest

from mocapdb.cli import main

from conftest import SAMPLE, SAMPLE_BVH, eval_scores, run

#: Ray Data's own DataContext warns about its deprecated fields whenever it copies itself
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning:ray.data.context")


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _labels_from(pred, out):
    """The annotation of 86_09 as a label file (native 120 Hz frames): truth for evaluate, clips for train."""
    rows = [r for r in _rows(pred) if r["document"] == "86_09"]
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["take", "action", "from", "to"])   # another project's column names (convert-labels)
        for r in rows:
            # 30 Hz frame k holds native frames 4k - 3 … 4k; the take has 4,794
            w.writerow(["86_09", r["label"], 4 * (int(r["start_frame"]) - 1) + 1, min(4 * int(r["end_frame"]), 4794)])
    return out


def _check_toml(r, t):
    assert r.output.startswith("#") and "\nroot = " in r.output and "lknee" in r.output


#: (command, arguments with {placeholders} of the tour's paths, check of the result) in the order run
TOUR = [
    ("ingest", ["ingest", "{takes}", "--silent"], lambda r, t: "3 ingested, 0 skipped, 0 failed" in r.output),
    ("joint-map-template", ["joint-map-template", "{walk}"], _check_toml),
    ("sql", ["sql", "SELECT count(*) AS n FROM motions", "--format", "csv"], lambda r, t: r.output == "n\n3\n"),
    ("annotate", ["annotate", "--format", "csv", "--out", "{pred}", "--silent"],
     lambda r, t: len(_rows(t["pred"])) >= 3),
    ("convert-labels", ["convert-labels", "{foreign}", "--out", "{truth}", "--document-column", "take",
                        "--label-column", "action", "--start-column", "from", "--end-column", "to"],
     lambda r, t: _rows(t["truth"])[0]["document"] == "86_09"),
    ("evaluate", ["evaluate", "--truth", "{truth}"], lambda r, t: eval_scores(r.output)[2] == 1.0),
    ("similar", ["similar", "86_09", "--start-frame", "40", "--end-frame", "110", "--limit", "3", "--format", "csv"],
     lambda r, t: r.output.startswith("document,motion_id,") and len(r.output.splitlines()) == 4),
    ("view", ["view", "86_09", "--out", "{page}", "--silent"],
     lambda r, t: t["page"].read_text(encoding="utf-8").startswith("<!DOCTYPE html>")),
    ("report", ["report", "--figure", "delta", "--motion", "86_09", "--out", "{figure}"],
     lambda r, t: t["figure"].read_bytes()[:4] == b"\x89PNG"),
    ("export-joints", ["export-joints", "86_09", "--format", "csv", "--out", "{joints}"],
     lambda r, t: len(_rows(t["joints"])) == 4794 and "lknee_y" in _rows(t["joints"])[0]),
    ("train", ["train", "--model", "tour", "--labels", "{truth}", "--silent"], lambda r, t: "tour" in r.output),
    ("learn-keyframes", ["learn-keyframes", "--model", "tour", "--labels", "{truth}", "--runs", "1", "--generations",
                         "2", "--jobs", "1", "--silent"], lambda r, t: r.output.split()[:3] == ["class", "keyframes", "fitness"]),
    ("define-class", ["define-class", "--model", "tour", "{cartwheel}"], lambda r, t: "cartwheel" in r.output),
    ("drop-index", ["drop-index"], lambda r, t: True),
    ("create-index", ["create-index"], lambda r, t: True),
    ("export-features", ["export-features", "{export}"], lambda r, t: (t["export"] / "motions.parquet").is_file()),
    ("import-features", ["--db", "{imported}", "import-features", "{export}"],
     lambda r, t: "3 motion(s) imported" in r.output),
    ("relocate", ["relocate", "{takes}", "{moved}"], lambda r, t: "3 " in r.output),
    ("delete", ["delete", "pymo_AV_8Walk_Meredith_HVHA_Rep1"], lambda r, t: "1 motion(s) deleted" in r.output),
    ("ray-annotate", ["ray-annotate", "{moved}", "--out", "{archive}", "--num-cpus", "1"],
     lambda r, t: json.loads((t["archive"] / "manifest.json").read_text())["motions"] == 3),
    ("attach", ["--db", "{views}", "attach", "{archive}"], lambda r, t: "3 motion(s)" in r.output),
    ("stats", ["stats", "--table", "formats", "--format", "csv"], lambda r, t: r.output.count("\n") >= 3),
    ("motions", ["motions", "--q", "86_", "--format", "csv"],
     lambda r, t: r.output.startswith("motion_id,name,format,") and "86_09" in r.output),
    ("serve", None, lambda r, t: '"motions"' in r.output or "<html" in r.output.lower()),
    ("warmup", ["warmup", "ingest"], lambda r, t: r.output.startswith("compiled in ")),
    ("extension-path", ["extension-path"], lambda r, t: r.output.strip().endswith("mocapdb.duckdb_extension")),
]


class _Served:
    """`mocapdb serve` (it serves until stopped): started on a free port, its archive page and API asked
    for, stopped; the result a command's (exit status, what it answered)."""

    def __init__(self, db):
        from serving import Served

        served = Served(db)
        try:
            status, page, _ = served.get("/")
            api_status, body, _ = served.get("/api/motions")
        finally:
            served.stop()
        self.exit_code = 0 if status == api_status == 200 else 1
        self.output = page.decode("utf-8", "replace") + body.decode("utf-8", "replace")


def test_the_tour_names_every_command():
    assert sorted(name for name, _, _ in TOUR) == sorted(main.commands)


@pytest.mark.slow
def test_every_command_runs_on_real_recordings(tmp_path, monkeypatch):
    takes = tmp_path / "takes"
    takes.mkdir()
    for f in sorted(SAMPLE.glob("*.xz")) + [SAMPLE / "86.asf"]:
        shutil.copy(f, takes)
    (tmp_path / "walk.bvh").write_bytes(lzma.decompress(SAMPLE_BVH.read_bytes()))
    t = {"takes": takes, "walk": tmp_path / "walk.bvh", "pred": tmp_path / "pred.csv", "truth": tmp_path / "truth.csv",
         "foreign": tmp_path / "foreign.csv", "page": tmp_path / "86_09.html", "figure": tmp_path / "delta.png",
         "cartwheel": SAMPLE.parent / "shipped_models" / "classes" / "cartwheel.toml", "export": tmp_path / "export",
         "imported": tmp_path / "imported.duckdb", "moved": tmp_path / "moved", "archive": tmp_path / "archive",
         "views": tmp_path / "views.duckdb", "joints": tmp_path / "86_09_joints.csv"}
    db = tmp_path / "tour.duckdb"
    # Ray starts its workers from the working directory: not the checkout, whose mocapdb would shadow
    monkeypatch.chdir(tmp_path)
    for name, args, check in TOUR:
        if name == "convert-labels":
            _labels_from(t["pred"], t["foreign"])
        if name == "relocate":
            shutil.move(takes, t["moved"])
        if args is None:
            r = _Served(db)
        else:
            argv = [a.format(**t) for a in args]
            target, argv = (argv[1], argv[2:]) if argv[0] == "--db" else (db, argv)
            r = run(target, *argv, code=None)
        assert r.exit_code == 0, f"{name}: {r.output}"
        assert check(r, t) is not False, f"{name}: {r.output}"
