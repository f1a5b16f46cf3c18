"""A third lab's clips with what a user expects of each: documents, per-clip truth and the measures.

``accad_dev`` (data/README.md) holds 69 BVH clips of one performer of the
ACCAD lab — walks, runs, side steps, backward walks, turns of 45–180°, hops
and leaps, crouches, crawling — and ``truth.csv``, which says per clip what
a user expects (``file,content,expected_labels,notes``). Unlike the studio's
clips (:mod:`lab.studio`) a clip here may hold several
actions (stand, then walk), so the truth is per clip, not per frame:
``expected_labels`` is ``+``-joined tokens —

* ``x``: label x must appear somewhere in the clip;
* ``a|b``: one of them must;
* ``?x``: x is acceptable, neither required nor wrong;
* ``none``: nothing is required (a motion outside the 15 classes: crawling,
  swaying, looking around), and any label not ``?``-listed is wrong.

A clip is **right** when every required token is found and no label outside
the required and acceptable ones appears. ``neutral`` (standing) is never a
wrong label — silence is either no label or ``neutral`` (issue 32) — and the
clips where it appears unlisted are counted apart.

:func:`lab_documents` reads the clips as documents (a clip each, 30 Hz
words); :func:`lab_measures` computes what a user would check: clips right,
locomotion clips with ``move`` and the share of their frames under it —
all of them, and those where the root travels (:mod:`lab.travel`) —,
turning clips with a ``turn``, locomotion clips where a turn is wrong that
have one, clips of no class left silent, and which clips failed and why.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.annotation.labels import LABEL_DTYPE
from mocapdb.errors import ParameterError, ParseError
from lab.documents import DocumentSet
from lab.travel import travelling_frames
from mocapdb.features import motion_features
from mocapdb.readers import read_motion

__all__ = ["LAB_FOLDER", "LOCOMOTION_EXTRAS", "ClipTruth", "LabDocuments", "LabScores", "parse_expected",
           "lab_clip_files", "lab_documents", "lab_measures"]

#: the folder of the development data that holds the clips
LAB_FOLDER = "accad_dev"
#: labels that may go with ``move`` in a clip that is locomotion throughout (a walker who turns or
#: hops is still moving); a clip that also stands, crouches or handles a box is not
LOCOMOTION_EXTRAS = frozenset({"turn", "jump", "hopOneLeg"})
_LABEL = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: never a wrong label: silence is no label or ``neutral``
SILENT = "neutral"


@dataclass(frozen=True)
class ClipTruth:
    """What a user expects of one clip (module docstring).

    Attributes
    ----------
    required : tuple of frozenset of str
        Each a token that must be found: one of its labels.
    acceptable : frozenset of str
        ``?``-listed labels: neither required nor wrong.
    """

    required: tuple
    acceptable: frozenset

    @property
    def allowed(self) -> frozenset:
        return frozenset().union(*self.required, self.acceptable, {SILENT})

    @property
    def requires(self) -> frozenset:
        """Labels required alone (not one of alternatives)."""
        return frozenset(lab for r in self.required if len(r) == 1 for lab in r)

    @property
    def locomotion(self) -> bool:
        """``move`` required and nothing else but turns and hops mentioned: moving throughout."""
        mentioned = frozenset().union(*self.required, self.acceptable)
        return "move" in self.requires and mentioned - {"move"} <= LOCOMOTION_EXTRAS

    def verdict(self, found) -> tuple:
        """(missing tokens, wrong labels) of the set of labels ``found`` in the clip."""
        found = set(found)
        missing = tuple("|".join(sorted(r)) for r in self.required if not r & found)
        return missing, tuple(sorted(found - self.allowed))


def parse_expected(text, *, where="expected_labels") -> ClipTruth:
    """A :class:`ClipTruth` from an ``expected_labels`` cell (``move+turn``, ``none+?standUp``, …).

    Raises
    ------
    ParameterError
        An empty token, or ``none`` beside a required label.
    """
    required, acceptable, none = [], set(), False
    for tok in str(text).strip().split("+"):
        tok = tok.strip()
        if tok == "none":
            none = True
        elif tok.startswith("?") and _LABEL.match(tok[1:]):
            acceptable.add(tok[1:])
        elif all(_LABEL.match(x) for x in tok.split("|")):
            required.append(frozenset(tok.split("|")))
        else:
            raise ParameterError(f"{where}: {tok!r} is no label token (x, a|b, ?x or none) in {text!r}")
    if none and required:
        raise ParameterError(f"{where}: 'none' beside required labels in {text!r}")
    return ClipTruth(tuple(required), frozenset(acceptable))


@dataclass(frozen=True, eq=False)
class LabDocuments:
    """The clips as documents (a clip each; ``docs.truth`` is empty: the truth is per clip).

    A clip the reader refuses (crawling on all fours is no upright human to
    it) is kept in ``refused``: a user who ingests it gets no label there, and
    :func:`lab_measures` scores it so.
    """

    docs: DocumentSet
    truth: tuple          # ClipTruth per document
    contents: tuple       # truth.csv's description per document
    refused: tuple = ()   # (name, ClipTruth, reason) of the clips the reader refuses: a user gets no label there
    travelling: tuple = ()  # per document, a boolean per frame: the root travels (:func:`lab.travel.travelling_frames`)


def lab_clip_files(data_dir) -> list:
    """``(path, ClipTruth, content)`` of every clip ``<data_dir>/accad_dev/truth.csv`` names, in its order.

    Raises
    ------
    ParameterError
        No ``truth.csv``, a row without its file, or a cell that does not parse
        (the message names the file and line).
    """
    folder = Path(data_dir) / LAB_FOLDER
    table = folder / "truth.csv"
    try:
        with open(table, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError as exc:
        raise ParameterError(f"{table}: cannot read the clips' truth ({exc.strerror})") from None
    out = []
    for line, r in enumerate(rows, start=2):
        if not {"file", "expected_labels"} <= set(r) or not r["file"]:
            raise ParameterError(f"{table}, line {line}: needs the columns file and expected_labels")
        path = folder / r["file"]
        if not path.is_file():
            raise ParameterError(f"{table}, line {line}: {r['file']!r} is not in {str(folder)!r}")
        out.append((path, parse_expected(r["expected_labels"], where=f"{table}, line {line}"), r.get("content", "")))
    return out


def lab_documents(data_dir) -> LabDocuments:
    """Read ``<data_dir>/accad_dev``: every clip ``truth.csv`` names (:func:`lab_clip_files`, whose errors it
    raises), in its order; a clip the reader refuses goes to ``refused``."""
    table = Path(data_dir) / LAB_FOLDER / "truth.csv"
    names, words, native, truth, contents, refused, travelling = [], [], [], [], [], [], []
    for path, expected, content in lab_clip_files(data_dir):
        name = path.name.split(".bvh")[0]
        try:
            motion = read_motion(path)
        except ParseError as exc:
            refused.append((name, expected, str(exc)))
            continue
        w = motion_features(motion)
        truth.append(expected)
        names.append(name)
        words.append(w)
        native.append(motion.n_frames)
        contents.append(content)
        travelling.append(travelling_frames(motion))
    if not names:
        raise ParameterError(f"{table}: no clips")
    empty = np.empty(0, LABEL_DTYPE)
    docs = DocumentSet(tuple(names), np.concatenate(words), np.array([w.size for w in words], np.int64),
                       np.array(native, np.int64), empty, empty)
    return LabDocuments(docs, tuple(truth), tuple(contents), tuple(refused), tuple(travelling))


@dataclass(frozen=True)
class LabScores:
    """What :func:`lab_measures` finds.

    Attributes
    ----------
    clips_right, clips : int
        Clips entirely right (every required token, no wrong label), of all.
    move_found, move_clips : int
        Clips that require ``move`` with a ``move`` segment, of all such.
    move_share : float
        Frames of the locomotion clips (:attr:`ClipTruth.locomotion`) under ``move``.
    move_share_travelling : float or None
        The same over the frames of those clips where the root travels (:mod:`lab.travel`): a clip that
        stands still before it walks, or between side steps, is not expected to be ``move`` there.
        None without :attr:`LabDocuments.travelling`.
    turning_with_turn, turning_clips : int
        Clips that require ``turn`` with one, of all such.
    straight_with_turn, straight_clips : int
        Locomotion clips where ``turn`` is wrong (e.g. 45° turns) with one, of all such.
    silent_right, silent_clips : int
        Clips of no class (``none``) without a wrong label, of all such.
    hops_found, hop_clips : int
        Clips that require ``jump|hopOneLeg`` with one of them, of all such.
    neutral_unlisted : int
        Clips with ``neutral`` where the truth does not list it (counted apart, never wrong).
    wrong_by_label : dict of str to int
        Clips with each wrong label.
    failures : dict of str to str
        Clip → what is missing and what is wrong.
    expected : frozenset of str
        Every label some clip's truth requires or accepts (with ``neutral``): a label outside it is
        wrong wherever it appears.
    clip_truth : dict of str to ClipTruth
        Clip → its truth (refused clips included).
    """

    clips_right: int
    clips: int
    move_found: int
    move_clips: int
    move_share: float
    turning_with_turn: int
    turning_clips: int
    straight_with_turn: int
    straight_clips: int
    silent_right: int
    silent_clips: int
    hops_found: int
    hop_clips: int
    neutral_unlisted: int
    wrong_by_label: dict
    failures: dict
    expected: frozenset = frozenset()
    clip_truth: dict = field(default_factory=dict, repr=False)
    move_share_travelling: float | None = None


def lab_measures(lab: LabDocuments, auto) -> LabScores:
    """The measures of :class:`LabScores` for an annotation of the clips (30 Hz, 0-based inclusive)."""
    auto = np.asarray(auto)
    if auto.dtype != LABEL_DTYPE:
        raise ParameterError("auto must be label rows (mocapdb.annotation.labels.LABEL_DTYPE)")
    c = dict.fromkeys(("right", "move_found", "move_clips", "turn_found", "turn_clips", "straight_turn",
                       "straight", "silent_right", "silent", "hops_found", "hops", "neutral"), 0)
    loco_frames = loco_move = travel_frames = travel_move = 0
    travelling = dict(zip(lab.docs.names, lab.travelling))
    wrong_by, failures = {}, {}
    clips = [*zip(lab.docs.names, lab.truth, lab.docs.doc_lengths.tolist()), *((n, t, 0) for n, t, _ in lab.refused)]
    for name, truth, n in clips:
        mine = auto[auto["document"] == name]
        found = set(mine["label"].tolist())
        missing, wrong = truth.verdict(found)
        c["right"] += not missing and not wrong
        if missing or wrong:
            failures[name] = "; ".join(([f"missing {', '.join(missing)}"] if missing else [])
                                       + ([f"wrong {', '.join(wrong)}"] if wrong else []))
        for lab_ in wrong:
            wrong_by[lab_] = wrong_by.get(lab_, 0) + 1
        listed = SILENT in truth.acceptable or any(SILENT in r for r in truth.required)
        c["neutral"] += SILENT in found and not listed
        if "move" in truth.requires:
            c["move_clips"] += 1
            c["move_found"] += "move" in found
        if "turn" in truth.requires:
            c["turn_clips"] += 1
            c["turn_found"] += "turn" in found
        if any(r == {"jump", "hopOneLeg"} for r in truth.required):
            c["hops"] += 1
            c["hops_found"] += bool(found & {"jump", "hopOneLeg"})
        if not truth.required:
            c["silent"] += 1
            c["silent_right"] += not wrong
        if truth.locomotion:
            covered = np.zeros(n, dtype=bool)
            for r in mine[mine["label"] == "move"]:
                covered[int(r["start"]):int(r["end"]) + 1] = True
            loco_frames += n
            loco_move += int(covered.sum())
            if name in travelling:
                travel_frames += int(travelling[name].sum())
                travel_move += int((covered & travelling[name]).sum())
            if "turn" not in truth.allowed:
                c["straight"] += 1
                c["straight_turn"] += "turn" in found
    return LabScores(
        clips_right=c["right"], clips=len(clips), move_found=c["move_found"], move_clips=c["move_clips"],
        move_share=loco_move / loco_frames if loco_frames else 0.0,
        turning_with_turn=c["turn_found"], turning_clips=c["turn_clips"],
        straight_with_turn=c["straight_turn"], straight_clips=c["straight"],
        silent_right=c["silent_right"], silent_clips=c["silent"], hops_found=c["hops_found"], hop_clips=c["hops"],
        neutral_unlisted=c["neutral"], wrong_by_label=dict(sorted(wrong_by.items(), key=lambda kv: -kv[1])),
        failures=failures, expected=frozenset().union(*(t.allowed for _, t, _ in clips)),
        clip_truth={name: t for name, t, _ in clips},
        move_share_travelling=(travel_move / travel_frames if travel_frames else 0.0) if lab.travelling else None)
