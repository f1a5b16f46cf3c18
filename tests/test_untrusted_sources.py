"""Archives and compressed files from strangers (issue 27 items 1 and 2).

A zip member's name must name a file inside its archive: a member called
``/home/u/x.bvh`` joined to the archive's path replaced it and made ingest
read the host's file; ``..`` members vanished from the summary. Such members
are refused and reported, and never read. Compression bombs (small packed,
huge unpacked; generated here in a temp dir, with the cap set low) stop at
the cap on decompressed bytes with one line naming the file and member,
while the other files of the ingest are stored.
"""
import lzma
import shutil
import tracemalloc
import zipfile

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import MocapdbError
from mocapdb.readers import read_motion
from mocapdb.readers.sources import (DEFAULT_MAX_DECOMPRESSED, decompression_cap, max_decompressed, parse_size,
                                     read_bytes, sha256)

from conftest import SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, SAMPLE_C3D, run
from fuzzing import bomb, zip_bomb


@pytest.fixture(scope="module")
def walk_bvh():
    return lzma.decompress(SAMPLE_BVH.read_bytes())


def test_members_that_would_leave_their_archive_are_refused_and_never_read(tmp_path, walk_bvh):
    host = tmp_path / "host"
    host.mkdir()
    # real recordings on the host that a hostile member points at
    secret = host / "secret.c3d"
    secret.write_bytes(lzma.decompress(SAMPLE_C3D.read_bytes()))
    (tmp_path / "beside.bvh").write_bytes(walk_bvh)
    archive = host / "takes.zip"
    hostile = [str(secret), "../beside.bvh", "sub/../../beside.bvh", "C:/takes/x.bvh", "..\\..\\x.bvh",
               "\\\\server\\share\\x.bvh"]
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("takes/walk.bvh", walk_bvh)
        for name in hostile:
            z.writestr(name, b"not read")
    with mocapdb.connect(tmp_path / "z.duckdb") as con:
        report = mocapdb.ingest(con, [archive])
        assert [p for p, *_ in report.ingested] == [str(archive / "takes" / "walk.bvh")]
        refused = dict(report.failed)
        assert sorted(refused) == sorted(f"{archive}/{name}" for name in hostile)
        for name in hostile:
            reason = refused[f"{archive}/{name}"]
            assert reason.startswith(f"{archive}/{name}: refused: its name "), reason
            assert "a member must name a file inside its archive" in reason
        assert "absolute" in refused[f"{archive}/{secret}"] and "'..'" in refused[f"{archive}/../beside.bvh"]
        assert "drive letter" in refused[f"{archive}/C:/takes/x.bvh"]
        # the host's files were never read
        assert con.execute("SELECT source_path FROM motions").fetchall() == [(str(archive / "takes" / "walk.bvh"),)]
        assert "6 failed" in report.summary()
    # a path through the archive with '..' is refused by the reader too (it would be the file beside)
    with pytest.raises(MocapdbError, match=r"refused: its name holds '\.\.'"):
        read_motion(archive / ".." / "beside.bvh")
    r = run(tmp_path / "cli.duckdb", "ingest", archive, "--silent", code=1)
    assert f"failed  {archive}/../beside.bvh: refused: its name holds '..'" in r.output
    assert "1 ingested, 0 skipped, 6 failed" in r.output


def _bvh_head_and_frame(walk_bvh, frames):
    """The sample walk's header announcing ``frames`` frames, and a frame line of zeros (compresses best)."""
    head, _, body = walk_bvh.partition(b"MOTION")
    lines = body.split(b"\n")
    return (head + b"MOTION\nFrames: %d\n" % frames + lines[2] + b"\n",
            b" ".join([b"0"] * len(lines[3].split())) + b"\n")


