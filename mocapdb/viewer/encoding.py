"""A viewer page's data, encoded compactly and inlined with its HTML, CSS and JS (no network).

Each page is one self-contained HTML file per motion. The page (``shell.html``, ``page.html``, ``page.css``, ``errors.js``, ``page.js`` beside this module) draws
the skeleton with its own perspective projection on a 2-D canvas (orbit by
dragging, zoom by the wheel, play/pause, scrubber, speed), the annotation
under it as a timeline (one element ``.seg[data-label]`` per segment, one
colour per label), the ground truth in a lane of its own, and Δ̄^τ per label
as a heat map (paper Fig. 3). Clicking a segment seeks the animation to its
first frame.

The data travel compactly inside the page:

* poses: joint positions quantized to 1/1000 of the body size (≈ 2 mm,
  far below a pixel), the 23 joints other than the root relative to the
  root, then per coordinate (channel-major) the second differences over
  time (the changes of velocity, mostly a few steps), as little-endian
  int16 (int32 when one does not fit), deflated and base64-encoded (the
  page inflates them with the browser's ``DecompressionStream``): about 30
  bytes per frame, 40 with base64;
* Δ̄^τ: one byte per label and frame, 0–254 = Δ̄^τ/τ·254, 255 = above τ
  (white), deflated and base64-encoded.
"""
from __future__ import annotations

import base64
import html
import json
import re
import zlib
from importlib import resources

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.bodies import JOINT_INDEX, JOINT_NAMES

__all__ = ["BONES", "PALETTE", "encode_poses", "encode_delta", "label_colors", "render_page", "render_index",
           "page_html", "json_script", "error_script"]

#: bones between the 24 canonical joints (parent, child), drawn as lines
BONES = tuple((JOINT_INDEX[a], JOINT_INDEX[b]) for a, b in (
    ("root", "lhip"), ("lhip", "lknee"), ("lknee", "lankle"), ("lankle", "ltoes"),
    ("root", "rhip"), ("rhip", "rknee"), ("rknee", "rankle"), ("rankle", "rtoes"),
    ("root", "belly"), ("belly", "chest"), ("chest", "neck"), ("neck", "head"), ("head", "headtop"),
    ("neck", "lclavicle"), ("lclavicle", "lshoulder"), ("lshoulder", "lelbow"), ("lelbow", "lwrist"),
    ("lwrist", "lfingers"),
    ("neck", "rclavicle"), ("rclavicle", "rshoulder"), ("rshoulder", "relbow"), ("relbow", "rwrist"),
    ("rwrist", "rfingers"),
))

#: label colours (matplotlib's tab10, then tab20's light tones): one per label
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7",
           "#dbdb8d", "#9edae5")

#: quantization steps per body size (the extent of the first pose)
POSE_STEPS = 1000

_MARKER = re.compile(r"@([A-Z]+)@")


def _packed(raw: bytes) -> str:
    # level 6: level 9 gains 3 % here at 8x the time
    return base64.b64encode(zlib.compress(raw, 6)).decode("ascii")


def encode_poses(joints):
    """Joint positions as the page's compact pose record.

    Parameters
    ----------
    joints : (n_frames, n_joints, 3) float
        At least one frame; finite.

    Returns
    -------
    dict
        ``unit`` (source length per step), ``origin`` (root of the first
        frame), ``dtype`` (``"int16"`` or ``"int32"``) and ``data`` (base64 of
        the deflated second differences over time of the root-relative steps,
        channel-major: all frames of joint 0's x, then of its y, …).
    """
    j = np.asarray(joints, np.float64)
    if j.ndim != 3 or j.shape[2] != 3 or j.shape[0] == 0:
        raise ParameterError(f"joints must have shape (n_frames >= 1, n_joints, 3), got {j.shape}")
    if not np.isfinite(j).all():
        raise ParameterError("joints must be finite")
    size = float(np.ptp(j[0], axis=0).max()) or 1.0
    unit = size / POSE_STEPS
    origin = j[0, 0].copy()
    q = np.rint((j - origin) / unit).astype(np.int64)
    q[:, 1:] -= q[:, :1]  # the body relative to its root: small numbers whatever the walk
    zero = np.zeros((1, *q.shape[1:]), np.int64)
    d = np.diff(np.diff(q, axis=0, prepend=zero), axis=0, prepend=zero)  # two cumulative sums undo it
    d = d.reshape(d.shape[0], -1).T  # channel-major: each coordinate's time series in one run
    fits = np.abs(d).max() <= np.iinfo(np.int16).max
    dtype = "<i2" if fits else "<i4"
    return {"unit": unit, "origin": origin.tolist(), "dtype": "int16" if fits else "int32",
            "data": _packed(d.astype(dtype).tobytes())}


def encode_delta(label_delta, taus):
    """Δ̄^τ per label as the page's heat-map record.

    Parameters
    ----------
    label_delta : (n_labels, n_frames) float
        Finite values in [0, τ]; inf (or anything above τ) is "no hit".
    taus : (n_labels,) float
        The scale of each row (the largest τ of the label's classes).

    Returns
    -------
    dict
        ``tau`` (per row) and ``data`` (base64 of the deflated bytes, row-major).
    """
    d = np.asarray(label_delta, np.float64)
    t = np.asarray(taus, np.float64).reshape(-1, 1)
    if d.ndim != 2 or t.shape[0] != d.shape[0]:
        raise ParameterError(f"label_delta (n_labels, n_frames) and taus (n_labels,) disagree: {d.shape}, "
                             f"{t.shape[0]}")
    above = ~np.isfinite(d) | (d > t)
    q = np.where(above, 255, np.clip(np.rint(np.where(above, 0, d) / np.maximum(t, 1e-12) * 254), 0, 254))
    return {"tau": t[:, 0].tolist(), "data": _packed(q.astype(np.uint8).tobytes())}


