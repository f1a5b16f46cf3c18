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
line's arguments and fields.
"""
from __future__ import annotations

import logging
import socket

from mocapdb.errors import ParameterError
from mocapdb.server.archive import BUSY_WAIT, REQUEST_TIMEOUT, Archive
from mocapdb.api import DEFAULT_MODEL

__all__ = ["Archive", "BUSY_WAIT", "REQUEST_TIMEOUT", "create_app", "serve", "bind"]

log = logging.getLogger("mocapdb")


def create_app(archive, *, host="127.0.0.1"):
    """The web application serving ``archive`` (:func:`mocapdb.server.app.create_app`)."""
    from mocapdb.server.app import create_app as make  # starlette: the serve extra

    return make(archive, host=host)


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
    """Serve the archive at ``path`` over HTTP until interrupted (Ctrl-C).

    Parameters
    ----------
    path : str or Path
        The database file (read only; it is opened for each request and
        closed after it, so writers can work between requests).
    host : str, keyword-only, default "127.0.0.1"
        The address to bind: this machine only, unless given otherwise.
    port : int, keyword-only, default 8765
        0 takes any free port.
    model : str, keyword-only
        The model whose stored annotations the pages show.
    busy_wait : float, keyword-only
        Seconds a request waits for another process's lock before it answers
        "busy" (:data:`~mocapdb.server.archive.BUSY_WAIT`).
    timeout : float, keyword-only
        Seconds a request may take before its work is stopped
        (:data:`~mocapdb.server.archive.REQUEST_TIMEOUT`).
    ready : callable, optional, keyword-only
        ``ready(url)`` once the server listens.
    """
    import uvicorn  # the serve extra

    from mocapdb.server.app import is_wildcard

    archive = Archive(path, model=model, busy_wait=busy_wait, timeout=timeout)
    app = create_app(archive, host=host)
    sock = bind(host, port)
    if is_wildcard(host):
        log.warning("mocapdb serve on %s: the archive (names, labels, absolute source paths, the poses of every "
                    "motion) is open to every machine that reaches this one; --host 127.0.0.1 keeps it to this "
                    "machine", host)
    bound = sock.getsockname()[1]
    url = f"http://{f'[{host}]' if ':' in host else host}:{bound}/"
    # no log configuration of uvicorn's own: the library never prints; the CLI says where it listens
    server = uvicorn.Server(uvicorn.Config(app, log_config=None, access_log=False, lifespan="off",
                                           timeout_graceful_shutdown=2))
    if ready is not None:
        ready(url)
    server.run(sockets=[sock])
