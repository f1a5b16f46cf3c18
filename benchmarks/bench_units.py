"""How often the BVH unit decision is right, over every BVH family at hand (issue 33 item 1).

Every BVH file of ``../shared/data`` (foreign, foreign2, bandai2_dev, accad_dev) and the CMU takes
(ASF/AMC, written as the CMU BVH conversions are: ASF bone names, lengths in 1/0.45 inch) is read and its
unit decided (:func:`mocapdb.bodies.units.bvh_unit`). Where the unit is known (the data README: Bandai and
ACCAD centimetres; Mixamo centimetres, fairmotion's PFNN skeleton metres, the Kinect take centimetres; the
CMU takes as written) the decision is scored. Then each take's body is put in each of the five units
(m, cm, mm, inch, cmu; the joints divided by the unit's metres) and the decision scored again: a
studio writing the same performer in another unit.

    python benchmarks/bench_units.py [--quick]     # --quick: 10 files a family
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path

from mocapdb.errors import MocapdbError
from mocapdb.readers import read_motion
from mocapdb.writers.joints_write import _write_bvh
from mocapdb.bodies.units import UNITS, bvh_unit, leg_length

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
KNOWN = {"mixamo_freebvh.bvh": "cm", "fairmotion_pfnn_hierarchy.bvh": "m", "kinect_clap_nan.bvh": "cm"}
#: bone names of the exported BVH skeleton (ASF names: the CMU ones)
ASF_NAMES = ["root", "lhipjoint", "rhipjoint", "lowerback"]


def families(quick):
    n = 10 if quick else None
    return {"foreign": sorted((DATA / "foreign" / "bvh").glob("*.bvh")) + sorted((DATA / "foreign2" / "bvh").glob("*.bvh")),
            "bandai2_dev (cm)": sorted((DATA / "bandai2_dev").glob("*.bvh.gz"))[:n],
            "accad_dev (cm)": sorted((DATA / "accad_dev").glob("*.bvh.gz"))[:n],
            "cmu (cmu, written from the AMC)": sorted((DATA / "cmu").rglob("*.amc"))[:n]}


def truth(family, path):
    if family.startswith("foreign"):
        return KNOWN.get(path.name)
    return family.split("(")[1].split(")")[0].split(",")[0]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    rows, unknown = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for family, paths in families(args.quick).items():
            right = total = twins_right = twins = 0
            decided, refused = Counter(), 0
            for path in paths:
                try:
                    if path.suffix == ".amc":
                        # cmu/13 and cmu/14 came without their ASF: any CMU subject's reads them (data README)
                        asf = None if list(path.parent.glob("*.asf")) else DATA / "cmu" / "02" / "02.asf"
                        amc = read_motion(path, asf=asf)
                        bvh = Path(tmp) / f"{path.stem}.bvh"
                        _write_bvh(bvh, amc.joints * 0.01 / UNITS["cmu"], amc.fps, amc.root_rotation)
                        path = bvh
                    m = read_motion(path)
                except MocapdbError:
                    refused += 1    # not a human skeleton: no unit to decide
                    continue
                unit = m.meta["unit"]
                decided[unit] += 1
                want = truth(family, path)
                if want is None:
                    unknown.append((path.name, unit, m.meta["unit_reason"]))
                else:
                    total += 1
                    right += unit == want
                    names = ASF_NAMES if m.skeleton == "bvh:asf" else []
                    metres = m.joints * UNITS[want]
                    for u, s in UNITS.items():
                        twins += 1
                        twins_right += bvh_unit(metres / s, names)[0] == u
            rows.append((family, len(paths), refused, dict(decided), f"{right}/{total}", f"{twins_right}/{twins}"))
    print("| family | files | refused (not human) | decided | right (known unit) | right, body in each of 5 units |")
    print("|---|---:|---:|---|---:|---:|")
    for family, n, refused, decided, right, twins in rows:
        print(f"| {family} | {n} | {refused} | {', '.join(f'{k} {v}' for k, v in sorted(decided.items()))} | "
              f"{right} | {twins} |")
    for name, unit, reason in unknown:
        print(f"unit not documented: {name}: {reason}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
