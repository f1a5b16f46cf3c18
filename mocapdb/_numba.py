"""Numba options for every kernel of the package, set in one place.

``cache=True`` is deliberate: the CLI and the SQL functions start in fresh
processes, and a cold compile of the feature kernels costs seconds.
``nogil=True`` lets a thread pool run kernels side by side (DuckDB calls a
Python UDF from one thread; parallelism happens inside).
"""
import numba

#: Serial kernel: compiled once, cached on disk, releases the GIL.
jit = numba.njit(cache=True, nogil=True, error_model="numpy")

#: Parallel kernel: as :data:`jit`, with ``prange`` loops over independent
#: takes, templates or chunks (each iteration writes only its own slice).
pjit = numba.njit(cache=True, nogil=True, parallel=True, error_model="numpy")

#: Small helper inlined into its callers at numba's IR level (the number
#: scanner: a call per token would cost a third of a reader's time).
inline_jit = numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")

prange = numba.prange


def limit_threads(n: int) -> None:
    """Let the parallel kernels of the calling thread use at most ``n`` threads.

    Numba keeps this setting per thread, so a worker calls it in the thread
    that runs the kernels (e.g. a Ray actor with one CPU: 1).
    """
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


__all__ = ["jit", "pjit", "inline_jit", "prange", "limit_threads"]
