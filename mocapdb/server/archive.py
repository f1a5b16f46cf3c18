"""The database as ``mocapdb serve`` reads it: opened read-only for each request, never held between requests.

:class:`Archive` is a :class:`mocapdb.api.reading.SharedReader`: the file is
opened read-only when a request comes and closed when the answer is ready (a
page of the archive holds it for tens of milliseconds); between requests the
file is free, so ``ingest``, ``annotate`` or ``delete`` work beside the
server. While a writer
holds it, a request waits up to :data:`BUSY_WAIT` seconds for it, then
answers "busy" (:class:`~mocapdb.storage.schema.DatabaseLockedError`, HTTP
503: the pages say so and ask again); the first request after the writer
finished sees what it wrote. A writer that starts while a request is being
answered waits for it (``mocapdb.api.connect``'s ``lock_wait``).

A request is bounded (:meth:`Archive.run`): it runs in a worker thread for
at most :data:`REQUEST_TIMEOUT` seconds, and when the time runs out or its
client hangs up, its DuckDB work is interrupted (``interrupt()`` on its
connection and every cursor of it; a query not yet started is refused), so
the file is let go of at the request's next DuckDB step instead of being
held for a request nobody waits for (a numba kernel running then finishes
its batch first). At most :data:`HEAVY_REQUESTS` heavy requests (query by example, a
motion's page, which re-reads its source) run at once; another answers
"busy" at once and the page asks again. What a request may ask is bounded
too: :data:`MAX_QUERY_S` seconds of query stretch, pages of at most
:data:`mocapdb.api.MAX_LIMIT` rows.
"""
from __future__ import annotations

import threading
import time

import duckdb

from mocapdb.api import DEFAULT_MODEL
from mocapdb.api.reading import DatabaseLockedError, Request, RequestCancelled, SharedReader
from mocapdb.errors import MocapdbError

__all__ = ["Archive", "BUSY_WAIT", "REQUEST_TIMEOUT", "HEAVY_REQUESTS", "MAX_QUERY_S", "DatabaseLockedError",
           "RequestCancelled", "Overloaded"]

#: seconds a request waits for another process's lock on the file before it answers "busy"
BUSY_WAIT = 1.0
#: seconds a request may take before its work is interrupted and it answers "busy" (find-similar on a
#: large archive takes a few seconds; the archive's pages tens of milliseconds)
REQUEST_TIMEOUT = 30.0
#: heavy requests (query by example, a motion's page) answered at once; more answer "busy" at once
#: (each keeps a core busy and a long take's poses in memory)
HEAVY_REQUESTS = 2
#: the longest query stretch of find-similar, in seconds: its work grows with the stretch times the
#: archive (the CLI's ``similar`` takes any stretch; a web request is bounded)
MAX_QUERY_S = 60.0
#: seconds between two looks at the clock and the client while a request runs
_WATCH = 0.1


class Overloaded(MocapdbError):
    """As many heavy requests as allowed are running."""


class Archive(SharedReader):
    """A database file served read-only, opened per request (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The database file; it must exist.
    model : str, keyword-only
        The model whose stored annotations the pages show.
    busy_wait : float, keyword-only
        Seconds a request waits for a writer's lock (:data:`BUSY_WAIT`).
    memory_limit : str, optional, keyword-only
        DuckDB's memory limit of each request's connection.
    timeout : float, keyword-only
        Seconds a request may take (:data:`REQUEST_TIMEOUT`).
    heavy_requests : int, keyword-only
        Heavy requests answered at once (:data:`HEAVY_REQUESTS`).
    max_query_s : float, keyword-only
        The longest query stretch of find-similar (:data:`MAX_QUERY_S`).
    """

    def __init__(self, path, *, model=DEFAULT_MODEL, busy_wait=BUSY_WAIT, memory_limit=None,
                 timeout=REQUEST_TIMEOUT, heavy_requests=HEAVY_REQUESTS, max_query_s=MAX_QUERY_S):
        super().__init__(path, wait=busy_wait, memory_limit=memory_limit)
        self.model = model
        self.timeout = float(timeout)
        self.heavy_requests = int(heavy_requests)
        self.max_query_s = float(max_query_s)
        self._heavy = threading.BoundedSemaphore(self.heavy_requests)

    async def run(self, work, *, heavy=False, disconnected=None):
        """``work(con)`` in a worker thread with a read-only connection of its own, bounded.

        Parameters
        ----------
        work : callable
            ``work(con)`` → the answer.
        heavy : bool, keyword-only
            Counts against :attr:`heavy_requests`.
        disconnected : async callable, optional, keyword-only
            True once the client has left (Starlette's ``request.is_disconnected``).

        Raises
        ------
        Overloaded
            ``heavy`` and as many heavy requests are running.
        RequestCancelled
            The time ran out (or the client left) and the work was interrupted.
        """
        # anyio comes with starlette (the serve extra): imported here, so the package imports without it and
        # mocapdb.server.serve names the missing extra
        import anyio
        import anyio.to_thread

        if heavy and not self._heavy.acquire(blocking=False):
            raise Overloaded(f"{self.heavy_requests} heavy request(s) (find similar, a motion's page) are running, "
                             "the most mocapdb serve answers at once")
        request = Request()

        def call():
            with self.reading(request) as con:
                return work(con)

        async def watch():
            deadline = time.monotonic() + self.timeout
            while True:
                await anyio.sleep(_WATCH)
                if time.monotonic() >= deadline:
                    request.cancel(f"the request took longer than {self.timeout:g} s, mocapdb serve's limit per "
                                   "request; its work was stopped")
                    return
                if disconnected is not None and await disconnected():
                    request.cancel("the client left")
                    return

        outcome = {}
        try:
            async with anyio.create_task_group() as tg:
                tg.start_soon(watch)
                try:
                    outcome["answer"] = await anyio.to_thread.run_sync(call)
                except Exception as exc:  # raised below, outside the task group (which would wrap it)
                    outcome["error"] = exc
                finally:
                    tg.cancel_scope.cancel()
        finally:
            if heavy:
                self._heavy.release()
        error = outcome.get("error")
        if error is None:
            return outcome["answer"]
        if request.reason is not None or isinstance(error, duckdb.InterruptException):
            # the interruption itself, or whatever it broke on its way out (a reader's error wrapping it)
            raise RequestCancelled(request.reason or "interrupted") from None
        raise error
