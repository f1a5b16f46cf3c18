"""Shared fixtures: where the real data and the toolbox oracle live.

The data is never copied into the repository; it is read from ``../shared``
beside the checkout (override with ``MOCAPDB_SHARED``).
"""
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
