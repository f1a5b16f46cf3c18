"""The web application of ``mocapdb serve`` (Starlette): the pages and the JSON API under ``/api/``.

=========================  =====================================================================
route                      answers
=========================  =====================================================================
``/``                      the archive page: motions with labels and label strips; filters, sort, pages
``/stats``                 the summary: hours per format and rate, per label; refused files
``/motion/<motion>``       the motion's (id or name) viewer page with find-similar and a label's segments
``/api/motions``           :func:`mocapdb.api.motions` (``mocapdb motions``): ``label``, ``source_format``, ``q``,
                           ``min_s``, ``max_s``, ``sort``, ``limit``, ``offset``
``/api/motions/<motion>``  :func:`mocapdb.api.motion_info`: one motion, its row and its stored segments
``/api/similar``           :func:`mocapdb.api.similar` (``mocapdb similar``): ``motion`` (id or name),
                           ``start_frame``, ``end_frame``, ``limit``, ``features``
``/api/segments``          :func:`mocapdb.api.label_segments`: ``label``, ``limit``, ``offset``
``/api/stats``             :func:`mocapdb.api.stats` (``mocapdb stats``) as JSON
``/favicon.ico``           the icon
=========================  =====================================================================

Every route is a function of :mod:`mocapdb.api` (the command line's too): the
same arguments (a motion by id or name everywhere) and the same fields (every
segment with its ``confidence``). Every route also takes ``model`` (default:
the server's). Errors are JSON ``{"error", "message"}`` on ``/api/`` and a page
elsewhere: 400 for a bad parameter (an unknown label lists the labels), 404
for an unknown motion, 422 for a motion whose source cannot be read again
(moved, or other bytes than were ingested), 503 while another process writes
the database, while as many heavy requests run as allowed, or when a request
ran out of time (:mod:`mocapdb.server.archive`). Nothing is written, ever:
each request reads through a read-only connection of its own.
"""
from __future__ import annotations

import contextlib
import functools
import json
import logging
import math
import socket

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.responses import HTMLResponse, Response
from starlette.routing import Route

import mocapdb.api as api
from mocapdb.errors import MocapdbError, ParameterError, SchemaError
from mocapdb.server.archive import DatabaseLockedError, Overloaded, RequestCancelled
from mocapdb.server.pages import FAVICON, archive_page, message_page, motion_page, stats_page

__all__ = ["create_app", "LOOPBACK_HOSTS", "WILDCARD_HOSTS", "allowed_hosts", "is_wildcard"]

log = logging.getLogger("mocapdb")

