"""Writing viewer pages: one motion to a file, or every motion to a folder with an index page."""
from __future__ import annotations

from pathlib import Path
from urllib.parse import quote

from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.storage.annotations import motion_sources
from mocapdb.storage.names import file_in, file_stems
from mocapdb.viewer.data import motion_poses, motion_view
from mocapdb.viewer.encoding import label_colors, render_index, render_page

__all__ = ["write_motion_page", "write_pages", "INDEX_STEM", "is_viewer_page"]

#: the index page of ``view --all`` (a motion of this name gets ``index_<id>.html``)
INDEX_STEM = "index"
#: what marks a file as written by the viewer (``shell.html``'s generator tag)
_GENERATOR = b'<meta name="generator" content="mocapdb view">'


def is_viewer_page(path) -> bool:
    """Whether the file at ``path`` is a page the viewer wrote (its generator tag near the top)."""
    try:
        with open(path, "rb") as fh:
            return _GENERATOR in fh.read(4096)
    except OSError:
        return False


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
        Created if missing; pages are named ``<motion name>.html``, the name
        made a safe file name (``<name>_<motion_id>.html`` where names repeat
        or a motion is named ``index``: :func:`mocapdb.storage.names.file_stems`).
        Files of an earlier run are replaced; any other file of a page's or
        the index's name is never overwritten (an error, before anything is
        written).
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
    sources = motion_sources(con, motions)
    paths = [file_in(directory, stem, ".html") for stem in file_stems(sources, reserved=(INDEX_STEM,))]
    index = file_in(directory, INDEX_STEM, ".html")
    # a symbolic link of a page's name could point anywhere: never written through
    foreign = [p.name for p in (index, *paths) if p.is_symlink() or (p.exists() and not is_viewer_page(p))]
    if foreign:
        raise ParameterError(f"all: {str(directory)!r} holds files the viewer did not write that its pages "
                             f"would replace ({', '.join(foreign[:5])}{' …' if len(foreign) > 5 else ''}); "
                             "choose an empty folder")
    directory.mkdir(parents=True, exist_ok=True)
    entries, written = [], []
    if progress is not None:
        progress(0, len(sources))
    for k, (src, path) in enumerate(zip(sources, paths)):
        try:
            view = write_motion_page(con, src["motion_id"], path, index_href="index.html", **options)
        except (MocapdbError, OSError) as exc:
            # a moved or changed source file costs its own page only
            entries.append({"name": src["name"], "error": str(exc)})
            if progress is not None:
                progress(k + 1, len(sources))
            continue
        found = sorted({str(x) for x in view.segments["label"]}, key=list(view.labels).index)
        colors = label_colors(view.labels)
        # a name may hold #, ? or %: the link is URL-quoted
        entries.append({"href": quote(path.name), "name": view.name, "seconds": view.n_frames / view.fps,
                        "segments": len(view.segments), "labels": {lab: colors[lab] for lab in found}})
        written.append(path)
        if progress is not None:
            progress(k + 1, len(sources))
    index.write_text(render_index(entries), encoding="utf-8")
    return [index, *written]
