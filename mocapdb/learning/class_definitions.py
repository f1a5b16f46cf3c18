"""Hand-designed classes (paper Sect. 8): readable class definitions compiled to a template and a query.

"Because of their explicit semantic interpretation, even a manual design or
tuning of motion templates and keyframes is feasible in case no suitable
example motions are available" (paper Sect. 8). A class definition says what
the named features (the 40 of :data:`mocapdb.features.FEATURE_NAMES`, and
feature 41 ``root_heading_turned``, FEATURES.md §10) do during the
motion, phase by phase; it compiles to what a learned class has: a quantized
motion template (columns of 0 / 1 / wildcard, TEMPLATES.md §8) and a keyframe
query (KEYFRAMES.md §2).

A definition file is TOML (docs/MODEL.md "Class definitions")::

    [[class]]
    name = "turnLeft"         # fine class (a template of its own)
    label = "turn"            # the label it annotates with
    mirror = "turnRight"      # optional: also the left/right mirror image (FEATURES.md §7)
    reverse = { name = "…", label = "…" }   # optional: also the motion played backwards
    tau = 0.13                # optional: hit threshold τ (default 0.13)
    default = 0               # optional: value of the features a phase leaves out
                              # (0, 1 or "*"; default "*")

    [[class.phase]]
    seconds = [0.3, 2.0]      # or frames = … (30 Hz); a number or [min, max] (max may be inf)
    root_high_ang_vel = 1     # feature = 0, 1 or "*" (wildcard)
    keyframe = ["root_high_ang_vel"]   # optional: true (all fixed features), false, or names

Compilation (:func:`compile_definition`):

* **template** — each phase becomes ``round(30·d)`` identical columns, d =
  the phase's duration (a number; for ``[min, max]`` the geometric mean, or
  ``min`` if ``max`` is infinite); column weights 1. A feature a phase names
  is fixed to its value (``"*"``: wildcard); the others take the class's
  ``default``.
* **keyframe query** — one keyframe per phase that has ``keyframe`` true (the
  default when the phase fixes a feature) or a list of names (only those
  features, with the phase's values), placed at the phase's middle column;
  the first keyframe at its phase's first column and the last at its
  phase's last, so that the chain spans as much of the template as it can
  (annotation widens a found chain by twice the columns outside it). A
  class with one keyframe phase longer than a column searches its pose at
  both ends of the phase: twice, up to twice the phase's columns apart.
  The gap between keyframes of phases i < j admits the last frame of phase i
  and the first of phase j for every timing the durations allow:
  ``d_min = 1 + Σ min`` and ``d_max = 1 + Σ max`` over the phases strictly
  between (a chain through those two frames exists whenever the motion
  happens, and the search reports it).
  A single duration d stands for ``[d/2, 2d]``: the time warp the annotation's
  DTW steps allow. ``keyframes = false`` on the class gives no query.

**Keyframes for a learned class** (:class:`KeyframeDefinition`,
:func:`attach_keyframes`): the same files may hold ``[[keyframes]]`` tables
that give a class with a template (a learned one) a hand-designed keyframe
query — the moment that makes the motion what it is, where a learned
template only says how it goes on average::

    [[keyframes]]
    class = "kickLFront1Reps"
    [[keyframes.keyframe]]          # one per keyframe, in time order
    foot_left_raised_rel_y_body_min = 1
    femur_left_abduct_rel_spine = 1
    knee_left_bent = 0

Each keyframe is placed at the template column where it most probably
holds; a mirrored class takes the query mirrored. A query specific to its
class also lets the class's τ be learned through it
(:func:`lab.thresholds.learn_taus`, step 5); one that holds in
other motions too only filters. ``tau = …`` in the table caps the class's τ
(its mirror's too): the query is met only with keyframes on, the τ in both
modes, and a query that shuts motions out may leave the τ learned through it
too high for the motions ``--no-keyframes`` meets whole.

Errors are :class:`~mocapdb.errors.ParseError` naming the file and line.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.annotation.labels import read_text
from mocapdb.annotation.model import DEFAULT_TAU, ClassModel
from mocapdb.errors import ParameterError, ParseError
from mocapdb.features import FEATURE_RATE, MIRROR_BITS, N_BITS, N_FEATURES, WORD_FEATURE_NAMES, reverse_fuzzy_words
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery
from mocapdb.templates import QuantizedTemplate

__all__ = ["Phase", "ClassDefinition", "KeyframeDefinition", "parse_class_definitions", "parse_definitions",
           "read_class_definitions", "read_definitions", "compile_definition", "compile_definitions",
           "attach_keyframes", "apply_keyframe_definitions", "mirror_definition", "reverse_definition", "WILDCARD"]

#: the wildcard value of a feature in a definition
WILDCARD = "*"
_FEATURE = {name: k for k, name in enumerate(WORD_FEATURE_NAMES)}
_CLASS_KEYS = {"name", "label", "mirror", "reverse", "tau", "default", "description", "keyframes", "phase"}
_PHASE_KEYS = {"seconds", "frames", "keyframe", "name"}
#: a single duration d admits [d / WARP, d · WARP] in the keyframe gaps: the
#: DTW steps (1,1), (1,2), (2,1) let a template stretch or shrink by 2
WARP = 2.0


@dataclass(frozen=True)
class Phase:
    """One phase of a class definition.

    Attributes
    ----------
    values : tuple of (int or None)
        Per feature (40, matrix order): 0, 1, or None (wildcard).
    nominal : float
        Duration of the phase in the template, 30 Hz frames.
    min_frames, max_frames : float
        Durations the keyframe gaps admit (``max_frames`` may be ``inf``).
    keyframe : tuple of int
        Features (0-based) the phase's keyframe fixes; empty: no keyframe.
    line : int
        Line of the phase in its file.
    name : str
    """

    values: tuple
    nominal: float
    min_frames: float
    max_frames: float
    keyframe: tuple
    line: int = 0
    name: str = ""


@dataclass(frozen=True)
class ClassDefinition:
    """A hand-designed class: phases of feature values (see the module docstring).

    Attributes
    ----------
    name, label : str
    phases : tuple of Phase
    tau : float
    keyframes : bool
        Whether the class gets a keyframe query.
    description : str
    source : str
        ``path:line`` of the definition.
    """

    name: str
    label: str
    phases: tuple
    tau: float = DEFAULT_TAU
    keyframes: bool = True
    description: str = ""
    source: str = ""
    mirror_of: str | None = field(default=None, compare=False)

    @property
    def n_columns(self) -> int:
        """Template length (30 Hz columns)."""
        return sum(_columns(p) for p in self.phases)


@dataclass(frozen=True)
class KeyframeDefinition:
    """Hand-designed keyframes for a class that has a template already (a ``[[keyframes]]`` table).

    A learned template says how a motion goes on average; what makes it *this*
    motion is often one moment (a kick: the raised leg stretched). Such a
    moment, written as feature values, becomes the class's keyframe query
    (:func:`attach_keyframes`): the template is then matched only around it.

    With ``template`` (``template = "depositFloorR"`` in the table) it makes a
    class of its own: that learned class's template under another query, for
    a form of the motion the learned query leaves out (the learned clips
    deposit with the right hand alone; a box is lifted with both) — the query
    of the learned class stays as it was.

    Attributes
    ----------
    cls : str
        The class it is for (learned, in the recipe or the model), or with
        ``template`` the name of the new class.
    keyframes : tuple of (int, int)
        Per keyframe, in time order, (mask, value) as 40-bit words.
    names : tuple of str
    description, source : str
    template : str
        The learned class whose template the new class ``cls`` takes; empty:
        the keyframes are ``cls``'s own.
    tau : float or None
        τ at most this for the class (and its mirror image), however it is
        learned; None: no cap.
    """

    cls: str
    keyframes: tuple
    names: tuple = ()
    description: str = ""
    source: str = ""
    template: str = ""
    tau: float | None = None


# ---------------------------------------------------------------------------
# parsing


def _locate(text, table="class", sub="phase"):
    """Line numbers of the ``[[table]]`` and ``[[table.sub]]`` headers: [(table line, [sub lines])]."""
    out = []
    for k, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if re.match(r"^\[\[\s*" + table + r"\s*\]\]", s):
            out.append((k, []))
        elif re.match(r"^\[\[\s*" + table + r"\s*\.\s*" + sub + r"\s*\]\]", s) and out:
            out[-1][1].append(k)
    return out


def _key_line(lines, start, key):
    """The line (1-based) of ``key = …`` in the table that starts at line ``start``."""
    pat = re.compile(r"(^|[\s{,])" + re.escape(key) + r"\s*=")
    for k in range(start - 1, len(lines)):
        code = lines[k].split("#", 1)[0]
        if k > start - 1 and code.strip().startswith("["):
            break  # the next table: the key is not in this one
        if pat.search(code):
            return k + 1
    return start


class _Where:
    """Turns a (class, phase, key) position into a ParseError with file and line."""

    def __init__(self, path, text, table="class", sub="phase"):
        self.path = path
        self.lines = text.splitlines()
        self.headers = _locate(text, table, sub)

    def line(self, ci=None, pi=None, key=None):
        if ci is None or ci >= len(self.headers):
            return 1 if ci is None else None
        cline, plines = self.headers[ci]
        start = plines[pi] if pi is not None and pi < len(plines) else cline
        return _key_line(self.lines, start, key) if key is not None else start

    def error(self, message, ci=None, pi=None, key=None):
        return ParseError(self.path, self.line(ci, pi, key), message)


def _value(v, where, ci, pi, key):
    if isinstance(v, bool) or v not in (0, 1, WILDCARD):
        raise where.error(f"{key} = {v!r}: a feature value must be 0, 1 or \"*\" (wildcard)", ci, pi, key)
    return None if v == WILDCARD else int(v)


def _feature(name, where, ci, pi, key=None):
    if name in _FEATURE:
        return _FEATURE[name]
    close = difflib.get_close_matches(str(name), WORD_FEATURE_NAMES, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else "; see mocapdb.features.WORD_FEATURE_NAMES"
    raise where.error(f"unknown feature {name!r}{hint}", ci, pi, key or name)


def _number(v, where, ci, pi, key):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v):
        raise where.error(f"{key} = {v!r}: expected a number or [min, max]", ci, pi, key)
    return float(v)


def _duration(phase, where, ci, pi):
    """(nominal, min, max) in 30 Hz frames."""
    keys = [k for k in ("seconds", "frames") if k in phase]
    if len(keys) != 1:
        raise where.error("a phase needs exactly one of seconds = … or frames = … (30 Hz)", ci, pi)
    key = keys[0]
    scale = FEATURE_RATE if key == "seconds" else 1.0
    v = phase[key]
    if isinstance(v, list):
        if len(v) != 2:
            raise where.error(f"{key} = {v!r}: a range is [min, max]", ci, pi, key)
        lo, hi = (_number(x, where, ci, pi, key) * scale for x in v)
        if not (0 < lo <= hi) or math.isinf(lo):
            raise where.error(f"{key} = {v!r}: need 0 < min <= max (max may be inf)", ci, pi, key)
        nominal = lo if math.isinf(hi) else math.sqrt(lo * hi)
    else:
        nominal = _number(v, where, ci, pi, key) * scale
        if not 0 < nominal < math.inf:
            raise where.error(f"{key} = {v!r}: a duration must be positive and finite", ci, pi, key)
        lo, hi = nominal / WARP, nominal * WARP
    if round(nominal) < 1:
        raise where.error(f"{key} = {v!r}: the phase is shorter than one 30 Hz frame", ci, pi, key)
    return nominal, lo, hi


def _phase(phase, default, where, ci, pi):
    if not isinstance(phase, dict):
        raise where.error("a phase must be a table [[class.phase]]", ci, pi)
    nominal, lo, hi = _duration(phase, where, ci, pi)
    # a phase's default covers the 40 features; derived ones (FEATURES.md §10) only when named
    values = [default] * N_FEATURES + [None] * (N_BITS - N_FEATURES)
    for key, v in phase.items():
        if key in _PHASE_KEYS:
            continue
        values[_feature(key, where, ci, pi)] = _value(v, where, ci, pi, key)
    fixed = tuple(k for k, v in enumerate(values) if v is not None)
    kf = phase.get("keyframe", True)
    if isinstance(kf, bool):
        # keyframes are searched in the index of the 40 features: derived ones stay out
        keyframe = tuple(k for k in fixed if k < N_FEATURES) if kf else ()
    elif isinstance(kf, list) and kf and all(isinstance(x, str) for x in kf):
        keyframe = tuple(sorted({_feature(x, where, ci, pi, "keyframe") for x in kf}))
        loose = [WORD_FEATURE_NAMES[k] for k in keyframe if values[k] is None]
        if loose:
            raise where.error(f"keyframe names {', '.join(loose)}, which the phase leaves as wildcards; "
                              "a keyframe fixes features the phase fixes", ci, pi, "keyframe")
        derived = [WORD_FEATURE_NAMES[k] for k in keyframe if k >= N_FEATURES]
        if derived:
            raise where.error(f"keyframe names {', '.join(derived)}, a derived feature (FEATURES.md §10) that "
                              "the keyframe index does not hold; name features of the 40", ci, pi, "keyframe")
    else:
        raise where.error(f"keyframe = {kf!r}: expected true, false or a list of feature names",
                          ci, pi, "keyframe")
    name = phase.get("name", f"phase {pi + 1}")
    if not isinstance(name, str):
        raise where.error(f"name = {name!r}: expected a string", ci, pi, "name")
    return Phase(tuple(values), nominal, lo, hi, keyframe, where.line(ci, pi), name)


def _string(cls, key, where, ci, *, required=True):
    v = cls.get(key)
    if v is None and not required:
        return None
    if not isinstance(v, str) or not v.strip():
        raise where.error(f"{key} = {v!r}: expected a non-empty string", ci, None, key if key in cls else None)
    return v.strip()


def _description(table, where, ci):
    description = table.get("description", "")
    if not isinstance(description, str):
        raise where.error("description must be a string", ci, None, "description")
    return description


def _class(cls, where, ci):
    if not isinstance(cls, dict):
        raise where.error("expected a table [[class]]", ci)
    unknown = sorted(set(cls) - _CLASS_KEYS)
    if unknown:
        bad = unknown[0]
        if bad in _FEATURE:
            raise where.error(f"feature {bad!r} outside a phase; features go into [[class.phase]] tables",
                              ci, None, bad)
        raise where.error(f"unknown key {bad!r} in [[class]]; allowed: {', '.join(sorted(_CLASS_KEYS))}",
                          ci, None, bad)
    name = _string(cls, "name", where, ci)
    label = _string(cls, "label", where, ci)
    default = _value(cls.get("default", WILDCARD), where, ci, None, "default")
    tau = _tau(cls.get("tau", DEFAULT_TAU), where, ci)
    keyframes = cls.get("keyframes", True)
    if not isinstance(keyframes, bool):
        raise where.error(f"keyframes = {keyframes!r}: expected true or false", ci, None, "keyframes")
    description = _description(cls, where, ci)
    phases = cls.get("phase")
    if not isinstance(phases, list) or not phases:
        raise where.error(f"class {name!r} has no phases; add [[class.phase]] tables", ci)
    parsed = tuple(_phase(p, default, where, ci, pi) for pi, p in enumerate(phases))
    if not any(any(v is not None for v in p.values) for p in parsed):
        raise where.error(f"class {name!r} fixes no feature in any phase (all wildcards match everything)", ci)
    if keyframes and not any(p.keyframe for p in parsed):
        raise where.error(f"class {name!r} has no keyframe; set keyframe = true on a phase that fixes "
                          "features, or keyframes = false on the class", ci)
    defn = ClassDefinition(name, label, parsed, float(tau), keyframes, description,
                           f"{where.path}:{where.line(ci)}")
    out = [defn]
    mirror = _string(cls, "mirror", where, ci, required=False)
    if mirror:
        out.append(mirror_definition(defn, mirror))
    rev = cls.get("reverse")
    if rev is not None:
        if not isinstance(rev, dict) or set(rev) != {"name", "label"} or not all(
                isinstance(v, str) and v.strip() for v in rev.values()):
            raise where.error(f"reverse = {rev!r}: expected {{ name = \"…\", label = \"…\" }}", ci, None, "reverse")
        out += [reverse_definition(d, rev["name"].strip() + ("" if d is defn else "Mirrored"), rev["label"].strip())
                for d in list(out)]
    return out


def _tau(tau, where, ci):
    """A ``tau = …`` value: a non-negative number."""
    if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not 0 <= tau < math.inf:
        raise where.error(f"tau = {tau!r}: expected a non-negative number", ci, None, "tau")
    return float(tau)


_KEYFRAMES_KEYS = {"class", "description", "keyframe", "template", "tau"}


def _keyframes(table, where, ki):
    """A ``[[keyframes]]`` table: KeyframeDefinition."""
    if not isinstance(table, dict):
        raise where.error("expected a table [[keyframes]]", ki)
    unknown = sorted(set(table) - _KEYFRAMES_KEYS)
    if unknown:
        hint = "; features go into [[keyframes.keyframe]] tables" if unknown[0] in _FEATURE else ""
        raise where.error(f"unknown key {unknown[0]!r} in [[keyframes]]; allowed: "
                          f"{', '.join(sorted(_KEYFRAMES_KEYS))}{hint}", ki, None, unknown[0])
    cls = _string(table, "class", where, ki)
    template = _string(table, "template", where, ki) if "template" in table else ""
    if template == cls:
        raise where.error(f"template = {template!r} names the class itself; leave it out for the class's own "
                          "keyframes", ki, None, "template")
    description = _description(table, where, ki)
    frames = table.get("keyframe")
    if not isinstance(frames, list) or not frames:
        raise where.error(f"keyframes for {cls!r} hold no [[keyframes.keyframe]] table", ki)
    words, names = [], []
    for pi, kf in enumerate(frames):
        if not isinstance(kf, dict):
            raise where.error("a keyframe must be a table [[keyframes.keyframe]]", ki, pi)
        values = [None] * N_BITS
        for key, v in kf.items():
            if key != "name":
                values[_feature(key, where, ki, pi)] = _value(v, where, ki, pi, key)
        mask, value = _words(values)
        if not mask:
            raise where.error("a keyframe fixes no feature (all wildcards match every frame)", ki, pi)
        name = kf.get("name", f"keyframe {pi + 1}")
        if not isinstance(name, str):
            raise where.error(f"name = {name!r}: expected a string", ki, pi, "name")
        words.append((mask, value))
        names.append(name)
    tau = _tau(table["tau"], where, ki) if "tau" in table else None
    return KeyframeDefinition(cls, tuple(words), tuple(names), description, f"{where.path}:{where.line(ki)}",
                              template, tau)


def parse_definitions(text, path="<string>"):
    """Class definitions and keyframe definitions from TOML text (see the module docstring).

    Returns
    -------
    classes : list of ClassDefinition
        In file order; a class with ``mirror`` is followed by its mirror image.
    keyframes : list of KeyframeDefinition
        The ``[[keyframes]]`` tables, in file order.

    Raises
    ------
    ParseError
        ``path:line: …`` for TOML syntax errors, unknown keys or features, bad
        values or durations, duplicate class names.
    """
    path = str(path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"at line (\d+)", str(e))
        raise ParseError(path, int(m.group(1)) if m else None, f"not valid TOML: {e}") from None
    where = _Where(path, text)
    unknown = sorted(set(doc) - {"class", "keyframes"})
    if unknown:
        raise ParseError(path, _key_line(where.lines, 1, unknown[0]),
                         f"unknown top-level key {unknown[0]!r}; a definition file holds [[class]] and "
                         "[[keyframes]] tables")
    classes, tables = doc.get("class", []), doc.get("keyframes", [])
    if not isinstance(classes, list) or not isinstance(tables, list) or not (classes or tables):
        raise ParseError(path, 1, "no [[class]] or [[keyframes]] table; see README \"Class definitions\"")
    out, seen = [], {}
    for ci, cls in enumerate(classes):
        for d in _class(cls, where, ci):
            if d.name in seen:
                raise where.error(f"class {d.name!r} is defined twice (first at {seen[d.name]})", ci)
            seen[d.name] = d.source
            out.append(d)
    kwhere = _Where(path, text, "keyframes", "keyframe")
    keyframes, kseen = [], {}
    for ki, table in enumerate(tables):
        k = _keyframes(table, kwhere, ki)
        if k.cls in kseen:
            raise kwhere.error(f"keyframes for class {k.cls!r} are given twice (first at {kseen[k.cls]})", ki)
        kseen[k.cls] = k.source
        keyframes.append(k)
    return out, keyframes


def parse_class_definitions(text, path="<string>"):
    """The class definitions of TOML text (:func:`parse_definitions` without the keyframe tables)."""
    return parse_definitions(text, path)[0]


def read_definitions(paths):
    """Class and keyframe definitions from one or more TOML files (or folders of ``*.toml``, in name order).

    Returns
    -------
    classes : list of ClassDefinition
    keyframes : list of KeyframeDefinition

    Raises
    ------
    ParseError
        As :func:`parse_definitions`; also for a class (or a class's keyframes)
        defined in two files.
    ParameterError
        A path that does not exist or a folder without definition files.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    files = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(p.glob("*.toml"))
            if not found:
                raise ParameterError(f"folder {str(p)!r} holds no class definition files (*.toml)")
            files += found
        elif p.is_file():
            files.append(p)
        else:
            raise ParameterError(f"class definition file {str(p)!r} does not exist")
    out, keyframes, seen = [], [], {}
    for f in files:
        classes, tables = parse_definitions(read_text(f), f)
        for d in classes + tables:
            key = d.name if isinstance(d, ClassDefinition) else ("keyframes", d.cls)
            if key in seen:
                path, _, line = d.source.rpartition(":")
                what = f"class {d.name!r} is" if isinstance(d, ClassDefinition) else f"keyframes for {d.cls!r} are"
                raise ParseError(path, int(line), f"{what} already defined at {seen[key]}")
            seen[key] = d.source
        out += classes
        keyframes += tables
    return out, keyframes


def read_class_definitions(paths):
    """The class definitions of files or folders (:func:`read_definitions` without the keyframe tables)."""
    return read_definitions(paths)[0]


# ---------------------------------------------------------------------------
# mirror and compile


def apply_keyframe_definitions(classes, keyframes) -> tuple:
    """Keyframe definitions applied to classes: (the classes with their queries, the copies).

    A definition for a class (:attr:`KeyframeDefinition.cls`) gives it its
    query (:func:`attach_keyframes`); one with ``template`` makes a copy — a
    class of its own, named ``cls``, with the template (label, δ, τ) of the
    class ``template`` and the definition's query —, the template's class
    keeping its own query. Definitions whose class or template is not among
    ``classes`` are left out: the caller says which it expects (a training
    fold without a class's clips has no class to attach to).

    Parameters
    ----------
    classes : sequence of ClassModel
    keyframes : sequence of KeyframeDefinition

    Returns
    -------
    (tuple of ClassModel, tuple of ClassModel)
        ``classes`` in their order, and the copies in definition order.
    """
    own = {k.cls: k for k in keyframes if not k.template}
    out = tuple(attach_keyframes(c, own[c.name]) if c.name in own else c for c in classes)
    by_name = {c.name: c for c in out}
    copies = tuple(attach_keyframes(dataclasses.replace(by_name[k.template], name=k.cls, keyframe_query=None), k)
                   for k in keyframes if k.template and k.template in by_name)
    return out, copies


def mirror_definition(defn: ClassDefinition, name: str) -> ClassDefinition:
    """The left/right mirror image of a definition (FEATURES.md §7), named ``name``."""
    perm = MIRROR_BITS
    inv = {perm[i]: i for i in range(N_BITS)}
    phases = tuple(Phase(tuple(p.values[perm[i]] for i in range(N_BITS)), p.nominal, p.min_frames,
                         p.max_frames, tuple(sorted(inv[k] for k in p.keyframe)), p.line, p.name)
                   for p in defn.phases)
    return ClassDefinition(name, defn.label, phases, defn.tau, defn.keyframes, defn.description,
                           defn.source, mirror_of=defn.name)


def reverse_definition(defn: ClassDefinition, name: str, label: str) -> ClassDefinition:
    """The definition of the motion played backwards (phases in reverse order, features by
    :func:`mocapdb.features.reverse_fuzzy_words`), named ``name`` with label ``label``."""
    phases = []
    for p in reversed(defn.phases):
        m, v = _words(p.values)
        km, kv = _words(p.values, set(p.keyframe))
        (m, km), (v, _) = reverse_fuzzy_words([m, km], [v, kv])
        m, v, km = int(m), int(v), int(km)
        values = tuple((v >> k) & 1 if (m >> k) & 1 else None for k in range(N_BITS))
        keyframe = tuple(k for k in range(N_BITS) if (km >> k) & 1)
        phases.append(Phase(values, p.nominal, p.min_frames, p.max_frames, keyframe, p.line, p.name))
    return ClassDefinition(name, label, tuple(phases), defn.tau, defn.keyframes and any(p.keyframe for p in phases),
                           defn.description, defn.source, mirror_of=defn.mirror_of)


def _columns(p: Phase) -> int:
    return max(1, int(round(p.nominal)))


def _words(values, features=None):
    mask = value = 0
    for k, v in enumerate(values):
        if v is None or (features is not None and k not in features):
            continue
        mask |= 1 << k
        value |= v << k
    return mask, value


def _query(defn: ClassDefinition, starts):
    """The keyframe query of a definition (module docstring), or None."""
    if not defn.keyframes:
        return None
    kf = [i for i, p in enumerate(defn.phases) if p.keyframe]
    words = [_words(defn.phases[i].values, set(defn.phases[i].keyframe)) for i in kf]
    pos = [starts[i] + (_columns(defn.phases[i]) - 1) // 2 for i in kf]
    d_min, d_max = [], []
    for a, b in zip(kf[:-1], kf[1:]):
        between = defn.phases[a + 1:b]
        d_min.append(1 + math.floor(sum(p.min_frames for p in between)))
        hi = 1 + sum(p.max_frames for p in between)
        d_max.append(UNBOUNDED if math.isinf(hi) else max(d_min[-1], math.ceil(hi)))
    # the chain spans its phases: the first keyframe at its phase's first column, the last at
    # its phase's last (the annotation widens a found chain by twice the columns outside it)
    first, last = kf[0], kf[-1]
    if len(kf) == 1 and _columns(defn.phases[first]) > 1:
        # one keyframe phase: its pose searched at both ends of the phase, up to twice its columns apart
        words.append(words[0])
        pos.append(0)
        d_min.append(1)
        d_max.append(2 * (_columns(defn.phases[first]) - 1))
    if len(pos) > 1:
        pos[0] = starts[first]
        pos[-1] = starts[last] + _columns(defn.phases[last]) - 1
    return KeyframeQuery(np.array([m for m, _ in words], np.uint64), np.array([v for _, v in words], np.uint64),
                         np.array(pos, np.int64), np.array(d_min, np.int64), np.array(d_max, np.int64),
                         defn.n_columns)


def compile_definition(defn: ClassDefinition) -> ClassModel:
    """A class of a model from a definition: quantized template, τ and keyframe query.

    Returns
    -------
    ClassModel
        ``template`` None (no real-valued template), ``quantized`` the
        phases' columns with weights 1, ``keyframe_query`` per the module
        docstring (None with ``keyframes = false``), ``min_frames`` the
        shortest the definition allows (the sum of the phases' minimum
        durations): a shorter segment is not this motion.
    """
    if not isinstance(defn, ClassDefinition):
        raise ParameterError(f"expected a ClassDefinition, got {type(defn).__name__}")
    masks, values, starts = [], [], []
    for p in defn.phases:
        starts.append(len(masks))
        m, v = _words(p.values)
        masks += [m] * _columns(p)
        values += [v] * _columns(p)
    q = QuantizedTemplate(np.array(masks, np.uint64), np.array(values, np.uint64), np.ones(len(masks)))
    shortest = int(math.floor(sum(p.min_frames for p in defn.phases)))
    return ClassModel(defn.name, defn.label, quantized=q, tau=defn.tau, keyframe_query=_query(defn, starts),
                      min_frames=shortest)


def compile_definitions(definitions) -> list:
    """:func:`compile_definition` of each definition, in order."""
    return [compile_definition(d) for d in definitions]


def attach_keyframes(cls: ClassModel, kdef: KeyframeDefinition) -> ClassModel:
    """``cls`` with the keyframe query of a keyframe definition.

    Each keyframe sits at the template column where it is most likely to
    hold: for a learned template, the product over its fixed features of
    the column's probability of that value (the real-valued template);
    otherwise the columns of the quantized template that agree with it.
    Keyframes keep their order (each at or after the one before). A keyframe
    may fit a run of columns equally well (a pose the template holds for a
    while): it holds anywhere in the run, so the gap to the next keyframe
    admits the runs' nearest and farthest columns, d_near and d_far, warped
    as the DTW steps allow, [⌈d_near / 2⌉, 2 d_far] (at least 1 frame;
    d_near = d_far = d for single columns). The query's positions are the
    first keyframe's first column and the last keyframe's last column, so
    the chain spans as much of the template as it can: annotation widens a
    found chain by twice the columns outside it
    (:func:`mocapdb.keyframes.annot_margins`). For the same reason a single
    keyframe that fits a run of columns becomes a chain of itself at both
    ends of the run (the pose held: any two frames of it up to twice the
    run apart). The definition's ``tau``, if any, caps the class's τ.
    """
    if not isinstance(kdef, KeyframeDefinition):
        raise ParameterError(f"expected a KeyframeDefinition, got {type(kdef).__name__}")
    if cls.template is not None:
        prob = np.asarray(cls.template.real, dtype=np.float64)            # (L, 40): P(feature on)
        # a learned template never saw the derived features: either value as likely
        prob = np.hstack([prob, np.full((prob.shape[0], N_BITS - prob.shape[1]), 0.5)])
    else:
        q = cls.quantized.expand()
        m, v = q.mask, q.value
        bits = np.arange(N_BITS, dtype=np.uint64)
        fixed = ((m[:, None] >> bits) & np.uint64(1)).astype(bool)
        on = ((v[:, None] >> bits) & np.uint64(1)).astype(float)
        prob = np.where(fixed, on, 0.5)
    L = prob.shape[0]
    runs, start = [], 0
    for mask, value in kdef.keyframes:
        fit = np.ones(L)
        for f in range(N_BITS):
            if (mask >> f) & 1:
                fit *= prob[:, f] if (value >> f) & 1 else 1.0 - prob[:, f]
        fit[:start] = -1.0
        best = fit >= fit.max() - 1e-12
        a = int(np.argmax(best))
        b = a + int(np.argmin(np.append(best[a:], False))) - 1      # the run of best columns from a
        runs.append((a, b))
        start = a
    words = list(kdef.keyframes)
    if len(runs) == 1 and runs[0][1] > runs[0][0]:
        # one keyframe the template holds over several columns: searched at both ends of them
        runs.append(runs[0])
        words.append(words[0])
    a, b = (np.array(x, np.int64) for x in zip(*runs))
    pos = a.copy()
    if len(runs) > 1:
        pos[-1] = b[-1]
    # a keyframe may hold at any column of its run: the gap to the next spans the runs' nearest
    # and farthest columns, warped as the DTW steps allow
    near = np.maximum(0, a[1:] - b[:-1])
    far = b[1:] - a[:-1]
    d_min = np.maximum(1, np.ceil(near / WARP)).astype(np.int64)
    d_max = np.maximum(d_min, np.floor(far * WARP)).astype(np.int64)
    q = KeyframeQuery(np.array([m for m, _ in words], np.uint64), np.array([v for _, v in words], np.uint64),
                      np.array(pos, np.int64), d_min, d_max, L)
    tau = cls.tau if kdef.tau is None else min(cls.tau, kdef.tau)
    return dataclasses.replace(cls, keyframe_query=q, tau=tau)
