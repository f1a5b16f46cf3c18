"""``mocapdb serve`` in a real browser (headless Chromium, live over the DevTools protocol): the archive page
lists the sample and filters it as typed, a motion page plays, a stretch dragged on the timeline finds
what ``mocapdb similar`` finds, and the summary shows the hours — with no JavaScript error anywhere.

Screenshots of the pages go to ``$MOCAPDB_SCREENSHOTS`` when it names a folder."""
import os
import time
from pathlib import Path

import pytest

import mocapdb

from cdp import Browser
from serving import sample_db, server  # noqa: F401 (fixtures)


@pytest.fixture(scope="module")
def page():
    with Browser(size=(1200, 900)) as browser:
        yield browser.page()


def _shot(page, name):
    folder = os.environ.get("MOCAPDB_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        page.screenshot(str(Path(folder) / f"serve_{name}.png"))


def _no_errors(page):
    assert page.exceptions == []
    assert page.evaluate("document.getElementById('errors').children.length") == 0


def _rows(page):
    return page.evaluate("[...document.querySelectorAll('#motions tbody tr')].map(r => r.dataset.name)")


def _sql(db, query, params=()):
    with mocapdb.connect(db, read_only=True) as con:
        return [r[0] for r in con.execute(query, list(params)).fetchall()]


@pytest.mark.slow
def test_the_archive_page_lists_the_sample_and_filters_it(page, server, sample_db):
    page.goto(server.url)
    assert _rows(page) == _sql(sample_db, "SELECT name FROM motions ORDER BY motion_id")
    strips = page.evaluate("[...document.querySelectorAll('#motions tbody tr')].map(r => "
                           "[...new Set([...r.querySelectorAll('.strip span')].map(s => s.dataset.label))].sort())")
    assert strips == [sorted(_sql(sample_db, "SELECT DISTINCT label FROM annotations WHERE motion_id = ?", [k]))
                      for k in (1, 2, 3)]
    # the folder column, and concurrent labels drawn on rows of their own: no two spans of one strip overlap
    assert page.evaluate("[...document.querySelectorAll('#motions td.folder')].map(td => td.title)") == \
        _sql(sample_db, "SELECT source_path FROM motions ORDER BY motion_id")
    boxes = page.evaluate("[...document.querySelectorAll('#motions div.strip')].map(b => [...b.children].map(s => { "
                          "const r = s.getBoundingClientRect(); return [r.left, r.right, r.top, r.bottom]; }))")
    overlaps = [(a, b) for spans in boxes for i, a in enumerate(spans) for b in spans[i + 1:]
                if min(a[1], b[1]) - max(a[0], b[0]) > 0.5 and min(a[3], b[3]) - max(a[2], b[2]) > 0.5]
    assert overlaps == [] and max(int(r) for r in page.evaluate(
        "[...document.querySelectorAll('#motions div.strip')].map(b => b.dataset.rows)")) >= 2
    _shot(page, "archive")
    # typed into the name box: the rows follow, and the address keeps the filter
    page.type_into("input[name=q]", "pymo")
    page.wait_for("document.body.dataset.ready === 'q=pymo'")
    assert _rows(page) == ["pymo_AV_8Walk_Meredith_HVHA_Rep1"]
    assert page.evaluate("location.search") == "?q=pymo"
    # a label chosen: the motions with a stored segment of it
    page.evaluate("(() => { const q = document.querySelector('input[name=q]'); q.value = ''; "
                  "const s = document.querySelector('select[name=label]'); s.value = 'jump'; "
                  "s.dispatchEvent(new Event('input', {bubbles: true})); })()")
    page.wait_for("document.body.dataset.ready === 'label=jump'")
    assert _rows(page) == _sql(sample_db, "SELECT DISTINCT m.name FROM motions m JOIN annotations a USING (motion_id) "
                                          "WHERE a.label = 'jump'")
    # a filtered address opens filtered, sorted
    page.goto(server.url + "?min_s=30&sort=-seconds", "document.body.dataset.ready === 'min_s=30&sort=-seconds'")
    assert _rows(page) == ["86_09", "HDM_mm_01-02_03_120"]
    _no_errors(page)


@pytest.mark.slow
def test_a_motion_page_plays(page, server):
    page.goto(server.url + "motion/1")
    assert page.evaluate("document.getElementById('scrubber').value") == "0"
    page.click("#play")
    time.sleep(1.0)
    frame = int(page.evaluate("document.getElementById('scrubber').value"))
    assert page.evaluate("document.getElementById('play').textContent") == "pause"
    assert 5 <= frame <= 1199, frame  # a second at 30 Hz, however slowly frames are drawn here
    page.click("#play")
    _no_errors(page)


def test_find_similar_on_a_dragged_stretch(page, server, sample_db):
    page.goto(server.url + "motion/1")
    x, y, width = page.center(".lane .track")
    page.drag(x - width * 0.05, y, x + width * 0.05, y)  # 45 % … 55 % of 86_09's timeline
    first, last = (int(page.evaluate(f"document.getElementById('similar').dataset.{k}")) for k in ("first", "last"))
    assert 450 < first < last < 750
    page.click("#find-similar")
    page.wait_for("document.body.dataset.similar")
    got = page.evaluate("[...document.querySelectorAll('#similar-results tr.hit')].map(r => "
                        "[Number(r.dataset.motion), Number(r.dataset.start), Number(r.dataset.end)])")
    with mocapdb.connect(sample_db, read_only=True) as con:
        table = mocapdb.similar(con, 1, start_frame=first, end_frame=last, limit=10)
    want = [list(r) for r in zip(*(table.column(c).to_pylist() for c in ("motion_id", "start_frame", "end_frame")))]
    assert got == want and len(want) >= 1
    _shot(page, "motion")
    # a result's link opens its motion's page at the hit, the stretch selected
    mid, start, end = got[0]
    page.click("#similar-results tr.hit a")
    page.wait_for(f"location.pathname === '/motion/{mid}' && location.hash === '#frame={start}-{end}' && "
                  f"document.body.dataset.ready === '1' && document.getElementById('similar').dataset.first === '{start}'")
    assert page.evaluate("document.getElementById('similar').dataset.last") == str(end)
    assert page.evaluate("document.getElementById('scrubber').value") == str(start - 1)
    _no_errors(page)


def test_a_labels_segments_across_the_archive(page, server, sample_db):
    page.goto(server.url + "motion/3")
    page.evaluate("(() => { const s = document.getElementById('label-pick'); s.value = 'move'; "
                  "s.dispatchEvent(new Event('change')); })()")
    page.wait_for("!document.getElementById('label-results').hidden")
    got = page.evaluate("[...document.querySelectorAll('#label-results tbody tr')].map(r => Number(r.dataset.motion))")
    assert sorted(got) == sorted(_sql(sample_db, "SELECT motion_id FROM annotations WHERE label = 'move'"))
    _no_errors(page)


def test_the_summary_shows_the_hours(page, server, sample_db):
    page.goto(server.url + "stats")
    hours = _sql(sample_db, "SELECT sum(n_frames / fps) / 3600 FROM motions")[0]
    assert float(page.evaluate("document.getElementById('totals').dataset.hours")) == pytest.approx(hours)
    minutes, seconds = divmod(round(hours * 3600), 60)
    assert page.evaluate("document.getElementById('totals').textContent") == \
        f"3 motion(s), {hours:.2f} hours in all ({minutes} min {seconds:02d} s)"
    bars = page.evaluate("[...document.querySelectorAll('#labels .bar')].map(b => Number(b.dataset.hours))")
    want = _sql(sample_db, "SELECT sum(end_s - start_s) / 3600 AS h FROM annotations GROUP BY label ORDER BY h DESC")
    assert bars == pytest.approx(want)
    widths = page.evaluate("[...document.querySelectorAll('#labels .bar')].map(b => b.getBoundingClientRect().width)")
    assert widths[0] == max(widths) and widths[-1] < widths[0]  # bars drawn to scale
    assert page.evaluate("document.querySelectorAll('#refused tbody tr').length") == 3
    _shot(page, "stats")
    _no_errors(page)
