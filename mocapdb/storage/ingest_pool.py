"""Where ingest's per-file work runs: worker processes on both cores for an archive, threads otherwise.

Reading a take is a few numba kernels wrapped in per-file Python (paths,
headers, the skeleton lookup, the ``Motion``) — about half of a short take's
CPU — and that Python holds the GIL, so threads run it one at a time. Worker
processes run all of it side by side; the parent only decides what to store
and stores it (benchmarks/RESULTS.md, issue 35).

The workers are plain subprocesses (``python -m mocapdb.storage.ingest_worker``, :func:`serve`)
fed pickled tasks over a pipe, one per thread of a thread pool — not
``multiprocessing``, whose spawn and fork-server children re-run the caller's
main script (a user's script without a ``__main__`` guard would run again in
every worker) and whose fork would copy DuckDB's threads. A worker that dies
(a crash in a native library on one file) costs that file only: its task
comes back as :class:`WorkerDied`, and the thread starts a new worker.

A process costs about 1.5 CPU-s to start (imports, numba's cached kernels),
and on a machine whose cores are all busy it gets no more CPU than a thread,
so small ingests and busy machines stay on threads (:func:`use_processes`). Results come
back in the order of the inputs with at most ``window`` tasks in flight, so
memory is bounded by the window, not by the archive.
"""
from __future__ import annotations

import itertools
import os
import pickle
import signal
import subprocess
import sys
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

#: files whose bytes add up to less than this are read on threads: a worker costs ~1.5 CPU-s to start
#: (importing the readers and features, loading numba's cached kernels), which two free cores repay after about 6
#: CPU-s of work (~0.6 M frames, ~450 MB of AMC text)
PROCESS_MIN_BYTES = 512 << 20
#: the folder holding the mocapdb package that runs here
_PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: tasks in flight per worker: enough to keep a worker busy while the parent stores
_WINDOW_PER_WORKER = 4
#: files per task sent to a worker process
_CHUNK = 16


class WorkerDied:
    """The result of a task whose worker process died while running it."""

    def __init__(self, reason: str):
        self.reason = reason

    def __str__(self):
        return self.reason


def use_processes(n_files: int, n_bytes: int, workers: int) -> bool:
    """Whether a run of ``n_files`` files of ``n_bytes`` in all is worth worker processes: enough work,
    and a core free for a second worker (on a machine whose cores are busy the workers get no more CPU
    than threads do and only add their start; measured: 1.5× the CPU seconds, slower; RESULTS.md)."""
    if workers < 2 or n_files < 2 * workers or n_bytes < PROCESS_MIN_BYTES:
        return False
    return _idle_cores() >= 1.0


def _idle_cores() -> float:
    """Cores the last minute left idle (cores − the load average)."""
    try:
        return (os.cpu_count() or 1) - os.getloadavg()[0]
    except (OSError, AttributeError):   # no load average (not a Unix): assume the cores are busy
        return 0.0


#: bytes of freed memory a worker process keeps for its next files instead of returning them to the system
_KEEP_FREED = 64 << 20


