"""Headless Chromium for the viewer tests (Debian's package ``chromium``, installed by .ci/run).

A missing browser is a failure, never a skip. Each call starts a fresh
browser with its own profile, loads a ``file://`` page and either dumps the
DOM after the page's scripts have run (``--virtual-time-budget`` lets the
asynchronous decoding finish) or takes a screenshot. The browser's console
goes to stderr (``--enable-logging=stderr``): an uncaught JavaScript error
shows there as ``Uncaught …``.
"""
import html.parser
import shutil
import subprocess
import tempfile

import pytest

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def chromium():
    """The Chromium executable; the test fails when there is none."""
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("headless Chromium not found (apt-get install -y chromium; .ci/run installs it)")


def _run(url, *args, timeout=120):
    with tempfile.TemporaryDirectory(prefix="mocapdb-chromium-") as profile:
        cmd = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars",
               f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0", "--virtual-time-budget=20000",
               *args, url]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        pytest.fail(f"chromium exited with {r.returncode}: {r.stderr[-2000:]}")
    return r


def dump_dom(path, query=""):
    """(DOM after the scripts ran, browser stderr) of a local page."""
    r = _run(path.resolve().as_uri() + query, "--dump-dom")
    return r.stdout, r.stderr


def screenshot(path, png, *, size=(1100, 900), query=""):
    """Write a PNG screenshot of a local page; returns the browser's stderr."""
    return _run(path.resolve().as_uri() + query, f"--screenshot={png}", f"--window-size={size[0]},{size[1]}").stderr


def console_errors(stderr):
    """Lines of the browser log that report a JavaScript error."""
    return [ln for ln in stderr.splitlines() if "Uncaught" in ln or ("CONSOLE" in ln and "Error" in ln)]


class Elements(html.parser.HTMLParser):
    """Every element of a document as (tag, attributes, text directly inside)."""

    def __init__(self, text):
        super().__init__()
        self.elements = []
        self._open = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        e = [tag, dict(attrs), ""]
        self.elements.append(e)
        if tag not in ("meta", "input", "br", "img", "link"):
            self._open.append(e)

    def handle_endtag(self, tag):
        while self._open:
            if self._open.pop()[0] == tag:
                break

    def handle_data(self, data):
        if self._open:
            self._open[-1][2] += data

    def by_class(self, cls):
        return [e for e in self.elements if cls in e[1].get("class", "").split()]

    def by_id(self, ident):
        found = [e for e in self.elements if e[1].get("id") == ident]
        return found[0] if found else None
