"""The motion viewer: one self-contained HTML page per stored motion (``mocapdb view``).

:mod:`~mocapdb.viewer.data` (a motion annotated with its distance functions,
its poses re-read from the source), :mod:`~mocapdb.viewer.encoding` (a page's
data encoded compactly and inlined with the HTML/CSS/JS of the package files
``shell.html``, ``page.html``, ``page.css``, ``page.js``) and :mod:`~mocapdb.viewer.pages`
(writing one page, or a page per motion with an index) and
:mod:`~mocapdb.viewer.results` (the results of ``mocapdb similar`` as a page
linking each hit's motion page at the hit).
"""
from mocapdb.viewer.data import MotionView, motion_poses, motion_view
from mocapdb.viewer.encoding import BONES, PALETTE, encode_delta, encode_poses, label_colors, render_index, render_page
from mocapdb.viewer.pages import write_motion_page, write_pages
from mocapdb.viewer.results import render_results, write_results_pages

__all__ = ["MotionView", "motion_view", "motion_poses", "BONES", "PALETTE", "encode_poses", "encode_delta",
           "label_colors", "render_page", "render_index", "write_motion_page", "write_pages", "render_results",
           "write_results_pages"]