@pytest.mark.slow
def test_compression_bombs_stop_at_the_cap_and_the_other_files_go_in(tmp_path, walk_bvh, monkeypatch):
    """2 GiB bombs of ~2 MB (gzip, bzip2, xz files; zip members with a true and a lying header) among
    the shipped sample: each fails with one line naming the file (and member), read only up to the
    cap, and the sample goes in."""
    monkeypatch.delenv("MOCAPDB_MAX_DECOMPRESSED", raising=False)
    folder = tmp_path / "takes"
    folder.mkdir()
    for src in (SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH):
        shutil.copy(src, folder)
    head, frame = _bvh_head_and_frame(walk_bvh, 4_000_000)
    (folder / "bomb.bvh.gz").write_bytes(bomb("gz", 2 << 30, head=head, line=frame))
    (folder / "bomb.amc.bz2").write_bytes(bomb("bz2", 2 << 30, head=b":FULLY-SPECIFIED\n:DEGREES\n1\n",
                                               line=b"root 0 0 0 0 0 0\n"))
    (folder / "bomb.c3d.xz").write_bytes(bomb("xz", 2 << 30))
    c3d = lzma.decompress(SAMPLE_C3D.read_bytes())
    zipped = zip_bomb(folder / "bombs.zip", "takes/bomb.bvh", 2 << 30, others=[("takes/mm.c3d", c3d)])
    liar = zip_bomb(folder / "liar.zip", "takes/liar.bvh", 2 << 30, declared=1000)
    assert all(p.stat().st_size < 12e6 for p in [*folder.glob("*bomb*"), liar])   # 2 GiB each, in a few MB
    with mocapdb.connect(tmp_path / "b.duckdb") as con:
        report = mocapdb.ingest(con, [folder], max_decompressed="8MiB")
        assert sorted(p for p, *_ in report.ingested) == sorted(
            [str(folder / SAMPLE_86_09.name), str(folder / SAMPLE_BVH.name), str(zipped / "takes" / "mm.c3d")])
        failed = dict(report.failed)
        bombs = [folder / "bomb.bvh.gz", folder / "bomb.amc.bz2", folder / "bomb.c3d.xz", zipped / "takes/bomb.bvh"]
        assert sorted(failed) == sorted(map(str, [*bombs, liar / "takes/liar.bvh"]))
        for path in bombs:
            assert failed[str(path)].startswith(f"{path}: cannot read it (decompresses to more than 8 MiB, the cap "
                                                "on a recording's decompressed bytes (a compression bomb?); a larger "
                                                "cap: ingest --max-decompressed SIZE or MOCAPDB_MAX_DECOMPRESSED=SIZE")
            assert "\n" not in failed[str(path)]
        # a header that lies about the size: zipfile stops at the declared size, and the CRC fails
        assert "corrupt compressed data" in failed[str(liar / "takes/liar.bvh")]
    # hashing stops at the cap, in constant memory
    with decompression_cap("8MiB"):
        tracemalloc.start()
        with pytest.raises(OSError, match="decompresses to more than 8 MiB"):
            sha256(folder / "bomb.bvh.gz")
        with pytest.raises(OSError, match="decompresses to more than 8 MiB"):
            read_bytes(folder / "bomb.c3d.xz")   # one read of everything is bounded too
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peak < 40 << 20
    # the environment's cap reaches the readers; the default refuses the honest 2 GiB member unread
    monkeypatch.setenv("MOCAPDB_MAX_DECOMPRESSED", "8MiB")
    with pytest.raises(MocapdbError, match=r"bomb\.bvh\.gz: cannot read the file \(decompresses to more than 8 MiB"):
        read_motion(folder / "bomb.bvh.gz")
    monkeypatch.delenv("MOCAPDB_MAX_DECOMPRESSED")
    assert max_decompressed() == DEFAULT_MAX_DECOMPRESSED == 512 << 20
    with pytest.raises(MocapdbError, match="decompresses to more than 512 MiB"):
        read_motion(zipped / "takes/bomb.bvh")
    # the command line: one line per bomb, exit 1, a bad size named
    db = tmp_path / "cli.duckdb"
    r = run(db, "ingest", "--max-decompressed", "8MiB", folder / "bomb.c3d.xz", zipped, "--silent", code=1)
    assert f"failed  {folder / 'bomb.c3d.xz'}: cannot read it (decompresses to more than 8 MiB" in r.output
    assert f"failed  {zipped / 'takes/bomb.bvh'}: cannot read it (decompresses to more than 8 MiB" in r.output
    assert "1 ingested, 0 skipped, 2 failed" in r.output
    r = run(db, "ingest", "--max-decompressed", "lots", folder, code=1)
    assert r.output.strip() == "Error: max_decompressed: 'lots' is not a size in bytes (e.g. 512MiB, 2GiB, 1000000000)"


def test_sizes_read_as_people_write_them():
    assert [parse_size(s) for s in ("512MiB", "2GiB", "2G", "1.5GB", "1000000", "64 kib", 4096)] == [
        512 << 20, 2 << 30, 2_000_000_000, 1_500_000_000, 1_000_000, 64 << 10, 4096]
    for bad in ("0", "-1", "1XB", "", True):
        with pytest.raises(MocapdbError, match="size in bytes"):
            parse_size(bad)
