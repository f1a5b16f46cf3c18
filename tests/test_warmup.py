"""The background warm-up of a first run (issue 8, cold start): what it compiles is
exactly what the first ``mocapdb annotate`` needs, so that command compiles nothing."""
import os
import subprocess
import sys
from pathlib import Path

from conftest import DATA


def _cached(cache: Path) -> set:
    return {p.name for p in cache.rglob("*.nbc")}


def test_the_warmup_compiles_what_annotate_needs(tmp_path):
    cache = tmp_path / "numba"
    cache.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    env.pop("NUMBA_DISABLE_JIT", None)
    exe = [sys.executable, "-P", "-m"]
    warm = [subprocess.Popen(exe + ["mocapdb.storage.warmup", part], env=env) for part in ("search", "segments")]
    assert [p.wait(timeout=600) for p in warm] == [0, 0]
    warmed = _cached(cache)
    assert any(n.startswith("search_kernels.") for n in warmed) and any(n.startswith("chain_kernels.") for n in warmed)
    db = str(tmp_path / "demo.duckdb")
    r = subprocess.run(exe + ["mocapdb.cli", "--db", db, "ingest", str(DATA / "cmu/86/86_09.amc")], env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    before = _cached(cache)
    r = subprocess.run(exe + ["mocapdb.cli", "--db", db, "annotate"], env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0 and "86_09" in r.stdout, r.stderr
    assert _cached(cache) - before == set(), "annotate compiled kernels the warm-up missed"
    # the cache is warm now: no message, no new warm-up
    assert "Compiling" not in r.stderr
