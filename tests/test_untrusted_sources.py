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
import zipfile

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import MocapdbError
from mocapdb.readers import read_motion

from conftest import SAMPLE_BVH, SAMPLE_C3D, run


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
