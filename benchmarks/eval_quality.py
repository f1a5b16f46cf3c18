"""Annotation quality over every labelled set at once: one table, the previous default beside the new.

Runs :func:`mocapdb.evaluation.development_evaluation` on the same folds and
documents for three recipes, each with and without keyframes, every set
scored over the paper's 15 labels (Table 1; truth labels outside them are
'others', left unlabelled by a good annotation; ``turn`` is not scored on
sets whose truth never carries it, :data:`mocapdb.evaluation.UNSCORED`):

* **reference** — the toolbox's way: a template per HDM05 class (11
  classes), τ = 0.13, no keyframes (the shipped ``toolbox`` model);
* **previous** — the recipe of the default shipped at ``--previous``
  (default a7c2d94): its class and keyframe definitions, read from git, with
  the training it had (HDM05, CMU stretches, poses; nothing of the studio);
* **new** — :func:`lab.recipe.default_recipe` as shipped now,
  trained by :func:`lab.default_model.train_recipe`.

Folds (every set held out from what annotates it): leave-one-actor-out on
hdm05_cut (loao, its mirror image loao_mirrored), leave-one-document-out
on the CMU documents, leave-one-style-out on the studio's clips
(bandai2_dev, when a recipe trains on them; else the model of all data).
The studio block gives what a user of another studio's library checks:
locomotion frames labelled ``move`` (per content), turning clips with a
``turn``, straight clips with one, gesture frames under a label.
Where the truth is per clip (bandai2, accad), ``move`` is also given over the
locomotion frames where the root travels (:mod:`lab.travel`): a clip that
stands before it walks is not expected to be ``move`` there.

The third lab's clips (accad_dev, never trained on) are annotated by each
recipe's model of all the other data and scored per clip (every expected
label found, nothing wrong; locomotion under ``move``, turns, silence on
motions of no class, hops).

**Leave-one-lab-out** (``--lolo``, on by default): the new recipe trained
without each lab in turn (HDM05, CMU, bandai2_dev, accad_dev) annotates that
lab — what a stranger with another lab's recordings sees —, with and
without keyframes; per fold its figures, inside the fold per actor / document
/ style, and the spread (min–max) across folds; and the lab's short clips
(:mod:`lab.short_clips`: a clip of one gait cycle, 0.7 and 1 s, with
``move``; short excerpts of its other motions with a wrong label).
The segments' confidence is judged there twice: the raw score, and
calibrated — each lab's segments through confidence maps fitted on the other
labs' segments only (:func:`lab.calibration.calibrated_by_lab`).

``--shipped`` also scores the shipped models themselves (the previous one
from git, the new one from the package) on every set — the figures the
quality guard keeps (``tests/quality_records.json``); ``--record`` raises
those records to the new model's figures where they are better (never
lowers them) and stamps them with its fingerprint.

Usage: python benchmarks/eval_quality.py [--previous REV] [--shipped] [--record] [--json FILE] [--seed 0]
       [--only lolo,shipped]   (development: only these sections; the table in RESULTS.md runs them all)
"""
import argparse
import ast
import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from mocapdb.evaluation import evaluate_annotation, evaluate_by_label
from mocapdb.storage.model_store import fingerprint

from timing import model_at, model_dir

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)
from lab.calibration import calibrated_by_lab, confidence_calibration, held_out_segments, top_share_right
from lab.development import SETTINGS, development_data, development_evaluation
from lab.records import guard, headline_figures, raised_records, read_records, write_records
from lab.short_clips import short_clip_measures, short_clips
from lab.studio import studio_measures
from lab.default_model import train_recipe
from lab.recipe import PAPER_LABELS, default_recipe

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
RECORDS = REPO / "tests" / "quality_records.json"

#: paper Table 2 (Müller, Baak & Seidel 2009): F1 / F2
PAPER = {"total, without keyframes": (0.60, 0.70), "total, with keyframes": (0.74, 0.82),
         "CMU, with keyframes": (0.70, 0.76)}
MODES = {"keyframes": {}, "no keyframes": {"keyframes": False}}


