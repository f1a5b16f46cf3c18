"""Seeded mutation fuzzing of the readers and of ingest (READERS.md §4, issues 9, 19, 22).

Real AMC/ASF/BVH files from ../shared/data are mutated (tests/fuzzing.py) and
read: only a MocapdbError may leave a reader, an accepted motion is finite and
its features compute, and an ingest of mutated files never raises, stores
only what it reports and reports every file. Hostile numbers include lost
tracking as trackers write it (``1.#QNAN``, 1e36); cases are also packed as
compressed files and zip members, the packing sometimes damaged, and folders
hold FIFOs and files with control characters in their names. (The 2,400
cases take ~20 s on 2 cores; benchmarks/bench_bvh.py times the same generator.)
"""
import os
import zipfile

import numpy as np
import pytest

import mocapdb
from conftest import DATA
from fuzzing import mutate, pack
from mocapdb.errors import MocapdbError
from mocapdb.features import motion_features
from mocapdb.readers import read_motion

pytestmark = [pytest.mark.shared, pytest.mark.slow]

AMC = DATA / "hdm05_cut/kickLFront1Reps/HDM_bd_kickLFront1Reps_001_120.amc"
ASF = DATA / "hdm05_cut/HDM_bd.asf"
N_CASES = 2400


def _short_amc(frames=40) -> bytes:
    """The first ``frames`` frames of a real HDM05 take (fuzzing the whole take is slower, not wiser)."""
    out, seen = [], 0
    for line in AMC.read_bytes().split(b"\n"):
        if line.strip().isdigit():
            seen += 1
            if seen > frames:
                break
        out.append(line)
    return b"\n".join(out) + b"\n"


@pytest.fixture(scope="module")
def sources():
    bvh = [p.read_bytes() for p in sorted((DATA / "foreign/bvh").glob("*.bvh"))]
    assert len(bvh) == 5
    amc = _short_amc()
    fairmotion = (DATA / "foreign/amc/11_01.amc").read_bytes()[:20000]
    return ([("amc", amc, ASF)] * 3 + [("asf", ASF.read_bytes(), None)] * 2 + [("bvh", b, None) for b in bvh]
            + [("amc", fairmotion, DATA / "foreign/amc/11.asf")])


def test_only_mocapdb_errors_leave_the_readers(sources, tmp_path):
    rng = np.random.default_rng(20261125)
    short = _short_amc()
    escaped, accepted, refused = [], 0, 0
    for case in range(N_CASES):
        kind, data, asf = sources[int(rng.integers(0, len(sources)))]
        bad = mutate(data, rng)
        if kind == "amc":
            path, kw = tmp_path / "take.amc", {"asf": asf}
            path.write_bytes(bad)
        elif kind == "asf":
            (tmp_path / "mutated.asf").write_bytes(bad)
            path, kw = tmp_path / "with_mutated_asf.amc", {"asf": tmp_path / "mutated.asf"}
            path.write_bytes(short)
        else:
            path, kw = tmp_path / "take.bvh", {}
            path.write_bytes(bad)
        try:
            motion = read_motion(path, **kw)
        except MocapdbError as exc:
            refused += 1
            named = str(kw["asf"]) if kind == "asf" else str(path)
            assert named in str(exc) or str(path) in str(exc), f"case {case}: the error names no file: {exc}"
            continue
        except Exception as exc:  # noqa: BLE001 - the property under test
            escaped.append((case, kind, f"{type(exc).__name__}: {exc}"))
            continue
        accepted += 1
        assert np.isfinite(motion.joints).all(), f"case {case}: accepted non-finite joints"
        assert 0 < motion.fps <= 10_000
        words = motion_features(motion)  # features are defined for anything accepted
        assert words.dtype == np.uint64 and len(words) >= 1
    assert not escaped, escaped[:5]
    # the mutations must exercise both outcomes, or the test proves nothing
    assert accepted > 50 and refused > N_CASES // 2, (accepted, refused)


def test_ingest_of_mutated_files_never_raises_and_reports_every_file(sources, tmp_path, open_db):
    rng = np.random.default_rng(7)
    folder = tmp_path / "archive"
    folder.mkdir()
    (folder / "HDM_bd.asf").write_bytes(ASF.read_bytes())
    names = []
    for k in range(120):
        kind, data, asf = sources[int(rng.integers(0, len(sources)))]
        if kind == "asf" or asf not in (ASF, None):
            continue
        name = f"HDM_bd_m{k:03d}.{kind}"
        (folder / name).write_bytes(mutate(data, rng) if k % 4 else data)  # every 4th file intact
        names.append(name)
    con = open_db(tmp_path / "f.duckdb")
    report = mocapdb.ingest(con, [folder])
    seen = ([p for p, *_ in report.ingested] + [p for p, _ in report.skipped] + [p for p, _ in report.failed])
    assert sorted(seen) == sorted(str(folder / n) for n in names)
    assert [p for p, _ in report.unsupported] == [str(folder / "HDM_bd.asf")]
    assert report.ingested and report.failed
    stored = con.execute("SELECT count(*), sum(n_frames) FROM motions").fetchall()[0]
    assert stored[0] == len(report.ingested)
    assert stored[1] == con.execute("SELECT count(*) FROM features").fetchall()[0][0]
    # identical intact copies are stored once; identical broken ones fail alike
    for path, reason in report.failed:
        assert path in reason or "same bytes as" in reason


