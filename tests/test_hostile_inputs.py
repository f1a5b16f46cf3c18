"""Inputs that held a command for minutes (issue 33, the security probe): each refused at once.

A `.bvh.gz` of 500 MiB of NUL bytes (0.5 MB on disk, under the decompression cap) took 197 s and 1.3 GB
to refuse, time growing faster than size: a reader decides from the first bytes, and reading is linear.
`joint-map-template` on a FIFO waited for a writer forever; `ray-annotate --address nosuch:1234`
retried for minutes.
"""
import gzip
import os
import socket
import subprocess
import sys
import time

import pytest

import mocapdb
from mocapdb.errors import ParseError
from mocapdb.readers import read_motion
from mocapdb.readers.bvh_head import MAX_HEADER_LINE

from conftest import SAMPLE_BVH


def nul_gz(path, mib):
    """``mib`` MiB of NUL bytes as a gzip file of ~1 kB a MiB (gzip members one after another)."""
    member = gzip.compress(b"\0" * (1 << 20))
    with path.open("wb") as fh:
        for _ in range(mib):
            fh.write(member)
    return path


@pytest.mark.parametrize("suffix", [".bvh.gz", ".amc.gz"])
def test_a_gigabyte_line_of_nul_bytes_is_refused_from_its_first_bytes(tmp_path, suffix):
    """Refused on what its first block shows: under a decompression cap of 4 MiB the reason is still the
    line, not the cap (which a read of the whole, or hashing it first, would hit)."""
    big = nul_gz(tmp_path / f"big{suffix}", 500)
    assert big.stat().st_size < 600_000
    asf = SAMPLE_BVH.parent / "86.asf"
    with mocapdb.connect(tmp_path / "n.duckdb") as con:
        report = mocapdb.ingest(con, [big], asf=asf, max_decompressed="4MiB")
    ((path, why),) = report.failed
    assert path == str(big) and f"line longer than {MAX_HEADER_LINE:,} bytes" in why, why
    with pytest.raises(ParseError, match="line longer than"):
        read_motion(big, asf=asf)   # the reader alone, under the default cap (512 MiB) it is under


def test_a_bvh_is_decided_by_its_first_word(tmp_path):
    f = tmp_path / "x.bvh"
    f.write_bytes(b"MOTION\nFrames: 1\n" + b"0 " * 100_000)
    with pytest.raises(ParseError, match="expected 'HIERARCHY'"):
        read_motion(f)


def _cli(*args, timeout=120):
    code = "import sys; from mocapdb.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-P", "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, "MOCAPDB_PRECOMPILE": "0"})


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this OS")
def test_joint_map_template_refuses_a_fifo(tmp_path):
    fifo = tmp_path / "take.bvh"
    os.mkfifo(fifo)
    r = _cli("joint-map-template", fifo, timeout=60)   # it waited for a writer forever
    assert r.returncode == 1 and r.stderr.strip() == f"Error: {fifo}: a FIFO (named pipe), not a BVH file"


def test_ray_annotate_refuses_an_address_nobody_answers_at(tmp_path):
    pytest.importorskip("ray")
    with socket.socket() as s:   # a port of this machine nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    for address, why in (("nosuch.invalid:1234", "no such host 'nosuch.invalid'"),
                         (f"127.0.0.1:{port}", "Connection refused")):
        start = time.perf_counter()
        r = _cli("ray-annotate", SAMPLE_BVH, "--out", tmp_path / "archive", "--address", address)
        assert time.perf_counter() - start < 60   # it retried for minutes
        assert r.returncode == 1 and r.stderr.strip().startswith(
            f"Error: cannot connect to the Ray cluster at {address}: {why}"), r.stderr
