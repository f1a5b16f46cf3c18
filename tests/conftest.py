"""Shared fixtures: where the real data and the toolbox oracle live.

The data is never copied into the repository; it is read from ``../shared``
beside the checkout (override with ``MOCAPDB_SHARED``).
"""
import csv
import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared")).resolve()
DATA = SHARED / "data"
ORACLE = SHARED / "oracle"


def pytest_report_header(config):
    return f"mocapdb shared data: {SHARED} ({'found' if DATA.is_dir() else 'MISSING'})"


@pytest.fixture(scope="session")
def data_dir():
    if not DATA.is_dir():
        pytest.fail(f"real data not found at {DATA}; set MOCAPDB_SHARED")
    return DATA


@pytest.fixture(scope="session")
def oracle_dir():
    if not ORACLE.is_dir():
        pytest.fail(f"oracle not found at {ORACLE}; set MOCAPDB_SHARED")
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
