"""Writing viewer pages: one motion to a file, or every motion to a folder with an index page."""
from __future__ import annotations

from pathlib import Path

from mocapdb.errors import MocapdbError

from mocapdb.storage.annotations import file_stems, motion_sources
from mocapdb.viewer.data import motion_poses, motion_view
from mocapdb.viewer.page import label_colors, render_index, render_page

__all__ = ["write_motion_page", "write_pages"]


def write_motion_page(con, motion, out, *, index_href=None, **options):
    """Write the viewer page of one stored motion.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion : int or str
        Motion id or name.
    out : str or Path
        The HTML file.
    index_href : str, optional
        Link back to an index page.
    **options
        ``model``, ``tau``, ``keyframes``, ``truth``, ``label_map`` of
        :func:`mocapdb.viewer.motion_view`.

    Returns
    -------
    MotionView
        What the page shows.
    """
    view = motion_view(con, motion, **options)
    joints = motion_poses(con, view.motion_id, view.n_frames)
    Path(out).write_text(render_page(view, joints, index_href=index_href), encoding="utf-8")
    return view


def write_pages(con, directory, *, motions=None, progress=None, **options):
    """Write one viewer page per motion and an ``index.html`` linking them.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    directory : str or Path
        Created if missing; pages are named ``<motion name>.html``
        (``<name>_<motion_id>.html`` where names repeat).
    motions : sequence of int, optional
        Motion ids (default: every motion).
    progress : callable, optional
        ``progress(n_done, n_total)`` after each page.
    **options
        As :func:`write_motion_page`.

    Returns
    -------
    list of Path
        The index page first, then the motion pages (a motion whose source
        file cannot be re-read gets no page; the index says why).
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    sources = motion_sources(con, motions)
    entries, written = [], []
    if progress is not None:
        progress(0, len(sources))
    for k, (src, stem) in enumerate(zip(sources, file_stems(sources))):
        path = directory / f"{stem}.html"
        try:
            view = write_motion_page(con, src["motion_id"], path, index_href="index.html", **options)
        except (MocapdbError, OSError) as exc:
            # a moved or changed source file costs its own page only
            entries.append({"name": stem, "error": str(exc)})
            if progress is not None:
                progress(k + 1, len(sources))
            continue
        found = sorted({str(x) for x in view.segments["label"]}, key=list(view.labels).index)
        colors = label_colors(view.labels)
        entries.append({"href": path.name, "name": view.name, "seconds": view.n_frames / view.fps,
                        "segments": len(view.segments), "labels": {lab: colors[lab] for lab in found}})
        written.append(path)
        if progress is not None:
            progress(k + 1, len(sources))
    index = directory / "index.html"
    index.write_text(render_index(entries), encoding="utf-8")
    return [index, *written]
