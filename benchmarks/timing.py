"""Timing helper shared by the benchmark scripts (run as ``python benchmarks/<script>.py``)."""
import time


def best_of(fn, repeat=3):
    """Best wall time of ``repeat`` calls of ``fn`` (the machine is shared: the minimum is
    the least disturbed run) and the result of the last call: ``(seconds, result)``."""
    times, res = [], None
    for _ in range(max(1, repeat)):
        t = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t)
    return min(times), res


def best_seconds(fn, repeat=3):
    """Best wall time of ``repeat`` calls of ``fn``, in seconds."""
    return best_of(fn, repeat)[0]