def _jsonable(x):
    """Sets as sorted lists (their own order is the hash's, which moves between runs); anything else as text."""
    return sorted(x) if isinstance(x, (set, frozenset)) else str(x)


def previous_mirrors(rev):
    """``DEFAULT_MIRRORS`` as it was at git revision ``rev`` (the recipe module has moved since)."""
    for path in ("lab/recipe.py", "mocapdb/learning/recipe.py"):
        run = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:{path}"], capture_output=True, text=True)
        if run.returncode == 0:
            for node in ast.parse(run.stdout).body:
                if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "DEFAULT_MIRRORS"
                                                        for t in node.targets):
                    return ast.literal_eval(node.value)
    raise SystemExit(f"revision {rev} has no DEFAULT_MIRRORS in lab/recipe.py or mocapdb/learning/recipe.py")


def previous_recipe(rev):
    """The default recipe as it was at git revision ``rev``: its class and keyframe definitions and its mirrors."""
    folder = Path(tempfile.mkdtemp(prefix="mocapdb-classes-"))
    names = subprocess.run(["git", "-C", str(REPO), "ls-tree", "--name-only", f"{rev}:mocapdb/shipped_models/classes"],
                           check=True, capture_output=True, text=True).stdout.split()
    for name in names:
        blob = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:mocapdb/shipped_models/classes/{name}"],
                              check=True, capture_output=True).stdout
        (folder / name).write_bytes(blob)
    return dataclasses.replace(default_recipe(folder), mirrors=previous_mirrors(rev), concurrent_labels=())


def builder(recipe, seed):
    cache = {}

    def build(clips, name):
        return train_recipe(clips, recipe, name=name, seed=seed, cache=cache).model
    return build


def fixed(model):
    return lambda clips, name: model


def _cell(res, s, label=None):
    if s not in res.scores:
        return "    -    "
    if label is None:
        sc = res.scores[s]
    elif label not in res.vocabulary.get(s, ()):
        return "    -    "                                    # not scored on this set (UNSCORED)
    else:
        sc = evaluate_by_label(res.truth[s], res.auto[s], labels=[label])[label]
        if not (sc.truth_segments or sc.auto_segments):
            return "    .    "
    return f"{sc.f1:.3f}/{sc.f2:.2f}"


def print_table(columns):
    """One table: every set, all labels then each label, F1/F2 per column."""
    names = list(columns)
    print(f"{'':<24s}" + "".join(f"{n:>12s}" for n in names))
    for s in SETTINGS:
        any_res = next(r for r in columns.values())
        if s not in any_res.scores:
            continue
        docs = any_res.documents.get(s)
        size = f" ({len(docs.names)} documents, {int(docs.doc_lengths.sum())} frames)" if docs is not None else ""
        print(f"{s}{size}")
        print(f"{'  all labels':<24s}" + "".join(f"{_cell(r, s):>12s}" for r in columns.values()))
        for lab in PAPER_LABELS:
            cells = [_cell(r, s, lab) for r in columns.values()]
            if any(c.strip() not in (".", "-") for c in cells):  # "-": not scored, ".": no segment either side
                print(f"{'  ' + lab:<24s}" + "".join(f"{c:>12s}" for c in cells))


def _print_rows(rows, columns, attr):
    """A row per (name, fn): fn of each column's measures (its attribute ``attr``), '-' where it has none."""
    width = max(14, *(len(n) + 2 for n in columns))
    print(f"{'':<34s}" + "".join(f"{n:>{width}s}" for n in columns))
    for name, fn in rows:
        print(f"{name:<34s}" + "".join(f"{(fn(getattr(r, attr)) if getattr(r, attr) else '-'):>{width}s}"
                                       for r in columns.values()))


def _share(v):
    return "-" if v is None else f"{v:.3f}"