class _Worker:
    """One worker process: ``call(fn, arg)`` runs ``fn(arg)`` there (``fn`` a module-level function)."""

    def __init__(self):
        env = dict(os.environ, NUMBA_NUM_THREADS="1")   # the parallelism is the workers themselves
        # glibc hands a freed block of over 128 KiB back to the system at once, so every take's bytes and
        # arrays (a few hundred KiB each) were fresh pages faulted in and zeroed again, file after file: keeping
        # up to _KEEP_FREED per worker saves 7-10 % of a worker's CPU on BVH (RESULTS.md, issue 35). Other C
        # libraries ignore these variables; a caller's own setting wins.
        for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"):
            env.setdefault(name, str(_KEEP_FREED))
        # the worker imports this very mocapdb, however the caller found it (an install, a checkout on sys.path)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [_PACKAGE_ROOT, env.get("PYTHONPATH")]))
        # -P: `-m` would put the working directory first on sys.path, and a checkout there (or any folder
        # named mocapdb) would shadow the package that runs here
        self.proc = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.storage.ingest_worker"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)

    def call(self, fn, arg):
        try:
            pickle.dump((fn, arg), self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.proc.stdin.flush()
            return pickle.load(self.proc.stdout)
        except (EOFError, OSError, pickle.UnpicklingError):
            code = self.proc.wait()
            how = f"signal {-code}" if code < 0 else f"exit status {code}"
            return WorkerDied(f"the worker process reading it died ({how}); please report it")

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def close(self):
        # end of input ends the worker; its exit (interpreter teardown) is not waited for here
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        threading.Thread(target=self.proc.wait, daemon=True).start()

    def cancel(self):
        """End a worker that was never used (still importing, most likely): no need to wait for its start."""
        self.proc.kill()
        self.close()


class _ProcessPool:
    """``submit(fn, arg)`` as a thread pool's, each thread handing its tasks to a worker process of its own.

    The workers start at once (those of ``started``, a :func:`head_start`'s list, are taken from it):
    their imports overlap the parent's look at the database. ``setup`` ``(fn, arg)`` runs in each worker
    before its first task (also in one started after a worker died)."""

    def __init__(self, workers: int, setup=None, started=None):
        self._setup = setup
        taken = [started.pop() for _ in range(min(workers, len(started or ())))]
        self._idle = deque(taken + [_Worker() for _ in range(workers - len(taken))])
        self._workers = list(self._idle)
        self._threads = ThreadPoolExecutor(max_workers=workers)
        self._local = threading.local()
        self._lock = threading.Lock()

    def _run(self, fn, arg):
        w = getattr(self._local, "worker", None)
        if w is None or not w.alive:
            with self._lock:
                w = self._idle.popleft() if self._idle else None
            if w is None or not w.alive:   # a worker died on a file: a new one for the next
                w = _Worker()
                with self._lock:
                    self._workers.append(w)
            self._local.worker = w
            if self._setup is not None:
                done = w.call(*self._setup)
                if isinstance(done, WorkerDied):
                    return done
        return w.call(fn, arg)

    def submit(self, fn, arg):
        return self._threads.submit(self._run, fn, arg)

    def shutdown(self):
        self._threads.shutdown(wait=True, cancel_futures=True)
        for w in self._workers:
            w.close()


@contextmanager
def head_start(workers: int, folders: bool):
    """``with head_start(workers, folders) as started:`` — one worker process started before the caller
    walks its folders, when a pool of processes is likely (``workers`` ≥ 2, folders to walk, a core free):
    the walk (~55 µs a file: 0.65 s for 11,856 files) holds one core and the worker's start (~0.9 CPU-s)
    takes the other. :func:`executor` takes it from ``started``; one not taken is ended on leaving."""
    started = []
    if workers >= 2 and folders and _idle_cores() >= 1.0:
        started.append(_Worker())
    try:
        yield started
    finally:
        for w in started:
            w.cancel()


@contextmanager
def executor(workers: int, processes: bool, setup=None, started=None):
    """A pool of ``workers`` worker processes, or of threads; ``submit(fn, arg)`` returns a future.

    ``setup`` ``(fn, arg)``: ``fn(arg)`` runs once in each worker process before its first task, or
    once here for threads (what the tasks share, sent to a process once rather than with every task).
    ``started``: worker processes started already (:func:`head_start`), used by a pool of processes."""
    workers = max(1, int(workers))
    if not processes:
        if setup is not None:
            setup[0](setup[1])
        with ThreadPoolExecutor(max_workers=workers) as pool:
            yield pool
        return
    pool = _ProcessPool(workers, setup, started)
    try:
        yield pool
    finally:
        pool.shutdown()


def ordered(pool, fn, items, *, window: int, chunk: int = 1):
    """``fn(item)`` for every item, yielded in order, at most ``window`` tasks submitted ahead of the consumer.

    A task is ``chunk`` items: a worker process then wakes once per chunk, not per file (on a loaded
    machine each wake-up waits for a time slice, which cost more than reading a short take)."""
    pending = deque()
    it = iter(items)

    def submit():
        part = list(itertools.islice(it, chunk))
        if part:
            pending.append((part, pool.submit(apply_all, (fn, part))))
        return bool(part)

    while len(pending) < window and submit():
        pass
    while pending:
        part, future = pending.popleft()
        results = future.result()
        submit()
        if isinstance(results, WorkerDied):
            # one file took its worker down: the chunk's files again, one task each, so only it fails
            results = [results] if len(part) == 1 else [
                r if isinstance(r, WorkerDied) else r[0]
                for r in (pool.submit(apply_all, (fn, [x])).result() for x in part)]
        yield from results


def apply_all(task):
    """``[fn(x) for x in items]`` of a task ``(fn, items)``: what a worker runs."""
    fn, items = task
    return [fn(x) for x in items]


def chunk_for(processes: bool) -> int:
    """Files per task: one on threads, several for a worker process."""
    return _CHUNK if processes else 1


def window_for(workers: int) -> int:
    """Tasks in flight for ``workers`` workers (what :func:`ordered` may hold beyond the consumer)."""
    return max(1, int(workers)) * _WINDOW_PER_WORKER


def serve() -> None:
    """A worker's loop: pickled ``(fn, arg)`` in on stdin, pickled ``fn(arg)`` out on stdout, until stdin ends."""
    inp, out = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr   # whatever a library prints must not land in the result stream
    # Ctrl-C reaches the whole process group: the parent handles it (and ends its workers), no traceback here
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            fn, arg = pickle.load(inp)
        except EOFError:
            return
        try:
            result = fn(arg)
        except Exception as exc:  # noqa: BLE001 - a bug costs its task (its files, reported), not the worker
            result = WorkerDied(f"internal error while reading it ({type(exc).__name__}: {exc}); please report it")
        try:
            pickle.dump(result, out, protocol=pickle.HIGHEST_PROTOCOL)
            out.flush()
        except OSError:   # the parent is gone (killed mid-ingest): nothing to answer, no traceback
            return


__all__ = ["PROCESS_MIN_BYTES", "WorkerDied", "use_processes", "head_start", "executor", "ordered", "window_for", "chunk_for",
           "apply_all", "serve"]
