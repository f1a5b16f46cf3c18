"""The web application of ``mocapdb serve`` (Starlette): the pages and the JSON API under ``/api/``.

=========================  =====================================================================
route                      answers
=========================  =====================================================================
``/``                      the archive page: motions with labels and label strips; filters, sort, pages
``/stats``                 the summary: hours per format and rate, per label; refused files
``/motion/<id>``           the motion's viewer page with find-similar and a label's segments
``/api/motions``           a page of motions: ``label``, ``format``, ``q``, ``min_s``, ``max_s``,
                           ``sort`` (:data:`mocapdb.storage.browse.SORTS`), ``limit``, ``offset``
``/api/motions/<id>``      one motion: its row and its stored segments
``/api/similar``           query by example: ``motion``, ``start_frame``, ``end_frame``, ``limit``,
                           ``features`` (as ``mocapdb similar``)
``/api/segments``          a label's stored segments across the archive: ``label``, ``limit``, ``offset``
``/api/stats``             :func:`mocapdb.storage.stats.archive_stats` as JSON
=========================  =====================================================================

Every route also takes ``model`` (default: the server's). Errors are JSON
``{"error", "message"}`` on ``/api/`` and a page elsewhere: 400 for a bad
parameter, 404 for an unknown motion, 422 for a motion whose source cannot
be read again, 503 while another process writes the database
(:mod:`mocapdb.server.archive`). Nothing is written, ever: each request reads
through a read-only connection of its own.
"""
from __future__ import annotations

import functools
import json
import logging
import math

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.responses import HTMLResponse, Response
from starlette.routing import Route

from mocapdb.errors import MocapdbError, ParameterError, SchemaError
from mocapdb.server.archive import DatabaseLockedError
from mocapdb.server.pages import archive_page, message_page, motion_page, stats_page
from mocapdb.storage.browse import (MAX_LIMIT, STRIP_BINS, label_segments, model_labels, motion_page as browse_page,
                                    motion_row, motion_segments)
from mocapdb.storage.retrieval import query_stretch, similar_stretches
from mocapdb.storage.stats import archive_stats
from mocapdb.viewer import label_colors

__all__ = ["create_app", "LOOPBACK_HOSTS"]

log = logging.getLogger("mocapdb")

#: the host names a server bound to the loopback interface answers (a web page elsewhere that rebinds
#: its own name to 127.0.0.1 cannot read the archive through the browser)
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1", "[::1]")


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