def print_studio(columns):
    print("\nbandai2 (another studio's clips, leave-one-style-out where a recipe trains on them)")
    rows = [("locomotion frames labelled move", lambda st: f"{st.move_share:.3f}"),
            ("  of those where the root travels", lambda st: _share(st.move_share_travelling))]
    contents = sorted({c for r in columns.values() if r.studio for c in r.studio.move_by_content})
    rows += [(f"  {c}", lambda st, c=c: f"{st.move_by_content.get(c, 0):.3f}") for c in contents]
    rows += [("turning clips with a turn", lambda st: f"{st.turning_with_turn}/{st.turning_clips}"),
             ("straight clips with a turn", lambda st: f"{st.straight_with_turn}/{st.straight_clips}"),
             ("gesture frames labelled", lambda st: f"{st.gesture_wrong:.3f}")]
    _print_rows(rows, columns, "studio")
    for n, r in columns.items():
        if r.studio and r.studio.wrong_by_label:
            print(f"  gesture frames by label, {n}: "
                  + ", ".join(f"{k} {v:.3f}" for k, v in r.studio.wrong_by_label.items()))


def print_lab(columns):
    print("\naccad_dev (a third lab's clips, never trained on; per clip: every expected label, nothing wrong)")
    rows = [("clips entirely right", lambda L: f"{L.clips_right}/{L.clips}"),
            ("clips needing move with move", lambda L: f"{L.move_found}/{L.move_clips}"),
            ("locomotion frames labelled move", lambda L: f"{L.move_share:.3f}"),
            ("  of those where the root travels", lambda L: _share(L.move_share_travelling)),
            ("turning clips with a turn", lambda L: f"{L.turning_with_turn}/{L.turning_clips}"),
            ("straight clips with a turn", lambda L: f"{L.straight_with_turn}/{L.straight_clips}"),
            ("clips of no class left silent", lambda L: f"{L.silent_right}/{L.silent_clips}"),
            ("hops/leaps in locomotion found", lambda L: f"{L.hops_found}/{L.hop_clips}")]
    _print_rows(rows, columns, "lab")
    for n, r in columns.items():
        if r.lab and r.lab.failures:
            print(f"  failing clips, {n}: " + "; ".join(f"{k.removeprefix('Male1_')} ({v})"
                                                      for k, v in r.lab.failures.items()))


def _group_f1(res, s, group):
    """F1 per group of a setting's documents (``group(document)`` → its actor, document, style)."""
    docs = res.documents[s].names
    out = {}
    for g in dict.fromkeys(group(d) for d in docs):
        mine = [d for d in docs if group(d) == g]
        t, a = res.truth[s], res.auto[s]
        out[g] = evaluate_annotation(t[np.isin(t["document"], mine)], a[np.isin(a["document"], mine)],
                                     labels=res.vocabulary[s]).f1
    return out


def lolo_folds(res, studio):
    """Per lab (fold): its figures and the figures of the groups inside it (``studio``: the studio's documents)."""
    fig = headline_figures(res)
    out = {}
    if "loao" in res.scores:
        out["hdm05"] = {"f1": fig["loao"]["f1"], "f1 mirrored": fig.get("loao_mirrored", {}).get("f1"),
                        "move": fig["loao"].get("move_recall"),
                        "per actor": _group_f1(res, "loao", lambda d: d.split("_")[1])}
    if "cmu" in res.scores:
        out["cmu"] = {"f1": fig["cmu"]["f1"], "f1 86_09": fig["cmu86_09"]["f1"], "f1 mocap6": fig["mocap6"]["f1"],
                      "move": fig["cmu"].get("move_recall"),
                      "per document": _group_f1(res, "cmu", lambda d: d)}
    if res.studio is not None:
        st = res.studio
        out["bandai2"] = {"f1": fig["bandai2"]["f1"], "move": st.move_share,
                          "move travelling": st.move_share_travelling,
                          "turning with turn": fig["bandai2"]["turning_with_turn"],
                          "straight with turn": fig["bandai2"]["straight_with_turn"],
                          "gesture frames labelled": st.gesture_wrong,
                          "per style": _group_f1(res, "bandai2", lambda d: d.split("_")[2])}
        by_style = {style: studio_measures(studio.subset(np.array(studio.styles) == style), res.auto["bandai2"])
                    for style in sorted(set(studio.styles))}
        out["bandai2"]["move per style"] = {k: v.move_share for k, v in by_style.items()}
        out["bandai2"]["move travelling per style"] = {k: v.move_share_travelling for k, v in by_style.items()}
        out["bandai2"]["gesture frames labelled per style"] = {k: v.gesture_wrong for k, v in by_style.items()}
        # which labels fire on the gestures, over all styles and per style (what a fix must silence)
        out["bandai2"]["gesture frames by label"] = dict(st.wrong_by_label)
        for style, v in by_style.items():
            out["bandai2"][f"gesture frames by label, {style}"] = dict(v.wrong_by_label)
    if res.lab is not None:
        a = fig["accad"]
        out["accad"] = {"clips right": a["clips_right"], "move": a["move_share"],
                        "move travelling": res.lab.move_share_travelling,
                        "turning with turn": a["turning_with_turn"], "straight with turn": a["straight_with_turn"],
                        "silent on no class": a["silent_right"], "hops found": a["hops_found"]}
    return out


