"""Acclaim skeleton (ASF) reader.

:func:`read_asf` turns an ``.asf`` file into a :class:`Skeleton`: the root
(DOF order, position, orientation), the bones in file order (unit direction,
length, axis, DOFs, limits, parent) and the units. Lengths are converted to the
toolbox's unit once, here, so that everything downstream (forward kinematics,
BVH export) works in one unit.

ASF files are small; this is plain Python. Files are read as bytes and decoded
as Latin-1 (HDM05 headers carry Latin-1 bytes), with any mix of CRLF/LF line
ends.

References
----------
FEATURES.md §1 (units), §2.2 (skeleton nodes, direction re-normalisation, root
position/orientation); toolbox ``tools/parser/ASFAMCparser/readASF.m``,
``readBone.m``, ``readRootASF.m``, ``readUnits.m``.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from mocapdb.bodies.acclaim import BONE_DOFS, INCH_TO_TOOLBOX, ROOT_DOFS, Bone, Skeleton
from mocapdb.errors import ParseError
from mocapdb.readers.sources import read_bytes

__all__ = ["read_asf", "parse_asf"]

#: centimetres per named length unit (``:units length m``, a non-Acclaim dialect)
_LENGTH_CM = {"m": 100.0, "meter": 100.0, "meters": 100.0, "metre": 100.0, "metres": 100.0,
              "cm": 1.0, "mm": 0.1, "in": 2.54, "inch": 2.54, "inches": 2.54, "ft": 30.48, "feet": 30.48}

#: a frame rate noted in ``:documentation`` (``fps:30``, ``frame rate = 60``, ``120 fps``)
_DOC_RATE = re.compile(r"(?i)(?:\bfps|frame[ _-]?rate|samples[ _-]per[ _-]second)\s*[:=]?\s*"
                       r"(\d+(?:\.\d+)?)|(?<![\w.])(\d+(?:\.\d+)?)\s*fps\b")

_ANGLE_UNITS = {"deg": "deg", "degree": "deg", "degrees": "deg",
                "rad": "rad", "radian": "rad", "radians": "rad"}


# ----------------------------------------------------------------------------
# parsing

def read_asf(path) -> Skeleton:
    """Read an ASF skeleton file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Skeleton

    Raises
    ------
    ParseError
        Malformed file: the message names the file, the line, what was
        expected and what was found (unknown units, DOF or order tokens,
        non-numeric values, bones missing from ``:hierarchy``, ...).
    FileNotFoundError

    References
    ----------
    FEATURES.md §1, §2.2.
    """
    path = Path(path)
    return parse_asf(read_bytes(path), path=path)


def parse_asf(data: bytes | str, *, path="<asf>") -> Skeleton:
    """Parse the text of an ASF file (bytes decoded as Latin-1). See :func:`read_asf`."""
    if isinstance(data, (bytes, bytearray)):
        data = bytes(data).removeprefix(b"\xef\xbb\xbf").decode("latin-1")  # BOM, Latin-1
    text = data.lstrip("\ufeff")
    return _AsfParser(text, str(path)).parse()


class _AsfParser:
    """Line-oriented recursive reader; keeps the line number for every error."""

    def __init__(self, text: str, path: str):
        self.path = path
        # (line number, stripped content) of non-empty, non-comment lines
        self.lines = []
        for no, raw in enumerate(text.split("\n"), start=1):
            s = raw.strip()
            if s and not s.startswith("#"):
                self.lines.append((no, s))
        self.i = 0

    # -- helpers -------------------------------------------------------------
    def error(self, line, message):
        return ParseError(self.path, line, message)

    def floats(self, line, tokens, n, what):
        if len(tokens) < n:
            raise self.error(line, f"{what}: expected {n} numbers, found {len(tokens)}"
                             f" ({' '.join(tokens) or 'nothing'})")
        out = []
        for t in tokens[:n]:
            try:
                v = float(t)
            except ValueError:
                raise self.error(line, f"{what}: expected a number, found {t!r}") from None
            if not math.isfinite(v):
                raise self.error(line, f"{what}: expected a finite number, found {t!r}")
            out.append(v)
        return out

    def section_lines(self):
        """Lines up to the next ``:keyword`` line (consumed)."""
        out = []
        while self.i < len(self.lines) and not self.lines[self.i][1].startswith(":"):
            out.append(self.lines[self.i])
            self.i += 1
        return out

    # -- top level -----------------------------------------------------------
    def parse(self) -> Skeleton:
        meta = {"name": None, "length": 1.0, "mass": 1.0, "angle": "deg", "unit_notes": [],
                "documented_fps": None}
        root = None
        bones = None
        hierarchy = None
        hierarchy_line = None
        while self.i < len(self.lines):
            no, s = self.lines[self.i]
            if not s.startswith(":"):
                raise self.error(no, f"expected a ':keyword' section, found {s[:40]!r}")
            key, _, rest = s[1:].partition(" ")
            key = key.lower()
            self.i += 1
            if key == "version":
                continue
            if key == "name":
                meta["name"] = rest.strip()
            elif key == "units":
                self.parse_units(no, rest, meta)
            elif key == "documentation":
                self.parse_documentation(meta)
            elif key == "root":
                root = self.parse_root(meta)
            elif key == "bonedata":
                bones = self.parse_bonedata(meta)
            elif key == "hierarchy":
                hierarchy_line = no
                hierarchy = self.parse_hierarchy()
            else:
                # e.g. :skin — not needed; skip its content
                self.section_lines()
        if root is None:
            raise self.error(None, "no ':root' section")
        if bones is None:
            bones = []
        if hierarchy is None and bones:
            raise self.error(None, "no ':hierarchy' section (needed to connect the bones)")
        return self.build(meta, root, bones, hierarchy or {}, hierarchy_line)

    def parse_units(self, no, rest, meta):
        # Acclaim writes multipliers (``length 0.45``); other writers name a
        # unit (``length m``, ``mass kg``) or add keys of their own. Features
        # do not depend on the length unit (FEATURES.md §1), so a named or
        # unknown unit never refuses a file: a known length name is converted,
        # anything else is kept as written and ignored.
        items = [(no, rest.strip())] if rest.strip() else []
        items += self.section_lines()
        for line, s in items:
            tok = s.split()
            k = tok[0].lower()
            if k in ("mass", "length"):
                if len(tok) < 2:
                    raise self.error(line, f"units {k}: expected a number or a unit name, found nothing")
                word = tok[1].lower()
                try:
                    v = float(tok[1])
                except ValueError:
                    v = None
                if v is None and k == "length" and word in _LENGTH_CM:
                    # the toolbox divides by L and multiplies by 2.54 (cm):
                    # a named unit of c cm is the L that makes that true
                    v = INCH_TO_TOOLBOX / _LENGTH_CM[word]
                if v is None:
                    meta["unit_notes"].append(f"units {k} {tok[1]!r} kept as written")
                    continue
                if not (math.isfinite(v) and v > 0):
                    raise self.error(line, f"units {k}: expected a positive number, "
                                     f"found {tok[1]!r}")
                meta[k] = v
            elif k == "angle":
                unit = tok[1].lower() if len(tok) > 1 else ""
                if unit not in _ANGLE_UNITS:
                    raise self.error(line, "units angle: expected 'deg' or 'rad', found "
                                     f"{(tok[1] if len(tok) > 1 else '')!r}")
                meta["angle"] = _ANGLE_UNITS[unit]
            else:
                meta["unit_notes"].append(f"unit {tok[0]!r} ignored")

    def parse_documentation(self, meta):
        # free text; some writers note the take's rate there (``fps:30``,
        # ``frame rate 60``), which an AMC without ``:SAMPLES-PER-SECOND`` lacks
        for _, s in self.section_lines():
            m = _DOC_RATE.search(s)
            if m and meta["documented_fps"] is None:
                v = float(m.group(1) or m.group(2))
                if math.isfinite(v) and 0 < v <= 10_000:
                    meta["documented_fps"] = v

    def parse_root(self, meta):
        root = {"order": ROOT_DOFS, "axis": "XYZ", "position": [0.0, 0.0, 0.0],
                "orientation": [0.0, 0.0, 0.0], "line": None}
        for line, s in self.section_lines():
            tok = s.split()
            k = tok[0].lower()
            if k == "order":
                order = []
                for t in tok[1:]:
                    d = t.lower()
                    if d not in ROOT_DOFS:
                        raise self.error(line, f"root order: unknown token {t!r} "
                                         "(expected TX TY TZ RX RY RZ)")
                    if d in order:
                        raise self.error(line, f"root order: {t!r} appears twice")
                    order.append(d)
                root["order"] = tuple(order)
            elif k == "axis":
                root["axis"] = self.axis_order(line, tok[1] if len(tok) > 1 else "", "root axis")
            elif k == "position":
                root["position"] = self.floats(line, tok[1:], 3, "root position")
            elif k == "orientation":
                root["orientation"] = self.floats(line, tok[1:], 3, "root orientation")
            else:
                raise self.error(line, f"unknown root property {tok[0]!r} "
                                 "(expected order, axis, position, orientation)")
        return root

    def axis_order(self, line, token, what):
        if token.upper() != "XYZ":
            raise self.error(line, f"{what}: unsupported rotation order {token!r} "
                             "(only XYZ is supported, as in the toolbox)")
        return "XYZ"

    def parse_bonedata(self, meta):
        bones = []
        body = self.section_lines()
        j = 0
        while j < len(body):
            line, s = body[j]
            if s.lower() != "begin":
                raise self.error(line, f"bonedata: expected 'begin', found {s[:40]!r}")
            begin_line = line
            bone = {"name": None, "id": None, "direction": None, "length": None,
                    "axis": [0.0, 0.0, 0.0], "axis_order": "XYZ", "dof": (), "limits": [],
                    "line": begin_line}
            j += 1
            while True:
                if j >= len(body):
                    raise self.error(begin_line, "bonedata: 'begin' without 'end'")
                line, s = body[j]
                j += 1
                tok = s.split()
                k = tok[0].lower()
                if k == "end":
                    break
                if k == "begin":
                    raise self.error(line, "bonedata: expected 'end' before the next 'begin'")
                if k == "id":
                    try:
                        bone["id"] = int(tok[1])
                    except (IndexError, ValueError):
                        raise self.error(line, "bone id: expected an integer, found "
                                         f"{' '.join(tok[1:])!r}") from None
                elif k == "name":
                    if len(tok) != 2:
                        raise self.error(line, "bone name: expected one name, found "
                                         f"{' '.join(tok[1:])!r}")
                    bone["name"] = tok[1]
                elif k == "direction":
                    bone["direction"] = self.floats(line, tok[1:], 3, "bone direction")
                elif k == "length":
                    (bone["length"],) = self.floats(line, tok[1:], 1, "bone length")
                    if bone["length"] < 0:
                        raise self.error(line, "bone length: expected a length >= 0, "
                                         f"found {tok[1]!r}")
                elif k == "axis":
                    bone["axis"] = self.floats(line, tok[1:], 3, "bone axis")
                    bone["axis_order"] = self.axis_order(line, tok[4] if len(tok) > 4 else "",
                                                         "bone axis")
                elif k == "dof":
                    dof = []
                    for t in tok[1:]:
                        d = t.lower()
                        if d in ("tx", "ty", "tz", "l"):
                            raise self.error(line, f"dof: unsupported translation/length DOF {t!r} "
                                             "(only rx ry rz are supported, as in the toolbox)")
                        if d not in BONE_DOFS:
                            raise self.error(line, f"dof: unknown token {t!r} "
                                             "(expected rx, ry, rz)")
                        if d in dof:
                            raise self.error(line, f"dof: {t!r} appears twice")
                        dof.append(d)
                    bone["dof"] = tuple(dof)
                elif k == "limits":
                    pairs = [s[len(tok[0]):]]
                    # continuation lines: one "(lo hi)" per further DOF
                    while j < len(body) and body[j][1].startswith("("):
                        pairs.append(body[j][1])
                        j += 1
                    bone["limits"] = [self.limit_pair(line, p) for p in pairs]
                elif k in ("bodymass", "cofmass"):
                    pass
                else:
                    raise self.error(line, f"unknown bone property {tok[0]!r} (expected id, name, "
                                     "direction, length, axis, dof, limits)")
            for key in ("name", "direction", "length"):
                if bone[key] is None:
                    raise self.error(begin_line, f"bone without '{key}'")
            bones.append(bone)
        return bones

    def limit_pair(self, line, text):
        t = text.replace("(", " ").replace(")", " ").split()
        if len(t) != 2:
            raise self.error(line, f"limits: expected '(lo hi)', found {text.strip()!r}")
        try:
            return (float(t[0]), float(t[1]))
        except ValueError:
            raise self.error(line, f"limits: expected numbers, found {text.strip()!r}") from None

    def parse_hierarchy(self):
        body = self.section_lines()
        parent = {}
        lines = {}
        for line, s in body:
            tok = s.split()
            if tok[0].lower() in ("begin", "end"):
                continue
            for child in tok[1:]:
                if child in parent:
                    raise self.error(line, f"hierarchy: bone {child!r} has two parents "
                                     f"({parent[child]!r} and {tok[0]!r})")
                parent[child] = tok[0]
                lines[child] = line
            lines.setdefault(tok[0], line)
        parent["__lines__"] = lines
        return parent

    # -- assembly ------------------------------------------------------------
    def build(self, meta, root, bones, hierarchy, hierarchy_line) -> Skeleton:
        L = meta["length"]
        lines = hierarchy.pop("__lines__", {})
        seen = set()
        for b in bones:
            if b["name"] in seen:
                raise self.error(b["line"], f"bone {b['name']!r} defined twice")
            seen.add(b["name"])
            if b["name"].lower() == "root":
                raise self.error(b["line"], "a bone may not be called 'root'")
        for child, par in hierarchy.items():
            if child not in seen:
                raise self.error(lines.get(child, hierarchy_line),
                                 f"hierarchy: {child!r} is not a bone of :bonedata")
            if par != "root" and par not in seen:
                raise self.error(lines.get(child, hierarchy_line),
                                 f"hierarchy: parent {par!r} is not a bone of :bonedata")
        out = []
        for b in bones:
            if b["name"] not in hierarchy:
                raise self.error(hierarchy_line, f"hierarchy: bone {b['name']!r} "
                                 f"(line {b['line']}) is not the child of any bone or of root")
            d = np.asarray(b["direction"], dtype=np.float64)
            n = float(np.sqrt(d @ d))
            # FEATURES.md §2.2: re-normalise (6-digit files are off by ~6e-7);
            # toolbox readBone.m: offset = direction/norm(direction) * length
            unit = d / n if n > 0 else np.zeros(3)
            length = (b["length"] / L) * INCH_TO_TOOLBOX
            out.append(Bone(name=b["name"], id=b["id"], direction=unit, length=length,
                            axis=np.asarray(b["axis"], dtype=np.float64),
                            axis_order=b["axis_order"], dof=b["dof"],
                            limits=tuple(b["limits"]), parent=hierarchy[b["name"]],
                            offset=(unit * (b["length"] / L)) * INCH_TO_TOOLBOX,
                            line=b["line"]))
        # reject cycles (bones not reachable from the root)
        reach = {"root"}
        grew = True
        while grew:
            grew = False
            for b in out:
                if b.name not in reach and b.parent in reach:
                    reach.add(b.name)
                    grew = True
        lost = [b.name for b in out if b.name not in reach]
        if lost:
            raise self.error(hierarchy_line, "hierarchy: bones not connected to the root "
                             f"(cycle?): {', '.join(lost)}")
        pos = (np.asarray(root["position"], dtype=np.float64) / L) * INCH_TO_TOOLBOX
        return Skeleton(
            name=meta["name"] or Path(self.path).stem,
            bones=tuple(out),
            root_order=tuple(root["order"]),
            root_axis=root["axis"],
            root_position=pos,
            root_orientation=np.asarray(root["orientation"], dtype=np.float64),
            length_unit=L, mass_unit=meta["mass"], angle_unit=meta["angle"],
            documented_fps=meta["documented_fps"], notes=tuple(meta["unit_notes"]),
            path=self.path)
