"""Shared fixtures: where the real data and the toolbox oracle live.

The data is never copied into the repository; it is read from ``../shared``
beside the checkout (override with ``MOCAPDB_SHARED``). A test that needs it
is marked ``@pytest.mark.shared`` (a whole module: ``pytestmark =
pytest.mark.shared``). A module that reads the data while it is collected
reads it only if :data:`HAVE_SHARED` (its parametrizations through
:func:`shared_cases`), or, when every test of it needs the data, calls
:func:`require_shared` first. In a bare clone such tests are skipped
with the reason shown; with ``MOCAPDB_REQUIRE_SHARED=1`` (``.ci/run``) a
missing ``../shared`` fails the run instead. The recordings shipped in the
package (``mocapdb/sample/``, :data:`SAMPLE`) are there in a bare clone too: a
test that needs only one of them reads it from there and always runs.

The helpers the test modules share live here too: the connection fixture
:func:`open_db`, :func:`humerus`, :func:`run` (a CLI command) and
:func:`eval_scores`.
"""
import csv
import os
import sys
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
# lab/ (the development harness, not installed) beside the package: appended, so that `import mocapdb`
# still finds the installed package first (the tests run against it: python -P -m pytest)
if str(REPO) not in sys.path:
    sys.path.append(str(REPO))
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared")).resolve()
DATA = SHARED / "data"
ORACLE = SHARED / "oracle"

#: the recordings shipped with mocapdb (byte for byte the same takes as in ../shared/data:
#: cmu/86/86.asf and 86_09.amc, hdm05_full/HDM_mm_01-02_03_120.c3d, foreign/bvh/pymo_…bvh)
SAMPLE = Path(str(resources.files("mocapdb") / "sample"))
SAMPLE_86_ASF = SAMPLE / "86.asf"
SAMPLE_86_09 = SAMPLE / "86_09.amc.xz"
SAMPLE_C3D = SAMPLE / "HDM_mm_01-02_03_120.c3d.xz"
SAMPLE_BVH = SAMPLE / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh.xz"


#: the documents a user reads, in reading order: the README, the guides it links, then the other docs.
#: Their examples run in this order (test_readme), so a guide may use what an earlier one made.
USER_DOCS = [REPO / "README.md", *(REPO / "docs" / f"{name}.md" for name in ("USER_GUIDE", "READING_FILES", "MODEL",
                                                                                "CLUSTER"))]
USER_DOCS += sorted(set((REPO / "docs").glob("*.md")) - set(USER_DOCS))


def user_docs_text():
    """The README and every document of docs/, in reading order, as one text."""
    return "\n".join(path.read_text(encoding="utf-8") for path in USER_DOCS)


HAVE_SHARED = DATA.is_dir() and ORACLE.is_dir()
REQUIRE_SHARED = os.environ.get("MOCAPDB_REQUIRE_SHARED", "") not in ("", "0")
NO_SHARED = (f"needs ../shared (real recordings, labels, the toolbox oracle), not found at {SHARED}; "
             "set MOCAPDB_SHARED to run it")


def pytest_report_header(config):
    return f"mocapdb shared data: {SHARED} ({'found' if HAVE_SHARED else 'MISSING'})"


def pytest_configure(config):
    config.addinivalue_line("markers", "shared: needs ../shared beside the checkout (skipped in a bare "
                                       "clone; MOCAPDB_REQUIRE_SHARED=1 makes its absence an error)")
    # the fast lane, `pytest -m "not slow"` (README): what takes seconds on its own (a Ray cluster, a
    # browser, a killed process, whole commands in subprocesses, long real takes) is marked slow; every
    # kernel's brute-force twin, the readers' bad-input cases and the SQL functions stay in the lane
    config.addinivalue_line("markers", "slow: seconds or more on its own; left out of the fast lane "
                                       "(pytest -m 'not slow'), run by CI")
    if REQUIRE_SHARED and not HAVE_SHARED:
        raise pytest.UsageError(f"MOCAPDB_REQUIRE_SHARED is set but {NO_SHARED}")


def pytest_collection_modifyitems(config, items):
    if HAVE_SHARED:
        return
    skip = pytest.mark.skip(reason=NO_SHARED)
    for item in items:
        if item.get_closest_marker("shared") is not None:
            item.add_marker(skip)