def lolo_short_clips(res, clips, mode):
    """Per lab: its short clips (:mod:`lab.short_clips`) annotated by the model trained without it."""
    out = {}
    for lab, by_length in clips.items():
        model = res.models.get(f"without_{lab}")
        if model is None:
            continue
        for s, c in by_length.items():
            m = short_clip_measures(c, model, keyframes=mode == "keyframes")
            out.setdefault(lab, {})[f"cycles of {s} s with move"] = m["cycles with move"]
            out[lab][f"excerpts of {s} s with a wrong label"] = m["excerpts with a wrong label"]
            out[lab][f"excerpts of {s} s, wrong labels"] = m["wrong by label"]
    return out


def print_lolo(folds_by_mode):
    print("\nLeave-one-lab-out (the new recipe trained on none of the annotated lab's clips)")
    for mode, folds in folds_by_mode.items():
        print(f"  {mode}")
        for lab, figs in folds.items():
            parts = []
            for k, v in figs.items():
                if isinstance(v, dict) and not v:
                    parts.append(f"{k} none")
                elif isinstance(v, dict) and all(isinstance(x, int) for x in v.values()):   # counts
                    parts.append(f"{k} " + ", ".join(f"{g} {x}" for g, x in v.items()))
                elif isinstance(v, dict):
                    vals = list(v.values())
                    parts.append(f"{k} {min(vals):.3f}–{max(vals):.3f} (" + ", ".join(f"{g} {x:.3f}"
                                                                                     for g, x in v.items()) + ")")
                elif v is not None:
                    parts.append(f"{k} {v:.3f}")
            print(f"    {lab:<8s} " + "; ".join(parts))
        for k in ("f1", "move", "move travelling"):
            vals = {lab: f[k] for lab, f in folds.items() if f.get(k) is not None}
            if vals:
                print(f"    spread of {k} across labs: {min(vals.values()):.3f}–{max(vals.values()):.3f} "
                      f"(sd {np.std(list(vals.values())):.3f})")


def confidence_parts(res, *, calibrated=False):
    """Per judged set, (raw confidence, right); with ``calibrated`` also (calibrated confidence, right): each lab's
    segments through confidence maps fitted on the other labs' (the evaluation trains its models without maps)."""
    held = held_out_segments(res)
    raw = {s: (c, r) for s, (_, c, r) in held.items()}
    return (raw, calibrated_by_lab(PAPER_LABELS, held)) if calibrated else raw


def _with_pooled(parts):
    """The parts and, if any, every set's pairs concatenated as ``pooled``."""
    if not parts:
        return dict(parts)
    return dict(parts) | {"pooled": tuple(np.concatenate(x) for x in zip(*parts.values()))}


def calibration_rows(parts):
    """Per judged set and pooled: the confidence's calibration (segments ≥ 0.5 right, AUC)."""
    return {s: confidence_calibration(*v) for s, v in _with_pooled(parts).items()}


