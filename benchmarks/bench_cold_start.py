"""Cold start as a new user meets it: a fresh virtual environment, ``pip install .``, the main job.

Run: ``python benchmarks/bench_cold_start.py [--no-precompiled]``. Prints figures for
benchmarks/RESULTS.md (issue 18 item 3):

(a) install: wall seconds of ``pip install .`` into a new venv (the build
    step compiles the kernels, setup.py), the size of the built wheel, of the
    shipped sample and of the numba cache it carries;
(b) the README's main job in that venv, in fresh processes: the first
    ``mocapdb ingest --sample`` and the first ``mocapdb annotate``, then both
    again (warm). Target: the first two together ≤ 10 s on 2 cores (before:
    38–53 s), warm speed unchanged;
(c) with ``--no-precompiled``, the same with ``MOCAPDB_PRECOMPILE=0`` (a wheel
    without the cache: the kernels compile on first use), for comparison.

pip's download cache is used as a user's would be (the dependencies are
fetched once); the figures are wall seconds on this machine, its load printed.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import load_now, machine_header  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def run(cmd, **kwargs):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, **kwargs)
    return time.perf_counter() - t


def wheel_figures(env, tmp):
    """Size of the wheel ``pip wheel .`` builds and of the cache and sample it carries (MB)."""
    out = Path(tmp) / "wheel"
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(out), str(REPO)], env=env)
    whl = next(out.glob("*.whl"))
    with zipfile.ZipFile(whl) as z:
        infos = z.infolist()
    cache = [i for i in infos if i.filename.endswith((".nbi", ".nbc"))]
    sample = [i for i in infos if "/sample/" in i.filename]
    mb = 1 / 2**20
    return (whl.stat().st_size * mb, sum(i.compress_size for i in cache) * mb,
            sum(i.file_size for i in cache) * mb, len(cache), sum(i.file_size for i in sample) * mb)


def main_job(precompiled: bool):
    with tempfile.TemporaryDirectory(prefix="bench_cold_") as tmp:
        env = dict(os.environ)
        env.pop("NUMBA_CACHE_DIR", None)
        env.pop("PYTHONPATH", None)
        if not precompiled:
            env["MOCAPDB_PRECOMPILE"] = "0"
        venv = Path(tmp) / "venv"
        run([sys.executable, "-m", "venv", str(venv)])
        pip = venv / "bin" / "pip"
        install = run([str(pip), "install", "--quiet", str(REPO)], env=env, cwd=tmp)
        exe = venv / "bin" / "mocapdb"
        times = []
        for db in ("first.duckdb", "second.duckdb"):
            for args in (["ingest", "--sample"], ["annotate"]):
                times.append(run([str(exe), "--db", str(Path(tmp) / db), *args], env=env, cwd=tmp))
        sizes = wheel_figures(env, tmp) if precompiled else None
    return install, times, sizes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-precompiled", action="store_true", help="also measure a build without the cache")
    args = ap.parse_args()
    machine_header("bench_cold_start")
    for precompiled in (True, False) if args.no_precompiled else (True,):
        print(f"\n## {'with' if precompiled else 'without'} the build-time cache; {load_now()}")
        install, t, sizes = main_job(precompiled)
        print(f"pip install . into a new venv: {install:.0f} s")
        print(f"first ingest --sample {t[0]:.1f} s + first annotate {t[1]:.1f} s = {t[0] + t[1]:.1f} s "
              f"(target <= 10 s; before: 38-53 s)")
        print(f"warm: ingest --sample {t[2]:.1f} s + annotate {t[3]:.1f} s = {t[2] + t[3]:.1f} s "
              f"(before: 1.2 s each)")
        if sizes:
            whl, cache_z, cache, n, sample = sizes
            print(f"wheel {whl:.1f} MB: numba cache {cache_z:.1f} MB compressed ({cache:.1f} MB, {n} files), "
                  f"sample recordings {sample:.1f} MB")
    shutil.rmtree(REPO / "build", ignore_errors=True)


if __name__ == "__main__":
    main()