def label_colors(*label_lists):
    """One colour per label, in order of first appearance over the lists (the model's labels first)."""
    labels = list(dict.fromkeys(str(x) for lst in label_lists for x in lst))
    return {lab: PALETTE[k % len(PALETTE)] for k, lab in enumerate(labels)}


def _asset(name):
    return resources.files("mocapdb.viewer").joinpath(name).read_text(encoding="utf-8")


def _fill(template, values):
    """The template with its ``@NAME@`` markers replaced, in one pass (inserted text is not scanned)."""
    return _MARKER.sub(lambda m: values[m.group(1)], template)


def error_script():
    """The JavaScript (``errors.js``) that writes a page's uncaught errors into its ``#errors`` list;
    every page inlines it once, before its own script."""
    return _asset("errors.js")


def page_html(title, body, *, css=""):
    """A whole page: ``shell.html`` (head, the stylesheet and ``css`` after it) around ``body``."""
    return _fill(_asset("shell.html"), {"TITLE": title, "CSS": _asset("page.css") + css, "BODY": body})


def json_script(obj):
    """``obj`` as JSON to inline in a ``<script type="application/json">`` element (no ``<``, ``>``, ``&``)."""
    # inside <script type="application/json"> no "<" may appear: "</script" would end the element
    # and "<!--<script" would swallow the rest of the page; \u003c is the same character to JSON
    text = json.dumps(obj, separators=(",", ":"), allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def render_page(view, joints, *, index_href=None, extra="", css=""):
    """The HTML of a motion's viewer page.

    Parameters
    ----------
    view : mocapdb.viewer.MotionView
    joints : (view.n_frames, 24, 3) float
        The poses on the feature grid (:func:`mocapdb.viewer.motion_poses`).
    index_href : str, optional
        Link back to an index page.
    extra : str, optional
        HTML placed under the viewer, inside its ``<main>`` (``mocapdb serve``
        adds its find-similar and label panel there); nothing by default.
    css : str, optional
        CSS added after the page's own (for ``extra``).

    Returns
    -------
    str
    """
    if len(joints) != view.n_frames:
        raise ParameterError(f"joints has {len(joints)} frames, the motion {view.n_frames}")
    truth_labels = [] if view.truth is None else [str(x) for x in view.truth["label"]]
    colors = label_colors(view.labels, truth_labels)
    label_tau = [float(max(t for t, lab in zip(view.taus, view.class_labels) if lab == x) if x in view.class_labels
                       else max(view.taus, default=1.0)) for x in view.labels]
    segs = view.segments
    data = {
        "name": view.name, "model": view.model, "source": view.source_path, "fps": view.fps,
        "sourceFps": view.source_fps, "n": view.n_frames, "keyframes": bool(view.keyframes),
        "tau": sorted(set(np.round(view.taus, 6).tolist())),
        "joints": list(JOINT_NAMES), "bones": [list(b) for b in BONES],
        "side": [n[0] if n[0] in "lr" and n != "root" else "c" for n in JOINT_NAMES],
        "pose": encode_poses(joints),
        "labels": list(view.labels), "colors": colors,
        "segments": [{"label": str(s["label"]), "start": int(s["start"]) + 1, "end": int(s["end"]) + 1,
                      "cost": round(float(s["cost"]), 5)} for s in segs[np.argsort(segs["start"], kind="stable")]],
        "truth": None if view.truth is None else [
            {"label": str(r["label"]), "start": int(r["start"]) + 1, "end": int(min(r["end"], view.n_frames - 1)) + 1}
            for r in view.truth if r["start"] < view.n_frames],
        "delta": encode_delta(view.label_delta, label_tau),
        "index": index_href,
    }
    title = html.escape(f"{view.name} — mocapdb")
    return page_html(title, _fill(_asset("page.html"), {"TITLE": title, "JS": error_script() + _asset("page.js"),
                                                      "DATA": json_script(data), "EXTRA": extra}), css=css)


def render_index(entries, *, title="mocapdb motions"):
    """The HTML of an index page linking viewer pages.

    Parameters
    ----------
    entries : sequence of dict
        ``href``, ``name``, ``seconds``, ``segments`` (count) and ``labels``
        (label → colour of the labels found) per motion; or ``name`` and
        ``error`` for a motion without a page.

    Returns
    -------
    str
    """
    rows = []
    for e in entries:
        if e.get("error"):
            # a motion whose source cannot be re-read: listed, with the reason
            rows.append(f'<tr class="unreadable"><td>{html.escape(e["name"])}</td><td class="num"></td>'
                        f'<td class="num"></td><td>no page: {html.escape(e["error"])}</td></tr>')
            continue
        chips = "".join(f'<span class="chip" style="background:{html.escape(c)}">{html.escape(lab)}</span>'
                        for lab, c in e["labels"].items())
        rows.append(f'<tr><td><a href="{html.escape(e["href"])}">{html.escape(e["name"])}</a></td>'
                    f'<td class="num">{e["seconds"]:.1f}</td><td class="num">{e["segments"]}</td>'
                    f'<td>{chips}</td></tr>')
    title = html.escape(title)
    return page_html(title, f'<header><h1>{title}</h1></header><main><table class="index"><thead><tr><th>motion</th>'
                        f'<th>seconds</th><th>segments</th><th>labels</th></tr></thead><tbody>{"".join(rows)}'
                        '</tbody></table></main>')
