"""What a face on the API draws its HTML pages with: a stored motion read for the viewer, and the viewer's
encoders. ``mocapdb serve`` (mocapdb.server) builds its pages from these, so that it reads the archive only
through :mod:`mocapdb.api`, as the command line does; ``mocapdb view`` writes the same viewer page to a file."""
from __future__ import annotations

from mocapdb.viewer import motion_poses, motion_view
from mocapdb.viewer.encoding import error_script, json_script, page_html, render_page

__all__ = ["stored_motion_view", "render_page", "page_html", "json_script", "error_script"]


def stored_motion_view(con, motion_id, *, model, n_frames):
    """A stored motion as the viewer draws it: its annotation and its joints re-read from the source.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion_id : int
    model : str
        The model that annotates the motion.
    n_frames : int
        The motion's stored feature frames (its source must give as many).

    Returns
    -------
    view : mocapdb.viewer.MotionView
    joints : (view.n_frames, 24, 3) float

    Raises
    ------
    SchemaError
        No such motion, or its source gives other frames than were stored.
    ParseError, OSError
        Its source file cannot be read again (moved, or never a file).
    """
    # the source first: a motion without one (moved, or stored as words) fails before it is annotated
    joints = motion_poses(con, int(motion_id), n_frames)
    return motion_view(con, int(motion_id), model=model), joints
