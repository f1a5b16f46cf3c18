"""Every command that writes files: into a missing folder it makes the folder; where no folder can be made
it says so in one line, never Python's `[Errno …]` (issue 33 item 2).

`annotate --format eaf --out missing/x.eaf` ended with a raw `[Errno 2]`. Each writing command runs here
twice on the recordings shipped with mocapdb: its output under `missing/deeper/`, then under a path whose
parent is a regular file (no folder can be made there).
"""
import lzma
import shutil

import pytest

from conftest import SAMPLE, SAMPLE_86_09, run

#: (command, its arguments with {out} the path to write, the path written relative to {out}'s parent)
WRITERS = [
    ("ingest --report", ["ingest", "{takes}", "--silent", "--report", "{out}/r.csv"], "r.csv"),
    ("annotate csv", ["annotate", "--silent", "--format", "csv", "--out", "{out}/a.csv"], "a.csv"),
    ("annotate eaf, one motion", ["annotate", "86_09", "--silent", "--format", "eaf", "--out", "{out}/x.eaf"],
     "x.eaf"),
    ("annotate eaf, a folder", ["annotate", "--silent", "--format", "eaf", "--out", "{out}/eaf"], "eaf/86_09.eaf"),
    ("annotate parquet", ["annotate", "--silent", "--format", "parquet", "--out", "{out}/a.parquet"], "a.parquet"),
    ("export-features", ["export-features", "{out}/features"], "features/motions.parquet"),
    ("export-joints", ["export-joints", "86_09", "--out", "{out}/j.npz"], "j.npz"),
    ("export-joints, a folder", ["export-joints", "--all", "--out", "{out}/joints"], "joints/units.json"),
    ("convert-labels", ["convert-labels", "{labels}", "--out", "{out}/l.csv"], "l.csv"),
    ("report", ["report", "--figure", "delta", "--motion", "86_09", "--out", "{out}/f.png"], "f.png"),
    ("view", ["view", "86_09", "--silent", "--out", "{out}/v.html"], "v.html"),
    ("view --all", ["view", "--silent", "--all", "{out}/pages"], "pages/index.html"),
    ("similar csv", ["similar", "86_09", "--start-frame", "40", "--end-frame", "110", "--limit", "2", "--format",
                     "csv", "--out", "{out}/s.csv"], "s.csv"),
    ("similar html", ["similar", "86_09", "--start-frame", "40", "--end-frame", "110", "--limit", "2", "--format",
                      "html", "--out", "{out}/hits"], "hits/index.html"),
]


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    d = tmp_path_factory.mktemp("writers")
    takes = d / "takes"
    takes.mkdir()
    shutil.copy(SAMPLE / "86.asf", takes)
    (takes / "86_09.amc").write_bytes(lzma.decompress(SAMPLE_86_09.read_bytes()))
    labels = d / "labels.csv"
    labels.write_text("document,label,start_frame,end_frame\n86_09,walk,1,400\n")
    db = d / "w.duckdb"
    run(db, "ingest", takes, "--silent")
    return db, {"takes": takes, "labels": labels}


@pytest.mark.parametrize("name, args, written", WRITERS, ids=[w[0] for w in WRITERS])
def test_a_writing_command_makes_its_folder_or_says_why_not(archive, tmp_path, name, args, written):
    db, paths = archive
    out = tmp_path / "missing" / "deeper"
    r = run(db, *[a.format(out=out, **paths) for a in args], code=None)
    assert r.exit_code == 0, r.output
    assert (out / written).is_file()
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    r = run(db, *[a.format(out=blocker / "sub", **paths) for a in args], code=None)
    assert r.exit_code != 0
    assert "Errno" not in r.output and "Traceback" not in r.output and "internal error" not in r.output, r.output
    (error,) = [ln for ln in r.output.splitlines() if "Error" in ln]
    assert "a_file" in error and ("a_file is a file" in error or "Not a directory" in error), error


def test_every_command_that_writes_is_here():
    """A command with an option or argument naming a file or folder to write is in WRITERS."""
    from mocapdb.cli import main

    writing = set()
    for cmd_name, cmd in main.commands.items():
        for p in cmd.params:
            if p.name in ("out", "report", "directory", "all") and cmd_name not in ("import-features", "attach",
                                                                                   "relocate"):
                writing.add(cmd_name)
    covered = {args[0] for _, args, _ in WRITERS}
    # ray-annotate writes through the same layout as export-features (storage.parquet), in Ray workers
    assert writing - covered == {"ray-annotate"}, writing - covered
