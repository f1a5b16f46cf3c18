"""Paper Fig. 5: average precision, recall and fitness over the GA generations.

Learns the keyframe queries of all 11 classes of ../shared/data/hdm05_cut (all
actors as training, T- = the other classes) with the paper's parameters
(M = 50, r = 5, G = 100, beta = 2) and plots the population averages over
all classes and runs.  Needs matplotlib (``pip install mocapdb[plot]``).

Usage: python benchmarks/plot_ga.py OUT.png [--runs N] [--seed S]
"""
import argparse
import os
from pathlib import Path

from mocapdb import ga
from mocapdb.evaluation.figures import plot_ga_statistics
from mocapdb.learning.class_templates import clips_from_folders

SHARED = Path(os.environ.get("MOCAPDB_SHARED", Path(__file__).resolve().parents[2] / "shared"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="output image (e.g. fig5.png)")
    ap.add_argument("--runs", type=int, default=20, help="GA runs per class (default 20)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    clips = clips_from_folders(SHARED / "data" / "hdm05_cut")
    res = ga.learn_keyframe_queries(clips, runs=args.runs, random_state=args.seed)
    st = ga.average_statistics(res.values())
    plot_ga_statistics(st, args.out, title=f"GA on hdm05_cut: {len(res)} classes x "
                                            f"{args.runs} runs")
    print(f"wrote {args.out}: generation 0 precision {st.mean_precision[0]:.3f} recall "
          f"{st.mean_recall[0]:.3f} fitness {st.mean_fitness[0]:.3f}; generation "
          f"{st.generations} precision {st.mean_precision[-1]:.3f} recall "
          f"{st.mean_recall[-1]:.3f} fitness {st.mean_fitness[-1]:.3f}")


if __name__ == "__main__":
    main()