def require_shared():
    """Skip the calling module in a bare clone (call it before reading ``../shared`` at collection)."""
    if not HAVE_SHARED:
        pytest.skip(NO_SHARED, allow_module_level=True)


def shared_cases(cases):
    """Parametrization values read from ``../shared``, as they are; in a bare clone one
    skipped case instead (no cases at all is a collection error: ``empty_parameter_set_mark``)."""
    if HAVE_SHARED:
        return cases
    return [pytest.param(None, marks=pytest.mark.skip(reason=NO_SHARED), id="no-shared")]


@pytest.fixture(scope="session")
def data_dir():
    if not HAVE_SHARED:
        pytest.skip(NO_SHARED)
    return DATA


@pytest.fixture(scope="session")
def oracle_dir():
    if not HAVE_SHARED:
        pytest.skip(NO_SHARED)
    return ORACLE


def amc_frame_count(path):
    """Frames of an AMC counted independently of the reader: lines that are a bare integer."""
    with open(path, "rb") as f:
        return sum(1 for line in f if re.fullmatch(rb"\s*\d+\s*", line))


def c3d_frame_count(path):
    """Frames of a C3D file from its 512-byte header (last − first + 1), independent of ezc3d."""
    import struct
    with open(path, "rb") as f:
        first, last = struct.unpack("<2H", f.read(10)[6:10])
    return last - first + 1


def truth_86_09_rows():
    """The 86_09 ground truth (labels/cmu86_segmentation) as dicts with trial, label, start_frame, end_frame."""
    return list(csv.DictReader((DATA / "labels" / "cmu86_segmentation" / "cmu86_09_segments.csv").open()))


def write_truth_86_09(path):
    """The 86_09 ground truth as a label CSV (document,label,start_frame,end_frame; native frames)."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["document", "label", "start_frame", "end_frame"])
        for r in truth_86_09_rows():
            w.writerow([r["trial"], r["label"], r["start_frame"], r["end_frame"]])
    return path


def write_truth_86_09_eaf(path, fps=120.0):
    """The 86_09 ground truth as an ELAN file written with pympi by hand: one tier, times in ms,
    the recording as linked media (native frames s..e, 1-based, span [(s-1)/fps, e/fps))."""
    import pympi

    eaf = pympi.Elan.Eaf()
    eaf.add_linked_file((DATA / "cmu" / "86" / "86_09.amc").resolve().as_uri(), mimetype="unknown")
    eaf.add_tier("actions")
    for r in truth_86_09_rows():
        eaf.add_annotation("actions", round((int(r["start_frame"]) - 1) * 1000 / fps),
                           round(int(r["end_frame"]) * 1000 / fps), r["label"])
    pympi.Elan.to_eaf(str(path), eaf)
    return path


# --------------------------------------------------------------------------
# helpers shared by the test modules

@pytest.fixture
def open_db():
    """``open_db(path=":memory:", **options)``: :func:`mocapdb.connect`, closed when the test ends
    (whatever it raised). A test that must close a connection before it goes on (another
    process or the CLI opens the file next) uses ``with mocapdb.connect(…) as con:`` instead."""
    import mocapdb

    opened = []

    def connect(path=":memory:", **options):
        con = mocapdb.connect(path, **options)
        opened.append(con)
        return con

    yield connect
    for con in reversed(opened):
        con.close()


def humerus(joints):
    """The unit of the position tolerances: |rshoulder − relbow| at frame 1 (joints: (n, 24, 3))."""
    from mocapdb.bodies.joints import JOINT_INDEX

    return float(np.linalg.norm(joints[0, JOINT_INDEX["rshoulder"]] - joints[0, JOINT_INDEX["relbow"]]))


def run(db, *args, code=0):
    """``mocapdb --db DB ARGS…`` in this process (click's runner; a Python exception propagates).

    Asserts the exit status is ``code`` (``None``: any, the test looks itself) and returns the
    click ``Result`` (``output``, ``stderr``, ``exit_code``).
    """
    from click.testing import CliRunner

    from mocapdb.cli import main

    r = CliRunner().invoke(main, ["--db", str(db), *map(str, args)], catch_exceptions=False)
    if code is not None:
        assert r.exit_code == code, r.output
    return r


def eval_scores(output):
    """The six figures of the ``all`` row of ``mocapdb eval``'s table, as floats."""
    line = next(ln for ln in output.splitlines() if ln.startswith("all "))
    return [float(x) for x in line.split()[1:7]]
