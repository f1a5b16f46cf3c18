"""The results of a query by example as pages: a list of the hits, each linked to its motion's page at the hit.

``mocapdb similar … --format html --out DIR`` writes ``DIR/index.html`` (the
query and the ranked results) and a viewer page per motion involved
(``DIR/<motion>.html``); a result links to ``<motion>.html#frame=A-B``, which
the viewer page opens at frame A with frames A–B selected (page.js). A motion
whose source file cannot be re-read (moved, or stored as words only) is
listed without a page, with the reason.
"""
from __future__ import annotations

import html
from pathlib import Path

from mocapdb.errors import MocapdbError
from mocapdb.storage.annotations import file_stems, motion_sources
from mocapdb.viewer.encoding import page_html
from mocapdb.viewer.pages import write_motion_page

__all__ = ["write_results_pages", "render_results"]


def _link(entry, first, last, text):
    if entry.get("href") is None:
        return f'<span title="no page: {html.escape(entry["error"])}">{html.escape(text)}</span>'
    return f'<a href="{html.escape(entry["href"])}#frame={first}-{last}">{html.escape(text)}</a>'


def render_results(query, rows, pages, *, fps=30.0):
    """The HTML of a results page.

    Parameters
    ----------
    query : sequence of (motion_id, first, last)
        The query stretches (0-based inclusive frames).
    rows : list of dict
        The result rows (``document``, ``motion_id``, ``start_frame``,
        ``end_frame``, ``start_s``, ``end_s``, ``cost``), ranked.
    pages : dict
        motion id → ``{"name", "href"}`` or ``{"name", "error"}``.
    fps : float

    Returns
    -------
    str
    """
    asked = []
    for mid, first, last in query:
        e = pages[int(mid)]
        asked.append(f'<li class="query">{_link(e, first + 1, last + 1, e["name"])} frames {first + 1}–{last + 1} '
                     f'({first / fps:.2f}–{(last + 1) / fps:.2f} s)</li>')
    body = []
    for rank, r in enumerate(rows, start=1):
        e = pages[int(r["motion_id"])]
        body.append(f'<tr class="hit" data-motion="{int(r["motion_id"])}" data-start="{int(r["start_frame"])}" '
                    f'data-end="{int(r["end_frame"])}"><td class="num">{rank}</td>'
                    f'<td>{_link(e, r["start_frame"], r["end_frame"], r["document"])}</td>'
                    f'<td class="num">{r["start_frame"]}–{r["end_frame"]}</td>'
                    f'<td class="num">{r["start_s"]:.2f}–{r["end_s"]:.2f}</td>'
                    f'<td class="num">{r["cost"]:.4f}</td></tr>')
    title = "mocapdb similar"
    what = "the examples" if len(query) > 1 else "the query"
    return page_html(title, f'<header><h1>{title}</h1><p id="meta">{len(rows)} stretch(es) most like {what}, '
                            f'cheapest first (cost: the weighted Δ)</p></header><main><ul>{"".join(asked)}</ul>'
                            '<table class="index"><thead><tr><th>#</th><th>motion</th><th>frames</th><th>seconds</th>'
                            f'<th>cost</th></tr></thead><tbody>{"".join(body)}</tbody></table></main>')


def write_results_pages(con, table, query, directory, *, progress=None, **options):
    """Write ``index.html`` listing the results and a viewer page per motion involved.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    table : pyarrow.Table
        The result of :func:`mocapdb.api.similar`.
    query : sequence of (motion_id, first, last)
    directory : str or Path
        Created if missing.
    progress : callable, optional
        ``progress(n_done, n_total)`` per motion page.
    **options
        ``model``, ``tau``, ``keyframes`` … of :func:`mocapdb.viewer.motion_view`.

    Returns
    -------
    list of Path
        ``index.html`` first, then the motion pages.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    rows = table.to_pylist()
    ids = sorted({int(q[0]) for q in query} | {int(r["motion_id"]) for r in rows})
    sources = motion_sources(con, ids)
    pages, written = {}, []
    for k, (src, stem) in enumerate(zip(sources, file_stems(sources))):
        path = directory / f"{stem}.html"
        try:
            write_motion_page(con, src["motion_id"], path, index_href="index.html", **options)
            pages[src["motion_id"]] = {"name": src["name"], "href": path.name}
            written.append(path)
        except (MocapdbError, OSError) as exc:  # a source that cannot be re-read costs its own page only
            pages[src["motion_id"]] = {"name": src["name"], "href": None, "error": str(exc)}
        if progress is not None:
            progress(k + 1, len(sources))
    index = directory / "index.html"
    index.write_text(render_results(query, rows, pages), encoding="utf-8")
    return [index, *written]
