"""Compiling the kernels ahead of need (issue 18 item 3, cold start).

``pip install .`` runs :func:`mocapdb.warmup.compile_kernels` at build time;
where that cache is missing, a first ``ingest`` starts the annotation parts
in the background. Either way, what they compile must be exactly what the
main job needs: after them, ``ingest --sample`` and ``annotate`` compile
nothing.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mocapdb.warmup import PARTS, compile_kernels, sample_files


def _cached(cache: Path) -> set:
    return {p.name for p in cache.rglob("*.nbc")}


def _env(cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    env.pop("NUMBA_DISABLE_JIT", None)
    return env


def _seed_from_the_build(cache: Path) -> int:
    """Copy the kernels that ``pip install .`` compiled (the wheel's own cache files, listed in its RECORD,
    not what tests compiled since) into ``cache`` where numba looks for them under NUMBA_CACHE_DIR.

    The build ran the same compile parts, so the parts below then load instead of compiling (71 s
    saved); whatever they or the main job still compile is a kernel the build missed, which the test
    catches all the same. An editable install has no build step: nothing to copy, the parts compile."""
    import importlib.metadata

    from numba.core.caching import _CacheLocator

    dist = importlib.metadata.distribution("mocapdb")
    copied = 0
    for f in dist.files or ():
        if str(f).endswith((".nbi", ".nbc")):
            source = Path(str(dist.locate_file(f)))  # <module dir>/__pycache__/<kernel>.nbi
            module_dir = source.parent.parent
            target = cache / _CacheLocator.get_suitable_cache_subpath(str(module_dir / "x.py"))
            target.mkdir(parents=True, exist_ok=True)
            (target / source.name).write_bytes(source.read_bytes())
            copied += 1
    return copied


@pytest.mark.slow
def test_the_compile_parts_cover_the_main_job(tmp_path):
    cache = tmp_path / "numba"
    cache.mkdir()
    _seed_from_the_build(cache)
    env = _env(cache)
    exe = [sys.executable, "-P", "-m"]
    # as the build step runs them: reading first, then the two annotation halves side by side
    assert subprocess.run(exe + ["mocapdb.warmup", "ingest"], env=env, timeout=900).returncode == 0
    warm = [subprocess.Popen(exe + ["mocapdb.warmup", part], env=env) for part in ("search", "segments")]
    assert [p.wait(timeout=900) for p in warm] == [0, 0]
    warmed = _cached(cache)
    for module in ("relational.", "search_kernels.", "chain_kernels.", "distance.", "textscan.", "bvh."):
        assert any(n.startswith(module) for n in warmed), module
    db = str(tmp_path / "demo.duckdb")
    for args in (["ingest", "--sample"], ["annotate"]):
        r = subprocess.run(exe + ["mocapdb.cli", "--db", db, *args], env=env, capture_output=True, text=True,
                           timeout=900)
        assert r.returncode == 0, r.stderr
        assert "Compiling" not in r.stderr and "Waiting" not in r.stderr
    assert "86_09" in r.stdout and "HDM_mm_01-02_03_120" in r.stdout
    assert _cached(cache) == warmed, "the main job compiled kernels the compile parts missed"


def test_the_sample_ships_with_the_package():
    names = sorted(p.name for p in sample_files())
    assert names == ["86_09.amc.xz", "HDM_mm_01-02_03_120.c3d.xz", "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh.xz"]
    total = sum(p.stat().st_size for p in sample_files()[0].parent.iterdir())
    assert total < 2.5 * 2**20  # about 2 MB in all
    # the credits and licence notices travel with the files (MIT asks for its notice in copies)
    credits = (sample_files()[0].parent / "CREDITS.txt").read_text(encoding="utf-8")
    assert all(n.split(".")[0] in credits for n in names) and "Permission is hereby granted" in credits


def test_unknown_parts_are_refused():
    from mocapdb.errors import ParameterError

    assert set(PARTS) == {"ingest", "search", "segments"}
    with pytest.raises(ParameterError, match="unknown \\['linking'\\]"):
        compile_kernels(["linking"])


def test_the_installed_package_carries_the_compiled_kernels():
    """pip install . compiles the kernels at build time (setup.py): the installed package has
    numba's cache beside its modules, valid here, so the main job compiles nothing."""
    import importlib.metadata
    import json

    dist = importlib.metadata.distribution("mocapdb")
    direct = dist.read_text("direct_url.json")
    if direct and json.loads(direct).get("dir_info", {}).get("editable"):
        pytest.skip("an editable install has no build step: its kernels compile on first use")
    # the wheel's own files (its RECORD), not what earlier tests compiled since
    cached = {Path(str(f)).name.split("-")[0] for f in dist.files or () if str(f).endswith(".nbi")}
    for kernel in ("relational._upper_kernel", "distance._mt_distance_kernel", "chain_kernels._segments_kernel",
                   "search_kernels._search_kernel", "textscan._parse_rows_kernel"):
        assert kernel in cached, f"{kernel} is not in the installed package's numba cache"
    env = dict(os.environ, NUMBA_DEBUG_CACHE="1")
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("NUMBA_DISABLE_JIT", None)
    code = ("import mocapdb.warmup as w; w.compile_kernels(['ingest', 'search', 'segments'])")
    r = subprocess.run([sys.executable, "-P", "-c", code], env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    assert "data saved to" not in r.stdout, "the main job's calls compiled kernels the build did not cache"


@pytest.mark.slow
def test_a_stale_cache_is_cold_and_the_first_command_says_it_compiles(tmp_path, monkeypatch):
    """Issue 27 item 9: any cache index counted as a warm cache, but numba uses one only if this numba
    version wrote it for the source as it is (numba before 0.68 stamps a source by its mtime, which pip
    does not keep: a wheel's cache was stale there), so a first run compiled for 40 s without a word."""
    import pickle

    import numba

    from conftest import run
    from mocapdb import warmup

    cache = tmp_path / "numba"
    env = _env(cache)
    # a real index: one kernel compiled into a cache of its own
    code = "import numpy as np; from mocapdb.features import hysteresis; hysteresis(np.ones(3, bool), np.ones(3, bool))"
    assert subprocess.run([sys.executable, "-P", "-c", code], env=env, timeout=300).returncode == 0
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    monkeypatch.delenv("NUMBA_DISABLE_JIT", raising=False)
    [index] = [i for i in cache.rglob("relational._hysteresis_kernel-*.nbi")]
    assert not warmup.cache_is_cold()
    with open(index, "rb") as fh:
        version, (stamp, overloads) = pickle.load(fh), pickle.loads(fh.read())
    fresh = index.read_bytes()
    source = Path(warmup.__file__).parent / "features" / "relational.py"

    def write(version, stamp):
        with open(index, "wb") as fh:
            pickle.dump(version, fh)
            fh.write(pickle.dumps((stamp, overloads)))

    db = tmp_path / "q.duckdb"
    run(db, "ingest", "--sample", "--silent")
    st = source.stat()
    for stale in ((version, (st.st_mtime + 1.0, st.st_size)),   # as numba < 0.68 stamps a file pip rewrote
                  ("0.59.1", stamp)):                             # another numba's
        write(*stale)
        assert warmup.cache_is_cold(), stale
        r = run(db, "sql", "SELECT count(*) AS n FROM motions", "--format", "csv")
        assert "Compiling the numba kernels: this install has no usable compiled cache" in r.output
        assert "n\n3\n" in r.output   # the query's own output, unchanged
    index.write_bytes(fresh)
    # a leftover of a kernel since moved, beside its fresh index, is no cold cache
    (index.parent / index.name.replace("-", "-9", 1)).write_bytes(fresh.replace(pickle.dumps(version), pickle.dumps("0.1")))
    assert not warmup.cache_is_cold()
    assert "Compiling" not in run(db, "sql", "SELECT 1 AS one", "--format", "csv").output
