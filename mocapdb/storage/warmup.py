"""Compile the annotation kernels ahead of need, on the idle core (issue 8, cold start).

A new install has an empty numba cache: the first ``mocapdb ingest``
compiles the reader and feature kernels (~6 s), the first ``mocapdb
annotate`` the index, keyframe-search, Δ and segment kernels (~12 s), one
after the other on one core. When the CLI finds the cache empty it starts
``python -m mocapdb.storage.warmup`` in the background, which compiles the
annotation side on the other core while the command goes on; a later command
that annotates waits for it (:func:`wait_for_warmup`) instead of compiling
the same kernels a second time. The warm-up annotates a synthetic motion
through the same code path and dtypes as a stored motion
(:func:`mocapdb.storage.annotations.annotate_documents` over postings loaded
from DuckDB), so its cache entries are the ones the real call looks up.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from mocapdb.storage.annotations import annotate_documents
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.models import DEFAULT_MODEL
from mocapdb.storage.ingest import store_words
from mocapdb.storage.motions import motion_documents
from mocapdb.storage.postings import drop_index, index_version
from mocapdb.storage.schema import open_database

__all__ = ["warm_annotation_kernels", "start_warmup", "wait_for_warmup", "warmup_running", "cache_is_cold", "PARTS"]

_PACKAGE = Path(__file__).resolve().parents[1]


def _cache_root() -> Path:
    cache = os.environ.get("NUMBA_CACHE_DIR")
    return Path(cache) if cache else _PACKAGE


def cache_is_cold() -> bool:
    """True when numba has cached no kernel of this package yet (a first run)."""
    if os.environ.get("NUMBA_DISABLE_JIT") == "1":
        return False
    root = _cache_root()
    pattern = "**/*.nbi" if os.environ.get("NUMBA_CACHE_DIR") else "*/__pycache__/*.nbi"
    return not any(root.glob(pattern))


#: what each background process compiles: the keyframe search over the stored
#: index, and Δ with the segment kernels (two processes: two cores)
PARTS = ("search", "segments")


def _lock_path(part: str) -> Path:
    root = _cache_root()
    return (root if os.environ.get("NUMBA_CACHE_DIR") else root / "__pycache__") / f"mocapdb-warmup-{part}.lock"


def warm_annotation_kernels(part: str = "search", model: str = DEFAULT_MODEL) -> None:
    """Compile (and cache) one part of the annotation kernels on a synthetic stored motion.

    ``"search"``: the stored index loaded, the model's keyframe queries
    searched and Δ on the preselected slices; ``"segments"``: Δ on whole
    documents and the segment kernels. Both compile Δ; together they cover
    annotation with and without keyframes.
    """
    con = open_database(":memory:")
    try:
        if part == "segments":
            drop_index(con)  # nothing of the search side compiles here
        cache = connection_cache(con)
        key, m = cache.model(model)
        # a motion that performs every class (each template's columns, each twice,
        # with random bits outside its masks), so that every path of the chain
        # runs: hits, several labels, segments
        rng = np.random.default_rng(0)
        parts = []
        for c in m.classes:
            q = c.quantized
            noise = rng.integers(0, 1 << 40, size=q.value.size, dtype=np.uint64) & ~q.mask
            parts.append(np.repeat(q.value | noise, 2))
        (mid,) = store_words(con, {"warmup": np.concatenate(parts)})
        docs = motion_documents(con, [mid])
        # "search": the stored index, the keyframe search and Δ on the preselected
        # slices; "segments": Δ on whole documents and the segment kernels
        annotate_documents(cache, key, m, docs.words, docs.lengths, docs.motion_ids, keyframes=part == "search",
                           index_version=index_version(con))
    finally:
        con.close()


def start_warmup() -> bool:
    """Start the background warm-up once (first run only); False if running already or not needed."""
    if not cache_is_cold():
        return False
    started = False
    for part in PARTS:
        lock = _lock_path(part)
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)
            if _held(lock):
                continue
            subprocess.Popen([sys.executable, "-m", "mocapdb.storage.warmup", part], stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
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


def warmup_running() -> bool:
    """Whether a background warm-up is compiling (a caller that waits for it can say so)."""
    return any(_lock_path(part).exists() and _held(_lock_path(part)) for part in PARTS)


def wait_for_warmup(timeout: float = 120.0) -> None:
    """Block while a background warm-up holds a lock (it compiles what the caller needs)."""
    import time

    deadline = time.monotonic() + timeout
    for part in PARTS:
        lock = _lock_path(part)
        while lock.exists() and _held(lock) and time.monotonic() < deadline:
            time.sleep(0.1)


def main(argv=None) -> None:
    """``python -m mocapdb.storage.warmup PART``: compile one part, holding its lock meanwhile."""
    import fcntl

    part = (argv if argv is not None else sys.argv[1:] or ["search"])[0]
    if part not in PARTS:
        raise SystemExit(f"usage: python -m mocapdb.storage.warmup [{'|'.join(PARTS)}]")
    with contextlib.suppress(OSError), open(_lock_path(part), "a") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return  # another warm-up of this part runs
        warm_annotation_kernels(part)


if __name__ == "__main__":
    main()
