"""Speed of the Δ kernel, of the annotation chain and of template learning.

Prints figures for benchmarks/RESULTS.md (DESIGN.md §7 targets: ≥ 300,000
frames/s for a 15-class-sized model, ≥ 10× librosa including the cost,
≤ 0.2 s learning per class of 20 clips).

Data: every 30 Hz feature file of the toolbox oracle (../shared/oracle/features),
as documents, repeated to about 1,000,000 frames; the 11 oracle templates, and a
15-class-sized model (the 11 plus the first 4 again).

Usage: python benchmarks/bench_dtw.py [--frames N] [--librosa-frames N]
"""
import argparse
import os
import platform
import time
from pathlib import Path

import numba
import numpy as np

from mocapdb.annotation import annotate
from mocapdb.features import pack_words
from mocapdb.annotation.model import ClassModel, Model
from mocapdb.templates import ANNOTATION_STEPS, cost_table, mt_distance
from mocapdb.templates import QuantizedTemplate, learn_template

from timing import best_of  # benchmarks/timing.py

SHARED = Path(os.environ.get("MOCAPDB_SHARED", Path(__file__).resolve().parents[2] / "shared"))
ORACLE = SHARED / "oracle"


def load_feat30(stem):
    x = np.loadtxt(ORACLE / "features" / f"{stem}_feat30.csv", delimiter=",", skiprows=1,
                   ndmin=2)
    return x.astype(bool)


def load_templates():
    out = []
    for d in sorted((ORACLE / "templates").iterdir()):
        q = QuantizedTemplate.from_dense(
            np.loadtxt(d / "template_quantized_0.05.csv", delimiter=",", ndmin=2).T,
            np.loadtxt(d / "template_quantized_weights.csv", delimiter=",", ndmin=1))
        out.append((d.name, q))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--librosa-frames", type=int, default=100_000)
    args = ap.parse_args()

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"numba {numba.__version__}, {numba.get_num_threads()} threads")
    stems = sorted(p.name[:-len("_feat30.csv")]
                   for p in (ORACLE / "features").glob("*_feat30.csv"))
    docs = [pack_words(load_feat30(s)) for s in stems]
    base = sum(len(d) for d in docs)
    reps = max(1, -(-args.frames // base))
    docs = docs * reps
    words = np.concatenate(docs)
    lens = np.array([len(d) for d in docs])
    print(f"documents: {len(docs)} ({len(stems)} oracle files x {reps}), {len(words):,} frames "
          f"at 30 Hz ({len(words) / 30 / 60:.0f} min)")

    templates = load_templates()
    models = {"11-class": [q for _, q in templates],
              "15-class-sized": [q for _, q in templates] + [q for _, q in templates[:4]]}
    mt_distance(words[:5000], models["15-class-sized"], doc_lengths=[5000], return_starts=True)

    print("\n== Δ kernel (mt_distance, toolbox rule, cost included) ==")
    for name, qs in models.items():
        cells = sum(len(q) for q in qs) * len(words)
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            for starts in (False, True):
                t, _ = best_of(lambda: mt_distance(words, qs, doc_lengths=lens,
                                                   return_starts=starts))
                print(f"{name:15s} ΣK={sum(len(q) for q in qs):4d} threads={threads} "
                      f"starts={starts!s:5s}: {t:6.3f} s  {cells / t / 1e6:6.0f} M cells/s  "
                      f"{len(words) / t:10,.0f} frames/s")
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

    print("\n== whole annotation chain (annotate, no keyframes) ==")
    label_of = lambda n: n[:6]  # noqa: E731 - distinct labels are enough for timing
    for name, n_cls in (("11-class", 11), ("15-class-sized", 15)):
        classes = [ClassModel(f"{templates[k % 11][0]}_{k}", label_of(templates[k % 11][0]),
                              quantized=templates[k % 11][1], tau=0.13) for k in range(n_cls)]
        model = Model(name, classes)
        t, res = best_of(lambda: annotate(words, model, doc_lengths=lens, match_num_max=None),
                         repeat=2)
        print(f"{name:15s}: {t:6.3f} s  {len(words) / t:10,.0f} frames/s  "
              f"({len(res.segments)} segments, {len(res.hits)} hits)")

    print("\n== vs librosa.sequence.dtw(C=..., subseq=True), textbook rule, cost included ==")
    try:
        import librosa
    except ImportError:
        print("librosa not importable: skipped")
        librosa = None
    if librosa is not None:
        n = min(args.librosa_frames, len(words))
        w = words[:n]
        qs = models["11-class"]
        sigma = np.array([[s[0], s[1]] for s in ANNOTATION_STEPS])
        wmul = np.array([s[2] for s in ANNOTATION_STEPS])

        def run_librosa():
            out = []
            for q in qs:
                tab = cost_table(q)
                pc = np.bitwise_count((q.value[:, None] ^ w[None, :]) & q.mask[:, None])
                C = tab[np.arange(len(q))[:, None], pc]
                D = librosa.sequence.dtw(C=C, subseq=True, step_sizes_sigma=sigma,
                                         weights_mul=wmul, backtrack=False)
                out.append(D[-1])
            return np.array(out)

        run_librosa() if n <= 20000 else None
        t_lib, ref = best_of(run_librosa, repeat=1)
        cells = sum(len(q) for q in qs) * n
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            t_ours, ours = best_of(lambda: mt_distance(w, qs, rule="textbook"))
            assert np.array_equal(ours, ref), "textbook Δ differs from librosa"
            print(f"{n:,} frames x 11 templates: librosa {t_lib:.3f} s "
                  f"({cells / t_lib / 1e6:.0f} M cells/s); ours threads={threads} "
                  f"{t_ours:.4f} s ({cells / t_ours / 1e6:.0f} M cells/s): "
                  f"{t_lib / t_ours:.1f}x, identical Δ")
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

    print("\n== template learning (learn_template, toolbox order of training clips) ==")
    total = 0.0
    clips_total = 0
    for name, _ in templates:
        stems_c = (ORACLE / "templates" / name / "training_clips.txt").read_text().split()
        clips = [load_feat30(s) for s in stems_c]
        learn_template(clips[:2], iter_max=1)  # compiled
        t, mt = best_of(lambda: learn_template(clips), repeat=2)
        total += t
        clips_total += len(clips)
        print(f"{name:30s} {len(clips):3d} clips K={len(mt):4d} iters={mt.iterations:2d}: "
              f"{t:6.3f} s ({t / len(clips) * 20:.3f} s per 20 clips)")
    print(f"all 11 classes: {total:.2f} s, mean {total / 11:.3f} s per class, "
          f"{total / clips_total * 20:.3f} s per 20 clips")


if __name__ == "__main__":
    main()
