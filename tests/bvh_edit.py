"""Real BVH takes edited for tests: every length scaled (the take in another unit), or the channel values
changed (another pose of the same skeleton), the hierarchy's text otherwise kept byte for byte."""
import re

import numpy as np

from mocapdb.readers.bvh import parse_bvh


def edit_bvh(data: bytes, *, factor: float = 1.0, values=None) -> bytes:
    """``data`` with OFFSETs, End Sites and position channels times ``factor`` and the frames' channel
    values passed through ``values(array, hierarchy)`` (changed in place) when given."""
    hier = parse_bvh(data).hierarchy
    text = data.decode("latin-1")
    head, motion = re.split(r"(?m)^\s*MOTION\s*$", text, maxsplit=1)
    if factor != 1.0:
        head = re.sub(r"(OFFSET)((?:[ \t]+\S+){3})",
                      lambda m: m.group(1) + "".join(f" {float(x) * factor:.9g}" for x in m.group(2).split()), head)
    lines = motion.strip().splitlines()
    table = np.array([[float(x) for x in ln.split()] for ln in lines[2:] if ln.strip()])
    kinds = np.array([name.lower().endswith("position") for j in hier.joints for name in j.channels])
    table[:, kinds] *= factor
    if values is not None:
        values(table, hier)
    rows = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in table)
    return (head + "MOTION\n" + "\n".join(lines[:2]) + "\n" + rows + "\n").encode("latin-1")


def channel(hier, joint: str, name: str) -> int:
    """The column of a joint's channel (``"Zrotation"``) in the frames' values."""
    j = hier.joints[hier.index(joint)]
    return j.channel_start + [c.lower() for c in j.channels].index(name.lower())
