"""The viewer frames the body from its extent over the whole take (issue 33): a dance-like take whose root goes
metres up and down, and one whose root never moves, stay inside the canvas at every frame, in the page of
``mocapdb view`` and in ``mocapdb serve``'s motion page (headless Chromium).

Both takes are a real ACCAD recording with its root channels changed (written to the test's folder only)."""
import gzip
import math
import os
from pathlib import Path

import pytest

from cdp import Browser
from conftest import DATA, run
from serving import Served

#: a browser and a server: seconds each
pytestmark = [pytest.mark.slow, pytest.mark.shared]

SOURCE = DATA / "accad_dev" / "Male1_C20_Run2Jump2Walk.bvh.gz"  # run, jump, walk: centimetres, 30 Hz


def _retake(path, change):
    """The source BVH with ``change(frame, values)`` applied to each frame's channel values."""
    text = gzip.decompress(SOURCE.read_bytes()).decode("latin-1")
    head, _, motion = text.partition("MOTION")
    lines = motion.strip().splitlines()
    frames = [[float(v) for v in ln.split()] for ln in lines[2:] if ln.strip()]
    out = [head + "MOTION", lines[0], lines[1]]
    for k, values in enumerate(frames):
        change(k, values)
        out.append(" ".join(f"{v:.5f}" for v in values))
    path.write_text("\n".join(out) + "\n")
    return path


def _dance(k, v):
    # the root rises and falls 2.5 m every two seconds (a rope swing, a lift in a dance): twice the body's height
    v[1] += 250.0 * (1 - math.cos(2 * math.pi * k / 60)) / 2


def _fixed(k, v):
    v[0] = v[1] = v[2] = 0.0  # no root translation at all


@pytest.fixture(scope="module")
def takes(tmp_path_factory):
    root = tmp_path_factory.mktemp("framing")
    files = [_retake(root / "dance_like.bvh", _dance), _retake(root / "root_fixed.bvh", _fixed)]
    db = root / "framing.duckdb"
    run(db, "ingest", *files, "--silent")
    return db, root


@pytest.fixture(scope="module")
def browser():
    with Browser(size=(1200, 900)) as b:
        yield b


def _figure_stays_inside(page, name, shots):
    """Seek through the take; at every frame looked at, every joint lands inside the canvas."""
    n = int(page.evaluate("Number(document.getElementById('scrubber').max) + 1"))
    assert n > 60
    outside = []
    for t in range(0, n, 3):
        page.evaluate(f"(() => {{ const s = document.getElementById('scrubber'); s.value = '{t}'; "
                      "s.dispatchEvent(new Event('input')); })()")
        x0, y0, x1, y1, w, h = (float(v) for v in page.evaluate(
            "document.getElementById('skeleton').dataset.figure").split(","))
        if not (0 <= x0 and x1 <= w and 0 <= y0 and y1 <= h):
            outside.append((t, x0, y0, x1, y1, w, h))
        # the figure is not a speck either: a person spans a fair part of the canvas
        assert y1 - y0 > 0.12 * h, (t, y0, y1, h)
    assert outside == [], f"{name}: the figure leaves the canvas at {len(outside)} frame(s): {outside[:3]}"
    page.evaluate("(() => { const s = document.getElementById('scrubber'); s.value = '30'; "
                  "s.dispatchEvent(new Event('input')); })()")  # the top of the dance's first rise
    page.screenshot(str(shots / f"{name}.png"))
    assert (shots / f"{name}.png").stat().st_size > 10_000
    assert page.exceptions == []


@pytest.mark.parametrize("name", ["dance_like", "root_fixed"])
def test_view_keeps_the_figure_inside_the_canvas(takes, browser, name, tmp_path):
    db, root = takes
    out = root / f"{name}.html"
    run(db, "view", name, "--out", out, "--silent")
    page = browser.page()
    page.goto(out.resolve().as_uri())
    _figure_stays_inside(page, name, Path(os.environ.get("MOCAPDB_SCREENSHOTS") or tmp_path))


def test_serve_keeps_the_figure_inside_the_canvas(takes, browser, tmp_path):
    db, _ = takes
    server = Served(db)
    try:
        page = browser.page()
        for name in ("dance_like", "root_fixed"):
            page.goto(server.url + f"motion/{name}")
            _figure_stays_inside(page, f"serve_{name}", Path(os.environ.get("MOCAPDB_SCREENSHOTS") or tmp_path))
    finally:
        server.stop()