def _answer(kind):
    """Turn a handler's errors into answers: JSON for ``kind == "api"``, a page otherwise."""
    def deco(fn):
        @functools.wraps(fn)
        def handler(self, request):
            try:
                return fn(self, request)
            except DatabaseLockedError as exc:
                status, error, text = 503, "busy", f"{exc}; mocapdb serve reads it again once the writer is done"
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
    """The routes' handlers over one :class:`~mocapdb.server.archive.Archive` (plain functions: Starlette
    runs them in its thread pool, each with its own read-only connection)."""

    def __init__(self, archive):
        self.archive = archive
        self.archive_html = archive_page(archive.path.name)
        self.stats_html = stats_page(archive.path.name)

    def _model(self, request):
        return request.query_params.get("model") or self.archive.model

    @staticmethod
    def _colors(con, model, *extra):
        return label_colors(model_labels(con, model), *extra)

    def index(self, request):
        return HTMLResponse(self.archive_html)

    def stats(self, request):
        return HTMLResponse(self.stats_html)

    @_answer("page")
    def motion(self, request):
        model = self._model(request)
        mid = request.path_params["motion_id"]
        with self.archive.reading() as con:
            row = motion_row(con, mid, model=model)  # an unknown motion is a 404 before anything is read
            try:
                page = motion_page(con, mid, model=model, all_labels=model_labels(con, model),
                                   n_frames=row["n_frames"])
            except (MocapdbError, OSError) as exc:
                # a motion stored from words, or whose source moved: its facts without the viewer
                facts = [("name", row["name"]), ("format", row["format"]), ("rate", f"{row['source_fps']:g} Hz"),
                         ("duration", f"{row['seconds']:.1f} s"), ("source", row["source_path"]),
                         ("stored labels", ", ".join(row["labels"]) or "none")]
                return HTMLResponse(message_page(f"{row['name']} — mocapdb", f"no viewer for this motion: {exc}",
                                                 details=facts), status_code=422)
        return HTMLResponse(page)

    @_answer("api")
    def api_motions(self, request):
        p, model = request.query_params, self._model(request)
        limit, offset = _int(p, "limit", 50), _int(p, "offset", 0)
        with self.archive.reading() as con:
            page = browse_page(con, label=p.get("label"), format=p.get("format"), q=p.get("q"),
                               min_s=p.get("min_s") or None, max_s=p.get("max_s") or None, sort=p.get("sort") or "id",
                               limit=limit, offset=offset, model=model)
            colors = self._colors(con, model, [lab for r in page.rows for lab in r["labels"]])
        return _json({"model": model, "total": page.total, "limit": limit, "offset": offset,
                      "strip_bins": STRIP_BINS, "rows": page.rows, "colors": colors})

    @_answer("api")
    def api_motion(self, request):
        model = self._model(request)
        with self.archive.reading() as con:
            row = motion_row(con, request.path_params["motion_id"], model=model)
            segments = motion_segments(con, row["motion_id"], model=model)
            colors = self._colors(con, model, row["labels"])
        return _json({"model": model, "motion": row, "segments": segments, "strip_bins": STRIP_BINS,
                      "colors": colors})

    @_answer("api")
    def api_similar(self, request):
        p = request.query_params
        if p.get("motion") in (None, ""):
            raise ParameterError("motion must be a motion id (/api/similar?motion=ID&start_frame=A&end_frame=B)")
        mid, limit = _int(p, "motion", None), _int(p, "limit", 10)
        if not 1 <= limit <= MAX_LIMIT:  # a page of results, as every answer here
            raise ParameterError(f"limit must be an integer from 1 to {MAX_LIMIT}, got {limit}")
        with self.archive.reading() as con:
            stretch = query_stretch(con, mid, _int(p, "start_frame", None), _int(p, "end_frame", None))
            table = similar_stretches(con, [stretch], limit=limit, features=p.get("features") or "all")
            name = motion_row(con, mid)["name"]
        return _json({"query": {"motion_id": mid, "name": name, "start_frame": stretch[1] + 1,
                                "end_frame": stretch[2] + 1}, "rows": table.to_pylist()})

    @_answer("api")
    def api_segments(self, request):
        p, model = request.query_params, self._model(request)
        with self.archive.reading() as con:
            rows, total = label_segments(con, p.get("label"), model=model, limit=_int(p, "limit", 50),
                                         offset=_int(p, "offset", 0))
        return _json({"model": model, "label": p.get("label"), "total": total, "rows": rows})

    @_answer("api")
    def api_stats(self, request):
        model = self._model(request)
        with self.archive.reading() as con:
            s = archive_stats(con, model=model)
            colors = self._colors(con, model, s.labels.column("label").to_pylist())
        out = {"model": model, "motions": s.motions, "hours": s.hours, "formats": s.formats.to_pylist(),
               "labels": s.labels.to_pylist(), "annotated_models": list(s.annotated_models), "colors": colors}
        if s.refused is not None:
            out["refused"] = s.refused.to_pylist()
        return _json(out)


def create_app(archive, *, host="127.0.0.1"):
    """The Starlette application serving ``archive``.

    Parameters
    ----------
    archive : mocapdb.server.archive.Archive
    host : str, keyword-only
        The address the server binds: on a loopback address the application
        answers only requests naming a loopback host (:data:`LOOPBACK_HOSTS`).

    Returns
    -------
    starlette.applications.Starlette
    """
    h = _Handlers(archive)
    routes = [Route("/", h.index), Route("/stats", h.stats), Route("/motion/{motion_id:int}", h.motion),
              Route("/api/motions", h.api_motions), Route("/api/motions/{motion_id:int}", h.api_motion),
              Route("/api/similar", h.api_similar), Route("/api/segments", h.api_segments),
              Route("/api/stats", h.api_stats)]
    loopback = host in LOOPBACK_HOSTS or host.startswith("127.")
    middleware = [Middleware(TrustedHostMiddleware, allowed_hosts=[*LOOPBACK_HOSTS, host])] if loopback else []
    return Starlette(routes=routes, middleware=middleware)
