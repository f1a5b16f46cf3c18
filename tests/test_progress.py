"""Progress: bars on a terminal only, and annotation in pieces gives the same segments."""
import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios

import pytest

import mocapdb
from mocapdb.storage import annotations as stored

from conftest import DATA

pytestmark = [pytest.mark.shared, pytest.mark.slow]

HOPS = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("HDM_bd_*.amc"))[:6]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("progress") / "progress.duckdb"
    con = mocapdb.connect(path)
    mocapdb.ingest(con, [DATA / "cmu" / "86" / "86_09.amc", *HOPS])
    con.close()
    return path


@pytest.mark.parametrize("keyframes", [None, False])
def test_annotation_in_pieces_equals_one_piece(db, monkeypatch, keyframes):
    with mocapdb.connect(db, read_only=True) as con:
        whole = mocapdb.annotate(con, keyframes=keyframes, store=False)
        monkeypatch.setattr(stored, "PROGRESS_FRAMES", 40)  # 86_09 alone, then the clips one or two at a time
        calls = []
        pieces = mocapdb.annotate(con, keyframes=keyframes, store=False,
                                  progress=lambda done, total: calls.append((done, total)))
    assert pieces.equals(whole) and whole.num_rows > 0
    assert calls[0] == (0, 7) and calls[-1] == (7, 7) and len(calls) >= 4
    assert [c[0] for c in calls] == sorted(c[0] for c in calls)


def _cli(db, *args, tty):
    """Run the installed CLI with stderr on a pseudo-terminal (tty=True) or a pipe; returns stderr."""
    cmd = [sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), *map(str, args)]
    if not tty:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        return r.stderr
    leader, follower = pty.openpty()
    # a terminal of 24 × 100 characters (a fresh pty has 0 columns, where tqdm draws nothing)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    try:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=follower)
        os.close(follower)
        out = b""
        while True:
            try:
                chunk = os.read(leader, 4096)
            except OSError:  # the follower closed: the process is done writing
                break
            if not chunk:
                break
            out += chunk
        assert p.wait(timeout=600) == 0, out.decode(errors="replace")
    finally:
        os.close(leader)
    return out.decode(errors="replace")


@pytest.mark.parametrize("command", [("annotate", "--format", "csv", "--out", "{tmp}/a.csv"),
                                     ("view", "--all", "{tmp}/pages")])
def test_bars_on_a_terminal_only(db, tmp_path, command):
    args = [a.format(tmp=tmp_path) for a in command]
    assert f"{command[0]}:" in _cli(db, *args, tty=True)  # tqdm's "annotate: 100%|…"
    assert f"{command[0]}:" not in _cli(db, *args, "--silent", tty=True)
    assert f"{command[0]}:" not in _cli(db, *args, tty=False)