def raw_at_calibrated_count(raw, calibrated):
    """Per judged set and pooled: the share right of the raw score's k most trusted segments, k the number the
    calibrated confidence puts at ≥ 0.5 — the two confidences compared at the same coverage."""
    raw, calibrated = _with_pooled(raw), _with_pooled(calibrated)
    return {s: top_share_right(c, right, int((calibrated[s][0] >= 0.5).sum())) for s, (c, right) in raw.items()}


def print_calibration(title, by_mode):
    print(f"\n{title}: segments with confidence >= 0.5 that are right; AUC of right over wrong (target 0.90; 0.85)")
    for mode, rows in by_mode.items():
        print(f"  {mode}: " + "; ".join(f"{s} {c.confident_right:.3f} of {c.confident}/{c.segments}, "
                                        f"AUC {c.auc:.3f}" for s, c in rows.items()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous", default="a7c2d94", help="git revision of the previous default (its recipe)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shipped", action="store_true", help="also score the shipped models (the guard's figures)")
    ap.add_argument("--record", action="store_true", help="raise tests/quality_records.json to the new shipped "
                                                          "model's figures (implies --shipped)")
    ap.add_argument("--json", type=Path, default=REPO / "benchmarks" / "eval_quality.json")
    ap.add_argument("--only", default=None, help="comma-separated sections to run (folds, lolo, shipped); "
                                                  "default folds and lolo, and shipped with --shipped/--record")
    args = ap.parse_args()
    args.shipped = args.shipped or args.record
    sections = set(args.only.split(",")) if args.only else {"folds", "lolo"} | ({"shipped"} if args.shipped else set())
    args.shipped = "shipped" in sections
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, numba threads "
          f"{numba.config.NUMBA_NUM_THREADS}; data {DATA}; previous {args.previous}\n")
    t0 = time.perf_counter()
    data = development_data(DATA)
    # the previous recipe knew nothing of the studio's clips
    old_data = dataclasses.replace(data, studio_trains=False)
    common = dict(vocabulary=PAPER_LABELS, mirrored=True, seed=args.seed)
    timings, results = {}, {}
    # the figures are tied to the shipped model they were measured beside (a test compares)
    shipped_fp = fingerprint(model_dir(REPO / "mocapdb" / "shipped_models" / "default"))
    out = {"parameters": {"previous": args.previous, "seed": args.seed, "sections": sorted(sections),
                          "fingerprint": shipped_fp}}
    if "folds" in sections:
        t = time.perf_counter()
        results["reference"] = development_evaluation(DATA, data=old_data, cmu_training=False, tau=0.13,
                                                      modes={"no keyframes": {"keyframes": False}}, **common)
        timings["reference"] = time.perf_counter() - t
        for name, recipe, d in (("previous", previous_recipe(args.previous), old_data),
                                ("new", default_recipe(), data)):
            t = time.perf_counter()
            results[name] = development_evaluation(DATA, data=d, build=builder(recipe, args.seed), modes=MODES,
                                                   **common)
            timings[name] = time.perf_counter() - t
        columns = {"reference": results["reference"]["no keyframes"]}
        for name in ("previous", "new"):
            columns[f"{name} kf"] = results[name]["keyframes"]
            columns[f"{name} no-kf"] = results[name]["no keyframes"]

        print(f"Development evaluation over the paper's 15 labels, every set held out (seed {args.seed}); F1/F2\n")
        print_table(columns)
        print_studio({k: v for k, v in columns.items() if k != "reference"})
        print_lab(columns)
        print_calibration("Confidence, the new recipe's folds",
                          {m: calibration_rows(confidence_parts(results["new"][m])) for m in MODES})
        print()
        for k, (f1, f2) in PAPER.items():
            print(f"paper {k:<34s} {f1:.2f}/{f2:.2f}")
        out |= {"columns": {n: {s: {"f1": sc.f1, "f2": sc.f2, "p1": sc.p1, "r1": sc.r1}
                                for s, sc in r.scores.items()} for n, r in columns.items()},
                "studio": {n: dataclasses.asdict(r.studio) | {"scores": None} for n, r in columns.items()
                           if r.studio},
                "lab": {n: dataclasses.asdict(r.lab) for n, r in columns.items() if r.lab}}
    if "lolo" in sections:
        t = time.perf_counter()
        lolo = development_evaluation(DATA, data=data, build=builder(default_recipe(), args.seed), modes=MODES,
                                      leave_out_lab=True, **common)
        timings["leave-one-lab-out"] = time.perf_counter() - t
        folds = {m: lolo_folds(r, data.studio) for m, r in lolo.items()}
        # a clip of one gait cycle, a short excerpt of another motion: a file of 0.7-1 s of its own
        shorts = short_clips(DATA, data)
        for m, r in lolo.items():
            for lab, figs in lolo_short_clips(r, shorts, m).items():
                folds[m].setdefault(lab, {}).update(figs)
        print_lolo(folds)
        print_lab({f"lolo {m}": r for m, r in lolo.items()})
        parts = {m: confidence_parts(r, calibrated=True) for m, r in lolo.items()}
        calibration = {m: calibration_rows(raw) for m, (raw, _) in parts.items()}
        print_calibration("Confidence (raw score), leave-one-lab-out", calibration)
        calibrated = {m: calibration_rows(cal) for m, (_, cal) in parts.items()}
        print_calibration("Confidence calibrated (each lab's maps fitted on the other labs' segments), "
                          "leave-one-lab-out", calibrated)
        same_count = {m: raw_at_calibrated_count(raw, cal) for m, (raw, cal) in parts.items()}
        print("  the raw score's as many most trusted segments (as the calibrated puts >= 0.5), share right:")
        for m, rows in same_count.items():
            print(f"  {m}: " + "; ".join(f"{s} {v:.3f}" for s, v in rows.items()))
        out["lolo"] = folds
        out["lolo_calibration"] = {m: {s: dataclasses.asdict(c) for s, c in rows.items()}
                                   for m, rows in calibration.items()}
        out["lolo_calibrated"] = {m: {s: dataclasses.asdict(c) for s, c in rows.items()}
                                  for m, rows in calibrated.items()}
        out["lolo_raw_at_calibrated_count"] = same_count
    if args.shipped:
        t = time.perf_counter()
        shipped = {"previous shipped": model_at(args.previous),
                   "new shipped": model_dir(REPO / "mocapdb" / "shipped_models" / "default")}
        figures = {}
        for name, model in shipped.items():
            res = development_evaluation(DATA, data=data, build=fixed(model), modes=MODES, cmu_training=True,
                                         **common)
            figures[name] = {m: headline_figures(r) for m, r in res.items()}
        timings["shipped"] = time.perf_counter() - t
        print("\nthe shipped models on every set (headline figures; the quality guard's)")
        for name, figs in figures.items():
            for mode, sets in figs.items():
                print(f"  {name}, {mode}: " + "; ".join(f"{s} " + " ".join(f"{k} {v:.3f}" for k, v in f.items())
                                                       for s, f in sets.items()))
        new = figures["new shipped"]
        fp = fingerprint(shipped["new shipped"])
        if RECORDS.exists():
            rec = read_records(RECORDS)
            fails = guard(new, rec["figures"])
            print("\nguard against tests/quality_records.json: " + ("all figures keep their records" if not fails
                                                                    else "; ".join(fails)))
            if args.record:
                write_records(RECORDS, fp, raised_records(rec["figures"], new))
                print(f"records raised where the new model is better; fingerprint {fp[:12]}")
        elif args.record:
            write_records(RECORDS, fp, new)
            print(f"records written to {RECORDS}; fingerprint {fp[:12]}")
        out["shipped"] = figures
    total = time.perf_counter() - t0
    print("\ntimings: " + ", ".join(f"{k} {v:.0f} s" for k, v in timings.items()) + f"; total {total:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1, sort_keys=True, default=_jsonable) + "\n")
        print(f"figures written to {args.json}")


if __name__ == "__main__":
    main()