def test_packed_and_hostile_files_never_escape(sources, tmp_path, open_db):
    """Mutated files packed as .gz, .bz2, .xz or zip members (the packing damaged in a quarter of the
    cases): reading any of them raises only a MocapdbError naming it, and an ingest of the folder —
    with a FIFO and a control character in a file name beside them — reports every file."""
    rng = np.random.default_rng(19)
    folder = tmp_path / "packed"
    folder.mkdir()
    (folder / "HDM_bd.asf").write_bytes(ASF.read_bytes())
    escaped, refused, accepted, paths = [], 0, 0, []
    for case in range(300):
        kind, data, asf = sources[int(rng.integers(0, len(sources)))]
        if kind == "asf" or asf not in (ASF, None):
            continue
        name = f"HDM_bd_p{case:03d}\x1b.{kind}" if case % 50 == 0 else f"HDM_bd_p{case:03d}.{kind}"
        path = pack(mutate(data, rng) if case % 3 else data, name, folder, rng)
        paths.append(path)
        try:
            read_motion(path, asf=ASF if kind == "amc" else None)
            accepted += 1
        except MocapdbError as exc:
            refused += 1
            assert "\x1b" not in str(exc), f"case {case}: a raw control character: {exc!r}"
        except Exception as exc:  # noqa: BLE001 - the property under test
            escaped.append((case, path.name, f"{type(exc).__name__}: {exc}"))
    assert not escaped, escaped[:5]
    assert accepted > 20 and refused > 20, (accepted, refused)
    os.mkfifo(folder / "pipe.bvh")
    con = open_db(tmp_path / "p.duckdb")
    report = mocapdb.ingest(con, [folder], asf=ASF)
    seen = {p for p, *_ in report.ingested} | {p for p, _ in report.skipped} | {p for p, _ in report.failed}
    # a zip archive too damaged to list its members is reported as unreadable, in their stead
    damaged = {p for p, why in report.unreadable if why.startswith("unreadable archive")}
    assert seen | {str(p) for p in paths if str(p).split(".zip/")[0] + ".zip" in damaged} \
        == {str(p) for p in paths}
    assert (str(folder / "pipe.bvh"), "a FIFO (named pipe), not a regular file") in report.unsupported
    assert con.execute("SELECT count(*) FROM motions").fetchall()[0][0] == len(report.ingested)


def test_hostile_members_and_bombs_among_packed_files(sources, tmp_path, open_db, monkeypatch):
    """The probe's cases among mutated packed files (issue 27): zip members named with absolute paths,
    '..' and drive letters, pointing at real files of the host, and 2 GiB bombs (gzip, bzip2, xz, a zip
    member) with the cap set low. Every file is reported; no host file is read; each bomb fails with
    the cap's line and the rest is stored."""
    from fuzzing import bomb, zip_bomb

    monkeypatch.setenv("MOCAPDB_MAX_DECOMPRESSED", "16MiB")
    rng = np.random.default_rng(27)
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "HDM_bd.asf").write_bytes(ASF.read_bytes())
    host = tmp_path / "host.bvh"
    host.write_bytes(sources[5][1])
    paths = []
    for case in range(40):
        kind, data, asf = sources[int(rng.integers(0, len(sources)))]
        if kind == "asf" or asf not in (ASF, None):
            continue
        paths.append(pack(mutate(data, rng) if case % 2 else data, f"HDM_bd_h{case:03d}.{kind}", folder, rng))
    hostile = [str(host), "../host.bvh", "takes/../../host.bvh", "C:\\host.bvh", "D:/host.bvh"]
    with zipfile.ZipFile(folder / "hostile.zip", "w") as z:
        for name in hostile:
            z.writestr(name, sources[5][1])
    bombs = []
    for kind in ("gz", "bz2", "xz"):
        bombs.append(folder / f"bomb.bvh.{kind}")
        bombs[-1].write_bytes(bomb(kind, 2 << 30, head=sources[5][1].partition(b"MOTION")[0] + b"MOTION\n"))
    bombs.append(zip_bomb(folder / "bomb.zip", "takes/bomb.c3d", 2 << 30) / "takes" / "bomb.c3d")
    con = open_db(tmp_path / "h.duckdb")
    report = mocapdb.ingest(con, [folder], asf=ASF)
    failed = dict(report.failed)
    seen = {p for p, *_ in report.ingested} | {p for p, _ in report.skipped} | set(failed)
    damaged = {p for p, why in report.unreadable if why.startswith("unreadable archive")}
    assert seen | {str(p) for p in paths if str(p).split(".zip/")[0] + ".zip" in damaged} == \
        {str(p) for p in paths} | {f"{folder / 'hostile.zip'}/{n}" for n in hostile} | set(map(str, bombs))
    for name in hostile:
        assert "refused: its name" in failed[f"{folder / 'hostile.zip'}/{name}"]
    for path in bombs:
        assert failed[str(path)].startswith(f"{path}: cannot read it (decompresses to more than 16 MiB")
    assert report.ingested
    assert str(host) not in {p for p, *_ in con.execute("SELECT source_path FROM motions").fetchall()}
    assert con.execute("SELECT count(*) FROM motions").fetchall()[0][0] == len(report.ingested)
