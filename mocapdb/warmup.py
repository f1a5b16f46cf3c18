"""Compiling the numba kernels before a command needs them.

numba compiles a kernel the first time it is called with new argument types
and, with ``cache=True`` (:mod:`mocapdb._numba`), keeps the machine code in
``__pycache__`` beside the module. A cold cache makes the first ``ingest``
and ``annotate`` wait tens of seconds, so the cache is filled in two places:

- **at build time**: ``pip install .`` builds a wheel, and the build step
  (``setup.py``) runs :func:`compile_kernels` on the built package, so the
  wheel carries the cache of the machine that builds it — the user's own,
  since ``pip install .`` builds where it installs. numba accepts an entry only
  for the same numba version, Python, CPU and source bytes; anything else is
  simply compiled again, never wrong.
- **in the background**, where that cache is missing (an editable install, a
  different numba): :func:`start_background_compile` compiles on the other
  core while a first non-annotating command runs, and a command that
  annotates waits for it (:func:`wait_for_background_compile`) instead of
  compiling the same kernels twice.

:func:`compile_kernels` runs the real commands on the recordings shipped
with mocapdb (:func:`sample_files`) in a throw-away database, so every
kernel is compiled with exactly the argument types a real call has (arrays
from DuckDB and Arrow are read-only, which is a type of its own to numba).
It sits below :mod:`mocapdb.api` and makes the calls the API functions make.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from mocapdb.annotation import segment_table
from mocapdb.errors import ParameterError
from mocapdb.extension import connect as connect_database
from mocapdb.features import motion_features, relational_features
from mocapdb.readers import generic_rest, motion_files, read_motion
from mocapdb.bodies import smpl_forward_kinematics
from mocapdb.storage.annotations import annotate_documents
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.ingest import ingest_files
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.motions import motion_documents

__all__ = ["sample_files", "compile_kernels", "cache_is_cold", "start_background_compile", "background_compile_running",
           "wait_for_background_compile", "PARTS"]

_PACKAGE = Path(__file__).resolve().parent
SAMPLE_DIR = _PACKAGE / "sample"

#: what one compile process covers: reading and features; annotation with the
#: keyframe search and the SQL functions; annotation of whole documents (no
#: keyframes, the toolbox model). Two background processes share two cores.
PARTS = ("ingest", "search", "segments")


def sample_files() -> list[Path]:
    """The real recordings shipped with mocapdb (credited in the README), sorted.

    Returns
    -------
    list of Path
        Motion files (compressed); the CMU take's ASF lies beside its AMC.
    """
    return motion_files([SAMPLE_DIR])


def compile_kernels(parts=PARTS) -> float:
    """Compile (and cache) the kernels of ``parts`` by running them on the sample.

    The same calls as the commands make (:func:`mocapdb.api.ingest`,
    :func:`mocapdb.api.annotate`, the SQL functions), in a throw-away
    database.

    Parameters
    ----------
    parts : iterable of {"ingest", "search", "segments"}

    Returns
    -------
    float
        Seconds it took.

    Raises
    ------
    ParameterError
        For an unknown part.
    """
    parts = set(parts)
    unknown = parts - set(PARTS)
    if unknown:
        raise ParameterError(f"parts: unknown {sorted(unknown)}; expected some of {', '.join(PARTS)}")
    t0 = time.perf_counter()
    con = connect_database(":memory:")
    con.execute("SET enable_progress_bar = false")  # DuckDB's own bar, drawn for slow (compiling) queries
    try:
        ingest_files(con, sample_files())
        if "ingest" in parts:
            _other_rates()
            _smpl_kinematics()
        cache = connection_cache(con)
        docs = motion_documents(con)
        runs = ([(DEFAULT_MODEL, None)] if "search" in parts else []) + \
               ([(DEFAULT_MODEL, False), ("toolbox", None)] if "segments" in parts else [])
        for model, keyframes in runs:
            key, m = cache.model(model)
            segs = annotate_documents(cache, key, m, docs.words, docs.lengths, docs.motion_ids, keyframes=keyframes)
            segment_table(segs, motion_ids=docs.motion_ids, names=docs.names, fps=docs.fps)
        queries = (["SELECT annotate(motion_id) FROM motions", "SELECT * FROM keyframe_search('kickLFront1Reps')",
                    "SELECT mt_distance(motion_id, 'kickLFront1Reps') FROM motions"] if "search" in parts else []) + \
                  (["SELECT annotate(motion_id, keyframes := false) FROM motions"] if "segments" in parts else [])
        for q in queries:
            con.execute(q).fetchall()
    finally:
        con.close()
    return time.perf_counter() - t0


def _other_rates() -> None:
    """Features of a take that is not at 120 Hz (resampled to 120 Hz first, features.rates), and the 40
    relational features called directly."""
    amc = next(p for p in sample_files() if ".amc" in p.suffixes)
    m = read_motion(amc)
    m60 = type(m)(joints=np.ascontiguousarray(m.joints[::2]), root_rotation=None, fps=m.fps / 2, name=m.name,
                  skeleton=m.skeleton, source_format=m.source_format)
    motion_features(m60)
    # the public per-step API: ingest reaches the same kernels through one fused call, so they would
    # otherwise compile on a user's first direct call
    relational_features(m.joints, m.root_rotation, m.fps)


def _smpl_kinematics() -> None:
    """The forward kinematics of AMASS takes (no AMASS file ships: licence), on the rest pose."""
    smpl_forward_kinematics(generic_rest(), np.zeros((2, 22, 3)), np.zeros((2, 3)))


# -- the background compile of a cold cache -----------------------------------------

def _cache_root() -> Path:
    cache = os.environ.get("NUMBA_CACHE_DIR")
    return Path(cache) if cache else _PACKAGE


def _cache_dirs():
    """``(source folder, its numba cache folder)`` of each folder of the package: ``__pycache__`` beside
    the modules, or numba's folder for it under ``NUMBA_CACHE_DIR`` (``<name>_<sha1 of its path>``)."""
    user = os.environ.get("NUMBA_CACHE_DIR")
    for d in sorted({p.parent for p in _PACKAGE.rglob("*.py")}):
        yield d, (Path(user) / f"{d.name}_{hashlib.sha1(str(d).encode()).hexdigest()}" if user else d / "__pycache__")


