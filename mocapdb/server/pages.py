"""The HTML of ``mocapdb serve``: the archive page, the summary, a motion's page (the viewer and a panel under it).

Every page is self-contained as the viewer's pages are — CSS and JavaScript
inline, no library, no network resource but the server's own ``/api/``
answers. The archive page and the summary are the same for every request
(their rows come from ``/api/motions`` and ``/api/stats``); a motion's page
is the viewer page of :func:`mocapdb.api.pages.render_page` (the skeleton re-read
from its source file, the annotation, Δ̄ per label) with the panel of
``panel.html`` under it: find similar, and a label's segments across the
archive.
"""
from __future__ import annotations

import html
import re
from importlib import resources

from mocapdb.api.pages import error_script, json_script, page_html, render_page, stored_motion_view

__all__ = ["archive_page", "stats_page", "motion_page", "message_page", "FAVICON"]

_MARKER = re.compile(r"@([A-Z]+)@")

#: the tab's icon (``/favicon.ico``, which browsers ask for by themselves): a stick figure, as SVG
FAVICON = ('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 32 32"><rect width="32" height="32" rx="6" '
           'fill="#1f77b4"/><g stroke="#fff" stroke-width="2.6" stroke-linecap="round" fill="none">'
           '<circle cx="16" cy="7" r="3.2"/><path d="M16 10.5v9M16 13l-6 4M16 13l6-3M16 19.5l-5 8M16 19.5l5 8"/>'
           '</g></svg>').encode()


def _asset(name):
    return resources.files("mocapdb.server").joinpath(name).read_text(encoding="utf-8")


def _fill(template, values):
    # one pass: text put in is never scanned for markers
    return _MARKER.sub(lambda m: values[m.group(1)], template)


def _page(title, template, script, db):
    body = _fill(_asset(template), {"DB": html.escape(str(db)),
                                    "JS": error_script() + _asset("common.js") + _asset(script)})
    return page_html(html.escape(title), body, css=_asset("serve.css"))


def archive_page(db) -> str:
    """The archive page (its rows come from ``/api/motions``); ``db`` names the database in its header."""
    return _page("mocapdb archive", "archive.html", "archive.js", db)


def stats_page(db) -> str:
    """The summary page, hours per format and rate and per label as bars (from ``/api/stats``)."""
    return _page("mocapdb archive: summary", "stats.html", "stats.js", db)


def motion_page(con, motion_id, *, model, all_labels, n_frames) -> str:
    """The viewer page of a stored motion (:func:`mocapdb.api.pages.stored_motion_view`, whose arguments
    ``motion_id``, ``model`` and ``n_frames`` are, and whose errors it raises) with the server's panel under it,
    which offers ``all_labels`` (the motion's own first)."""
    view, joints = stored_motion_view(con, motion_id, model=model, n_frames=n_frames)
    found = sorted({str(x) for x in view.segments["label"]}, key=list(view.labels).index)
    data = {"motion_id": view.motion_id, "name": view.name, "n": view.n_frames, "fps": view.fps, "model": model,
            "labels": found, "all_labels": list(all_labels)}
    panel = _fill(_asset("panel.html"), {"DATA": json_script(data), "JS": _asset("common.js") + _asset("panel.js")})
    return render_page(view, joints, index_href="/", extra=panel, css=_asset("serve.css"))


def message_page(title, message, *, details=()) -> str:
    """A page that says what went wrong (or why the archive is busy), with links back.

    Parameters
    ----------
    title, message : str
    details : sequence of (str, str)
        Rows of a small table under the message (a motion's stored facts).
    """
    rows = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in details)
    table = f'<table class="index">{rows}</table>' if rows else ""
    body = (f'<header><h1>{html.escape(title)}</h1><nav class="site"><a href="/">archive</a>'
            f'<a href="/stats">summary</a></nav></header><main><p class="busy" id="message">{html.escape(message)}'
            f'</p>{table}</main>')
    return page_html(html.escape(title), body, css=_asset("serve.css"))