#: the host names a server bound to the loopback interface answers (a web page elsewhere that rebinds
#: its own name to 127.0.0.1 cannot read the archive through the browser)
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1", "[::1]")
#: the addresses that bind every interface of the machine
WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def _finite(obj):
    """``obj`` with NaN and infinities as None (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _json(obj, status=200):
    text = json.dumps(_finite(obj), default=str, allow_nan=False, separators=(",", ":"))
    return Response(text, status_code=status, media_type="application/json", headers={"Cache-Control": "no-store"})


def _int(params, name, default):
    value = params.get(name)
    if value in (None, ""):
        return default
    try:
        return int(value)
    except ValueError:
        raise ParameterError(f"{name} must be an integer, got {value!r}") from None


def _answer(kind, *, heavy=False):
    """A handler ``fn(self, request, con)`` run through :meth:`Archive.run` (a worker thread, a read-only
    connection, a time limit), its errors turned into answers: JSON for ``kind == "api"``, a page otherwise."""
    def deco(fn):
        @functools.wraps(fn)
        async def handler(self, request):
            try:
                return await self.archive.run(functools.partial(fn, self, request), heavy=heavy,
                                              disconnected=request.is_disconnected)
            except DatabaseLockedError as exc:
                status, error, text = 503, "busy", f"{exc}; mocapdb serve reads it again once the writer is done"
            except (Overloaded, RequestCancelled) as exc:
                status, error, text = 503, "busy", str(exc)
            except ParameterError as exc:
                status, error, text = 400, "bad parameter", str(exc)
            except SchemaError as exc:
                status, error, text = 404, "not found", str(exc)
            except (MocapdbError, OSError) as exc:
                status, error, text = 422, "cannot show", str(exc)
            if kind == "api":
                return _json({"error": error, "message": text}, status)
            page = message_page("mocapdb archive: " + error, text)
            if status == 503:  # the page asks again by itself while the writer works
                page = page.replace("<head>", '<head>\n<meta http-equiv="refresh" content="3">', 1)
            return HTMLResponse(page, status_code=status, headers={"Cache-Control": "no-store"})
        return handler
    return deco


class _Handlers:
    """The routes' handlers over one :class:`~mocapdb.server.archive.Archive`: each a function of
    :mod:`mocapdb.api` on a read-only connection of its own."""

    def __init__(self, archive):
        self.archive = archive
        self.archive_html = archive_page(archive.path.name)
        self.stats_html = stats_page(archive.path.name)

    def _model(self, request):
        return request.query_params.get("model") or self.archive.model

    async def index(self, request):
        return HTMLResponse(self.archive_html)

    async def stats(self, request):
        return HTMLResponse(self.stats_html)

    async def favicon(self, request):
        return Response(FAVICON, media_type="image/svg+xml", headers={"Cache-Control": "max-age=86400"})

    @_answer("page", heavy=True)
    def motion(self, request, con):
        model = self._model(request)
        row = api.motion_info(con, request.path_params["motion"], model=model)  # unknown: a 404 before reading
        try:
            page = motion_page(con, row["motion_id"], model=model, all_labels=api.labels(con, model=model),
                               n_frames=row["n_frames"])
        except (MocapdbError, OSError) as exc:
            # a motion stored from words, or whose source moved or changed: its facts without the viewer
            facts = [("name", row["name"]), ("format", row["format"]), ("rate", f"{row['source_fps']:g} Hz"),
                     ("duration", f"{row['seconds']:.1f} s"), ("source", row["source_path"]),
                     ("stored labels", ", ".join(row["labels"]) or "none")]
            return HTMLResponse(message_page(f"{row['name']} — mocapdb", f"no viewer for this motion: {exc}",
                                             details=facts), status_code=422)
        return HTMLResponse(page)

    @_answer("api")
    def api_motions(self, request, con):
        p, model = request.query_params, self._model(request)
        limit, offset = _int(p, "limit", 50), _int(p, "offset", 0)
        page = api.motions(con, label=p.get("label"), source_format=p.get("source_format"), q=p.get("q"),
                           min_s=p.get("min_s") or None, max_s=p.get("max_s") or None, sort=p.get("sort") or "id",
                           limit=limit, offset=offset, model=model)
        colors = api.label_colors(con, [lab for r in page.rows for lab in r["labels"]], model=model)
        return _json({"model": model, "total": page.total, "limit": limit, "offset": offset,
                      "strip_bins": api.STRIP_BINS, "rows": page.rows, "colors": colors})

    @_answer("api")
    def api_motion(self, request, con):
        model = self._model(request)
        row = api.motion_info(con, request.path_params["motion"], model=model)
        segments = row.pop("segments")
        return _json({"model": model, "motion": row, "segments": segments, "strip_bins": api.STRIP_BINS,
                      "colors": api.label_colors(con, row["labels"], model=model)})

    @_answer("api", heavy=True)
    def api_similar(self, request, con):
        p = request.query_params
        if p.get("motion") in (None, ""):
            raise ParameterError("motion must be a motion id or name "
                                 "(/api/similar?motion=NAME&start_frame=A&end_frame=B)")
        row = api.motion_info(con, p["motion"], model=self._model(request))
        first, last = _int(p, "start_frame", 1), _int(p, "end_frame", row["n_frames"])
        bound = self.archive.max_query_s
        if 1 <= first <= last <= row["n_frames"] and (last - first + 1) / row["fps"] > bound:
            # the work grows with the stretch times the archive: a web request is bounded, the CLI is not
            raise ParameterError(f"the query stretch {first}–{last} is {(last - first + 1) / row['fps']:.1f} s; "
                                 f"mocapdb serve answers stretches of at most {bound:g} s (mocapdb similar "
                                 "takes longer ones)")
        table = api.similar(con, row["motion_id"], start_frame=first, end_frame=last, limit=_int(p, "limit", 10),
                            features=p.get("features") or "all")
        return _json({"query": {"motion_id": row["motion_id"], "name": row["name"], "start_frame": first,
                                "end_frame": last}, "rows": table.to_pylist()})

    @_answer("api")
    def api_segments(self, request, con):
        p, model = request.query_params, self._model(request)
        rows, total = api.label_segments(con, p.get("label"), model=model, limit=_int(p, "limit", 50),
                                         offset=_int(p, "offset", 0))
        return _json({"model": model, "label": p.get("label"), "total": total, "rows": rows})

    @_answer("api")
    def api_stats(self, request, con):
        model = self._model(request)
        s = api.stats(con, model=model)
        out = {"model": model, "motions": s.motions, "hours": s.hours, "formats": s.formats.to_pylist(),
               "labels": s.labels.to_pylist(), "annotated_models": list(s.annotated_models),
               "colors": api.label_colors(con, s.labels.column("label").to_pylist(), model=model)}
        if s.refused is not None:
            out["refused"] = s.refused.to_pylist()
        return _json(out)


def create_app(archive, *, host="127.0.0.1"):
    """The Starlette application serving ``archive``.

    Parameters
    ----------
    archive : mocapdb.server.archive.Archive
    host : str, keyword-only
        The address the server binds: the application answers only requests
        naming a host of :func:`allowed_hosts` (on a loopback address the
        loopback names, :data:`LOOPBACK_HOSTS`).

    Returns
    -------
    starlette.applications.Starlette
    """
    h = _Handlers(archive)
    routes = [Route("/", h.index), Route("/stats", h.stats), Route("/favicon.ico", h.favicon),
              Route("/motion/{motion}", h.motion), Route("/api/motions", h.api_motions),
              Route("/api/motions/{motion}", h.api_motion), Route("/api/similar", h.api_similar),
              Route("/api/segments", h.api_segments), Route("/api/stats", h.api_stats)]
    return Starlette(routes=routes, middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=allowed_hosts(host))])


def is_wildcard(host) -> bool:
    """Whether ``host`` binds every interface (``0.0.0.0``, ``::``): the archive is open to the network."""
    return host in WILDCARD_HOSTS


def allowed_hosts(host) -> list:
    """The host names the server answers (the ``Host`` header; another name, say a web page's own name
    rebound to this machine's address, is refused).

    On a loopback address: the loopback names. Bound to another address: that address and this
    machine's names too. On every interface (``0.0.0.0``, ``::``): this machine's names and every
    address they resolve to, besides the loopback names.
    """
    names = {*LOOPBACK_HOSTS, host, f"[{host}]" if ":" in host else host}
    if host in LOOPBACK_HOSTS or host.startswith("127."):
        return sorted(names)
    machine = {socket.gethostname(), socket.getfqdn()}
    names |= machine
    if is_wildcard(host):
        for family, probe in ((socket.AF_INET, "192.0.2.1"), (socket.AF_INET6, "2001:db8::1")):
            # the address this machine reaches the network from (a UDP "connect" sends nothing)
            with contextlib.suppress(OSError), socket.socket(family, socket.SOCK_DGRAM) as sock:
                sock.connect((probe, 9))
                machine.add(sock.getsockname()[0])
        for name in machine:
            with contextlib.suppress(OSError):
                for info in socket.getaddrinfo(name, None):
                    addr = info[4][0].split("%")[0]
                    names |= {addr, f"[{addr}]"} if ":" in addr else {addr}
    names -= set(WILDCARD_HOSTS) | {"[::]"}
    return sorted(n for n in names if n)
