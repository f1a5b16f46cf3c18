"""``mocapdb serve``: the archive in a browser — search, filter, a summary, motion pages, find similar.

The ``serve`` extra (``pip install "mocapdb[serve]"``) brings the web stack:
Starlette (routes, responses) and uvicorn (the HTTP server).
:mod:`~mocapdb.server.archive` reads the database read-only, one connection
per request, so a writer can use the file between requests, and bounds each
request (time, heavy requests at once, the query stretch);
:mod:`~mocapdb.server.app` holds the routes and the JSON API under ``/api/``;
:mod:`~mocapdb.server.pages` the HTML (the archive page and the summary,
and each motion's viewer page of :mod:`mocapdb.viewer` with a panel under
it). The server is a face on :mod:`mocapdb.api`, as the command line is:
every route is an API function (``api.motions``, ``api.motion_info``,
``api.label_segments``, ``api.similar``, ``api.stats``) with the command
line's arguments and fields. :func:`serve` is the public entry point: the
CLI's ``mocapdb serve`` calls it, as the server sits above :mod:`mocapdb.api`
(nothing under the API imports the server; issue 34).
"""
from __future__ import annotations

import logging
import socket

from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.server.archive import BUSY_WAIT, REQUEST_TIMEOUT, Archive
from mocapdb.api import DEFAULT_MODEL

__all__ = ["Archive", "BUSY_WAIT", "REQUEST_TIMEOUT", "serve", "bind"]

log = logging.getLogger("mocapdb")


def bind(host, port):
    """A listening TCP socket on ``host:port`` (port 0: any free port).

    Raises
    ------
    ParameterError
        The address cannot be bound (the port is taken, the host is not this machine's).
    """
    try:
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
    except socket.gaierror as exc:
        raise ParameterError(f"host {host!r} is not an address of this machine ({exc.strerror})") from None
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise ParameterError(f"cannot listen on {host}:{port} ({exc.strerror}); choose another with --port "
                             "(--port 0 takes any free one)") from None
    return sock


def serve(path, *, host="127.0.0.1", port=8765, model=DEFAULT_MODEL, busy_wait=BUSY_WAIT, timeout=REQUEST_TIMEOUT,
          ready=None):
    """Serve the archive at ``path`` to a web browser until interrupted (Ctrl-C; ``mocapdb serve``).

    Pages: ``/`` every motion with name, format, rate, duration, stored labels
    and a strip of its label timeline, filtered by label, format, name and
    duration, sorted and paged; ``/stats`` the summary of
    :func:`mocapdb.api.stats` with bars; ``/motion/<id>`` the viewer page of
    :func:`mocapdb.api.view` with "find similar" (:func:`mocapdb.api.similar`
    on a stretch selected on the timeline) and every segment of a label across
    the archive. The JSON API the pages use is under ``/api/``
    (:mod:`mocapdb.server.app`).

    The server never writes: it opens the file read-only for each request and
    closes it after, so ``ingest``, ``annotate`` and the other writers can
    work beside it; while one holds the file, requests answer "busy" and the
    pages ask again (:mod:`mocapdb.server.archive`).

    Parameters
    ----------
    path : str or Path
        The database file (it must exist).
    host : str, keyword-only, default "127.0.0.1"
        The address to bind: this machine only, unless given otherwise. On
        ``0.0.0.0`` or ``::`` the server warns that the archive is open to the
        network.
    port : int, keyword-only, default 8765
        0 takes any free port.
    model : str, keyword-only
        The model whose stored annotations the pages show.
    busy_wait : float, keyword-only
        Seconds a request waits for another process's lock before it answers
        "busy" (:data:`~mocapdb.server.archive.BUSY_WAIT`).
    timeout : float, keyword-only
        Seconds a request may take before its work is stopped and it answers
        "busy" (:data:`~mocapdb.server.archive.REQUEST_TIMEOUT`, 30 s).
        Requests are bounded besides (docs/ARCHITECTURE.md, "The archive in a
        browser"): a query stretch of at most 60 s, pages of at most 500 rows,
        two heavy requests at once.
    ready : callable, optional, keyword-only
        ``ready(url)`` once the server listens.

    Raises
    ------
    ParameterError
        A timeout or port out of range, an address that cannot be bound.
    SchemaError
        No database file at ``path``, or a file that is not DuckDB's.
    MocapdbError
        The ``serve`` extra is not installed.
    """
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout < float("inf"):
        raise ParameterError(f"timeout must be a number of seconds > 0, got {timeout!r}")
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ParameterError(f"port must be an integer from 0 to 65535, got {port!r}")
    archive = Archive(path, model=model, busy_wait=busy_wait, timeout=timeout)   # refuses a missing or foreign file
    uvicorn, app = _web_stack()
    sock = bind(host, port)
    if app.is_wildcard(host):
        log.warning("mocapdb serve on %s: the archive (names, labels, absolute source paths, the poses of every "
                    "motion) is open to every machine that reaches this one; --host 127.0.0.1 keeps it to this "
                    "machine", host)
    bound = sock.getsockname()[1]
    url = f"http://{f'[{host}]' if ':' in host else host}:{bound}/"
    # no log configuration of uvicorn's own: the library never prints; the CLI says where it listens
    server = uvicorn.Server(uvicorn.Config(app.create_app(archive, host=host), log_config=None, access_log=False,
                                           lifespan="off", timeout_graceful_shutdown=2))
    if ready is not None:
        ready(url)
    server.run(sockets=[sock])


def _web_stack():
    """uvicorn and :mod:`mocapdb.server.app`, imported when a server starts: a missing ``serve`` extra is then one
    line naming the extra, not "No module named 'uvicorn'" mid-start (the rest of this package imports without it)."""
    try:
        # starlette named too: server.app may be imported already, and the extra is starlette and uvicorn both
        import starlette  # noqa: F401
        import uvicorn

        from mocapdb.server import app
    except ImportError as exc:
        missing = exc.name or "starlette or uvicorn"
        raise MocapdbError(f"mocapdb serve needs the serve extra, which is not installed ({missing} is missing): "
                           f"pip install \"mocapdb[serve]\" (Starlette and uvicorn)") from None
    return uvicorn, app
