"""Archives of real 120 Hz takes of any length, for the ingest benchmarks (run from benchmarks/).

Every ASF/AMC take of ``../shared/data/hdm05_cut`` and ``cmu`` (247 takes,
91,859 frames, 12.8 min) is one *copy*; an archive of H hours holds
``ceil(H × 60 / 12.8)`` copies, each with distinct bytes, so that ingest's
idempotency check stores every one:

* ``amc``: the files as published with a comment line ``# mocapdb bench copy k``
  first, in the shared folders' layout (the HDM05 actors' ASF beside the
  class folders, the CMU subjects' beside their takes; cmu/13 and cmu/14 get
  02.asf under their subject's name, as they were published without one);
* ``bvh``: each take written as BVH (cmuconvert names, ``%.6g``-style 6
  significant digits as MotionBuilder-like writers do) in copy 0; copy k is
  copy 0 with the root's ``OFFSET`` moved by k units along x (the root's
  position channels are added to it: the same take k units aside) — one rig
  per actor, as in a studio's archive. Writing a BVH copy from the takes costs
  minutes, editing one line costs a file copy, so a 10-hour archive is
  built in seconds (archives built before 2026-12-07 moved the root channel
  itself: the same numbers of bytes, the same words);
* ``amass``: each take written as an AMASS-format SMPL-H ``.npz``
  (:mod:`lab.amass_write`), the root moved as for BVH;
* ``c3d``: the real 120 Hz C3D recordings of ``cmu/c3d`` and ``hdm05_full``
  as published (binary files: one copy only, whatever ``hours`` asks).

The archive is kept in ``DIR`` (default ``/tmp/mocapdb_ingest_archive``)
and reused when it already holds enough copies.
"""
from __future__ import annotations

import dataclasses
import math
import os
import shutil
import sys
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
#: the source frames of one copy (all 120 Hz ASF/AMC takes of hdm05_cut and cmu)
COPY_MINUTES = 91_859 / 120 / 60


def takes():
    """(amc path, its folder under the copy, the ASF path, the ASF's name in that folder) per take."""
    from mocapdb.readers import find_skeleton

    out = []
    for amc in sorted((DATA / "hdm05_cut").rglob("*.amc")):
        asf = find_skeleton(amc)
        out.append((amc, Path("hdm05_cut") / amc.parent.name, asf, Path("hdm05_cut") / asf.name))
    for amc in sorted((DATA / "cmu").rglob("*.amc")):
        subject = amc.parent.name
        asf = find_skeleton(amc) or DATA / "cmu" / "02" / "02.asf"
        out.append((amc, Path("cmu") / subject, asf, Path("cmu") / subject / f"{subject}.asf"))
    if not out:   # an archive of no takes would be an empty benchmark (and copy 0 never written)
        raise SystemExit(f"ingest_archive: no ASF/AMC takes under {DATA}/hdm05_cut or {DATA}/cmu; "
                         f"set MOCAPDB_SHARED to the shared folder (the one holding data/)")
    return out


def copies_for(hours: float, fmt: str = "amc") -> int:
    if fmt == "c3d":
        return 1
    return max(1, math.ceil(hours * 60 / COPY_MINUTES - 1e-9))


def build(root, hours: float, fmt: str) -> Path:
    """The folder of an ``fmt`` (``amc``/``bvh``) archive of at least ``hours`` (whole copies), built if missing."""
    root = Path(root) / fmt
    want = copies_for(hours, fmt)
    for k in range(want):
        folder = root / f"copy{k:03d}"
        if (folder / ".done").exists():
            continue
        shutil.rmtree(folder, ignore_errors=True)
        _write_copy(folder, k, fmt)
        (folder / ".done").touch()
    return root


def copy_folders(root, hours: float, fmt: str) -> list[Path]:
    """The copy folders an archive of ``hours`` consists of (build it first)."""
    return [Path(root) / fmt / f"copy{k:03d}" for k in range(copies_for(hours, fmt))]


def _write_copy(folder: Path, k: int, fmt: str) -> None:
    from mocapdb.readers import load_skeleton, read_amc
    from mocapdb.writers import write_bvh
    from lab.amass_write import write_amass

    if fmt == "c3d":
        folder.mkdir(parents=True, exist_ok=True)
        for c3d in sorted((DATA / "cmu" / "c3d").glob("*.c3d")) + sorted((DATA / "hdm05_full").glob("*.c3d")):
            shutil.copyfile(c3d, folder / c3d.name)
        return
    if fmt == "bvh" and k > 0:
        _shift_bvh_copy(folder.parent / "copy000", folder, k)
        return
    for amc, sub, asf, asf_as in takes():
        (folder / sub).mkdir(parents=True, exist_ok=True)
        if fmt == "amc":
            if not (folder / asf_as).exists():
                shutil.copyfile(asf, folder / asf_as)
            (folder / sub / amc.name).write_bytes(f"# mocapdb bench copy {k}\n".encode() + amc.read_bytes())
        else:
            skel = load_skeleton(asf)
            m = read_amc(amc, skel)
            col = m.column("root", "tx")
            values = m.values.copy()
            values[:, col] += float(k)
            m = dataclasses.replace(m, values=values)
            if fmt == "bvh":
                write_bvh(folder / sub / (amc.stem + ".bvh"), skel, m, layout="cmu", precision=6)
            else:
                write_amass(folder / sub / (amc.stem + ".npz"), skel, m)


def _shift_bvh_copy(first: Path, folder: Path, k: int) -> None:
    """Copy ``first`` (copy 0, built) to ``folder`` with each take's root OFFSET moved by k along x."""
    if not (first / ".done").exists():
        _write_copy(first, 0, "bvh")
        (first / ".done").touch()
    for src in sorted(first.rglob("*.bvh")):
        text = src.read_bytes()
        at = text.index(b"OFFSET")             # the root's: the hierarchy's first
        end = text.index(b"\n", at)
        x, y, z = (float(v) for v in text[at:end].split()[1:4])
        dst = folder / src.relative_to(first)
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_bytes(text[:at] + f"OFFSET {x + k:g} {y:g} {z:g}".encode() + text[end:])