def _source_stamp(py_file: Path):
    """The stamp numba gives a module's source (numba 0.68: its bytes' SHA-256; before: its mtime and size)."""
    from numba.core import caching

    locator = object.__new__(caching.InTreeCacheLocator)   # the one method needs only the file
    locator._py_file = str(py_file)
    return locator.get_source_stamp()


def _index_fresh(index: Path, stamp, version: str) -> bool:
    """Whether numba would use a cache index: written by this numba version, for the source as it is."""
    try:
        with open(index, "rb") as fh:
            if pickle.load(fh) != version:
                return False
            return pickle.loads(fh.read())[0] == stamp
    except Exception:  # noqa: BLE001 - an index numba could not read either
        return False


def cache_is_cold() -> bool:
    """True when numba holds no usable cached kernel of this package: a command compiles first.

    That is: no cache index numba would use — none at all (a first run), or
    only stale ones, written by another numba version or for other source
    bytes. numba before 0.68 stamps a source by its modification time, which
    pip does not keep, so there a whole installed wheel's cache is stale; an
    upgraded numba makes every index stale. (A source edited in a checkout
    leaves its own kernels stale beside fresh ones: those compile as they go.)
    """
    if os.environ.get("NUMBA_DISABLE_JIT") == "1":
        return False
    import numba

    for source, cache in _cache_dirs():
        by_module = {}
        for index in cache.glob("*.nbi") if cache.is_dir() else ():
            by_module.setdefault(index.name.split(".", 1)[0], []).append(index)
        for stem, indexes in by_module.items():
            py = source / f"{stem}.py"
            if not py.is_file():
                continue   # a module gone: numba never reads its leftovers
            try:
                stamp = _source_stamp(py)
            except Exception:  # noqa: BLE001 - a numba whose stamps this cannot compute: only versions count
                stamp = None
            if any(_index_fresh(i, stamp, numba.__version__) if stamp is not None else
                   _index_version(i) == numba.__version__ for i in indexes):
                return False
    return True


def _index_version(index: Path):
    try:
        with open(index, "rb") as fh:
            return pickle.load(fh)
    except Exception:  # noqa: BLE001 - unreadable: no version
        return None


#: the parts a background compile runs, one process each (two cores)
_BACKGROUND = (("search",), ("segments",))


def _lock_path(name: str) -> Path:
    root = _cache_root()
    return (root if os.environ.get("NUMBA_CACHE_DIR") else root / "__pycache__") / f"mocapdb-compile-{name}.lock"


def start_background_compile() -> bool:
    """Start compiling the annotation kernels in the background (cold cache only).

    Returns
    -------
    bool
        False when the cache is warm or a compile runs already.
    """
    if not cache_is_cold():
        return False
    started = False
    for parts in _BACKGROUND:
        lock = _lock_path("-".join(parts))
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)
            if _held(lock):
                continue
            subprocess.Popen([sys.executable, "-m", "mocapdb.warmup", "--lock", str(lock), *parts],
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)
            started = True
        except OSError:
            pass  # an unwritable cache: the commands compile as they go
    return started


def _held(lock: Path) -> bool:
    import fcntl

    if not lock.exists():
        return False
    with open(lock, "a") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(fh, fcntl.LOCK_UN)
    return False


def background_compile_running() -> bool:
    """True while a background compile holds its lock."""
    return any(_held(_lock_path("-".join(p))) for p in _BACKGROUND)


def wait_for_background_compile(timeout: float = 180.0) -> float:
    """Block while a background compile runs (it compiles what the caller needs).

    Returns
    -------
    float
        Seconds waited.
    """
    t0 = time.monotonic()
    for parts in _BACKGROUND:
        lock = _lock_path("-".join(parts))
        while _held(lock) and time.monotonic() - t0 < timeout:
            time.sleep(0.1)
    return time.monotonic() - t0


def main(argv=None) -> None:
    """``python -m mocapdb.warmup [--lock FILE] [PART …]``: compile the parts (default all)."""
    import argparse
    import fcntl

    ap = argparse.ArgumentParser(prog="python -m mocapdb.warmup", description=main.__doc__)
    ap.add_argument("--lock", type=Path, help="hold this lock while compiling; exit if another process holds it")
    ap.add_argument("parts", nargs="*", help=f"some of {', '.join(PARTS)} (default: all)")
    args = ap.parse_args(argv)
    if args.lock is None:
        compile_kernels(args.parts or PARTS)
        return
    with contextlib.suppress(OSError), open(args.lock, "a") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return  # another process compiles this part
        compile_kernels(args.parts or PARTS)


if __name__ == "__main__":
    main()
