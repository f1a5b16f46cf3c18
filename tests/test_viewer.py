"""The viewer page in a real browser (headless Chromium): segments, clicks, pixels, no JavaScript errors."""
import json
import os
import re
import shutil
from pathlib import Path
from importlib import resources

import numpy as np
import pytest

import mocapdb
from mocapdb.annotation import read_truth
from mocapdb.viewer import encode_delta, encode_poses, motion_poses, motion_view

from browser import Elements, console_errors, dump_dom, screenshot
from conftest import DATA, REPO, run, write_truth_86_09_eaf

CMU86_MAP = resources.files("mocapdb.shipped_models").joinpath("cmu86_labels.csv")
HOPS = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("HDM_bd_*.amc"))[:2]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    root = tmp_path_factory.mktemp("viewer")
    path = root / "view.duckdb"
    con = mocapdb.connect(path)
    mocapdb.ingest(con, [DATA / "cmu" / "86" / "86_09.amc", *HOPS])
    con.close()
    return path, write_truth_86_09_eaf(root / "86_09_truth.eaf")


@pytest.fixture(scope="module")
def page(db, tmp_path_factory):
    """The 86_09 page with the ELAN ground truth, and the DOM Chromium made of it with ?selftest."""
    path, eaf = db
    out = tmp_path_factory.mktemp("page") / "86_09.html"
    run(path, "view", "86_09", "--out", out, "--truth", eaf, "--label-map", CMU86_MAP)
    dom, log = dump_dom(out, "?selftest=1")
    return out, Elements(dom), log


@pytest.mark.slow
@pytest.mark.shared
def test_every_segment_is_an_element_with_its_label(db, page):
    path, eaf = db
    out, dom, log = page
    with mocapdb.connect(path, read_only=True) as con:
        table = mocapdb.annotate(con, ["86_09"], store=False)
        n_frames = con.execute("SELECT n_frames FROM motions WHERE name = '86_09'").fetchone()[0]
    want = sorted(zip(["annotation"] * table.num_rows, table.column("label").to_pylist(),
                      table.column("start_frame").to_pylist(), table.column("end_frame").to_pylist()))
    truth = read_truth(eaf, label_map=str(CMU86_MAP), fps=120.0)
    want += sorted(("truth", str(r["label"]), int(r["start"]) + 1, min(int(r["end"]), n_frames - 1) + 1)
                   for r in truth)
    got = [(e[1]["data-lane"], e[1]["data-label"], int(e[1]["data-start"]), int(e[1]["data-end"]))
           for e in dom.by_class("seg")]
    assert table.num_rows >= 3 and len(truth) == 5
    assert sorted(g for g in got if g[0] == "annotation") == want[:table.num_rows]
    assert sorted(g for g in got if g[0] == "truth") == sorted(want[table.num_rows:])
    # the truth's walk became the model's move (--label-map), and shares its colour
    assert {g[1] for g in got if g[0] == "truth"} == {"move", "look_around", "clap", "stand_and_clap"}
    colours = {}
    for e in dom.by_class("seg"):
        colours.setdefault(e[1]["data-label"], set()).add(re.search(r"background: ([^;]+)", e[1]["style"]).group(1))
    assert all(len(c) == 1 for c in colours.values()) and len({min(c) for c in colours.values()}) == len(colours)


@pytest.mark.shared
def test_the_page_runs_without_javascript_errors(page):
    out, dom, log = page
    body = next(e for e in dom.elements if e[0] == "body")
    assert body[1].get("data-ready") == "1", "the page's script did not finish"
    assert console_errors(log) == []
    assert dom.by_id("errors")[2].strip() == ""


@pytest.mark.slow
@pytest.mark.shared
def test_a_javascript_error_fails_the_check(page, tmp_path):
    """The harness sees a broken page (so the checks above can fail)."""
    out, _, _ = page
    broken = tmp_path / "broken.html"
    broken.write_text(out.read_text(encoding="utf-8").replace('"use strict";', '"use strict"; no_such_function();', 1),
                      encoding="utf-8")
    dom, log = dump_dom(broken)
    assert console_errors(log) and "no_such_function" in "\n".join(console_errors(log))
    assert "data-ready" not in dump_dom(broken)[0].split("<body", 1)[1].split(">", 1)[0]


@pytest.mark.shared
def test_clicking_a_segment_seeks_there(page):
    out, dom, log = page
    test = dom.by_id("selftest")
    assert test[1]["data-status"] == "pass", test[2]
    assert int(test[1]["data-segments"]) == len(dom.by_class("seg"))


@pytest.mark.shared
def test_dragging_along_the_timeline_offers_a_similar_command(page):
    """The self test drags from 20 % to 40 % of the first track: frames selected, the command shown."""
    out, dom, log = page
    test = dom.by_id("selftest")
    first, last = map(int, test[1]["data-selection"].split("-"))
    assert 1 <= first < last
    assert test[1]["data-command"] == f"mocapdb similar 86_09 --start-frame {first} --end-frame {last}"
    assert dom.by_id("similar-command")[2] == test[1]["data-command"]
    box = dom.by_id("similar")
    assert "hidden" not in box[1] and (box[1]["data-first"], box[1]["data-last"]) == (str(first), str(last))


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("fragment, opened, selected", [("#frame=100-160", "100", ("100", "160")),
                                                       ("#frame=250", "250", None)])
def test_a_frame_fragment_opens_the_page_there(page, fragment, opened, selected):
    """The links of a results page (similar --format html) open the motion's page at the hit."""
    out, _, _ = page
    dom, log = dump_dom(out, fragment)
    assert console_errors(log) == []
    dom = Elements(dom)
    body = next(e for e in dom.elements if e[0] == "body")
    assert body[1].get("data-opened-at") == opened
    assert dom.by_id("clock")[2].split("frame ")[1].startswith(f"{opened}/")
    box = dom.by_id("similar")
    if selected is None:
        assert "hidden" in box[1]
    else:
        assert (box[1]["data-first"], box[1]["data-last"]) == selected
        assert dom.by_id("similar-command")[2] == f"mocapdb similar 86_09 --start-frame {selected[0]} " \
                                                 f"--end-frame {selected[1]}"


@pytest.mark.shared
def test_the_decoded_poses_are_the_source_joints(db, page):
    """The page's own decoder (JavaScript) gives back the re-read joints within the quantization step."""
    path, _ = db
    out, dom, log = page
    with mocapdb.connect(path, read_only=True) as con:
        mid = con.execute("SELECT motion_id FROM motions WHERE name = '86_09'").fetchone()[0]
        joints = motion_poses(con, mid)
    unit = encode_poses(joints)["unit"]
    probes = json.loads(dom.by_id("selftest")[1]["data-poses"])
    assert len(probes) == 12
    for t, j, *xyz in probes:
        # float32 in the page; rounding to the step twice (joint and root) at most
        np.testing.assert_allclose(xyz, joints[t, j], atol=1.01 * unit + 1e-4 * np.abs(joints[t, j]).max())


@pytest.mark.slow
@pytest.mark.shared
def test_the_screenshot_is_not_blank(page, tmp_path):
    out, _, _ = page
    png = tmp_path / "viewer.png"
    log = screenshot(out, png)
    assert console_errors(log) == []
    import matplotlib.image

    img = matplotlib.image.imread(png)[..., :3]
    assert img.shape[:2] == (900, 1100)
    assert img.std() > 0.05  # not one colour
    stage = img[60:470, 20:1080]  # the skeleton canvas: dark bones and joints on white
    assert (stage.max(axis=2) < 0.4).sum() > 200
    colours = np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50
    if os.environ.get("MOCAPDB_UPDATE_SCREENSHOT"):  # the README's picture (committed once, docs/viewer.png)
        shutil.copyfile(png, REPO / "docs" / "viewer.png")


@pytest.mark.shared
def test_the_page_is_self_contained(page):
    out, _, _ = page
    text = out.read_text(encoding="utf-8")
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=|@import|url\(", text)
    assert not re.search(r"https?://(?!www\.w3\.org)", text.split('id="mocapdb-data"')[0])


@pytest.mark.slow
@pytest.mark.shared
def test_all_writes_a_page_per_motion_and_an_index(db, tmp_path):
    path, _ = db
    r = run(path, "view", "--all", tmp_path / "pages", "--silent")
    assert "and 3 page(s)" in r.output
    pages = sorted(p.name for p in (tmp_path / "pages").glob("*.html"))
    assert pages == sorted(["index.html", "86_09.html", *(p.stem + ".html" for p in HOPS)])
    index = Elements((tmp_path / "pages" / "index.html").read_text(encoding="utf-8"))
    links = sorted(e[1]["href"] for e in index.elements if e[0] == "a")
    assert links == [p for p in pages if p != "index.html"]
    dom, log = dump_dom(tmp_path / "pages" / HOPS[0].with_suffix(".html").name, "?selftest=1")
    assert console_errors(log) == [] and Elements(dom).by_id("selftest")[1]["data-status"] == "pass"


@pytest.mark.shared
def test_view_needs_a_motion_or_all(db, tmp_path, monkeypatch):
    path, _ = db
    assert run(path, "view", code=1).output.startswith("Error: give a motion")
    assert "no motion 'no_such'" in run(path, "view", "no_such", "--out", "x.html", code=1).output
    monkeypatch.chdir(tmp_path)   # without --out: <motion name>.html here
    assert run(path, "view", "86_09").output.strip() == "written 86_09.html" and (tmp_path / "86_09.html").is_file()


@pytest.mark.shared
def test_the_header_gives_the_models_tau_once(page):
    """Issue 27 item 8: the header listed every class's τ ("τ 0.1/0.11/0.13/…"), read as tick labels."""
    out, dom, log = page
    meta = dom.by_id("meta")[2]
    assert re.search(r"model default, τ 0\.\d+–0\.\d+ \(per class\), keyframes", meta), meta


@pytest.mark.shared
def test_the_distance_functions_are_those_of_sql_mt_distance(db):
    """Δ̄^τ of the page (reference mode) is made of the SQL function's Δ: every finite value is a
    value of Δ below τ, and where Δ has its smallest value below τ, Δ̄^τ has it too."""
    path, _ = db
    with mocapdb.connect(path, read_only=True) as con:
        v = motion_view(con, "86_09", keyframes=False)
        checked = 0
        for k, (cls, tau) in enumerate(zip(v.class_names, v.taus)):
            delta = np.array(con.execute("SELECT mt_distance(motion_id, ?) FROM motions WHERE name = '86_09'",
                                         [cls]).fetchone()[0])
            bar = v.class_delta[k]
            assert bar.shape == delta.shape == (v.n_frames,)
            finite = np.isfinite(bar)
            assert np.isin(bar[finite], delta[delta <= tau]).all(), cls
            if delta.min() < tau:
                best = int(np.argmin(delta))
                assert bar[best] == delta[best], cls
                checked += 1
        label_of = np.array(v.class_labels)
        for k, lab in enumerate(v.labels):  # per label: the minimum over the label's classes
            rows = v.class_delta[label_of == lab]
            np.testing.assert_array_equal(v.label_delta[k], rows.min(axis=0) if len(rows) else np.inf)
    assert checked >= 2  # at least move and throwR have hits on 86_09


def test_delta_bytes():
    d = np.array([[0.0, 0.065, 0.13, np.inf, 0.2]])
    rec = encode_delta(d, [0.13])
    import base64
    import zlib

    assert list(zlib.decompress(base64.b64decode(rec["data"]))) == [0, 127, 254, 255, 255]


def test_poses_fall_back_to_int32_for_big_jumps():
    j = np.zeros((3, 24, 3))
    j[:, 12, 1] = 170.0  # a body of height 170
    j[2] += 1e6  # a teleport of ~6000 body sizes within a frame
    assert encode_poses(j[:2])["dtype"] == "int16" and encode_poses(j)["dtype"] == "int32"


@pytest.mark.shared
def test_all_lists_a_motion_whose_source_moved_without_a_page(tmp_path, open_db):
    """A source file moved after ingest costs its own page only; the index says why."""
    src = tmp_path / "takes"
    src.mkdir()
    for name in ("02.asf", "02_01.amc", "02_02.amc"):
        shutil.copy(DATA / "cmu/02" / name, src / name)
    con = open_db(tmp_path / "moved.duckdb")
    assert len(mocapdb.ingest(con, [src]).ingested) == 2
    (src / "02_02.amc").unlink()
    written = mocapdb.view(con, all=tmp_path / "pages")
    assert [p.name for p in written] == ["index.html", "02_01.html"]
    index = written[0].read_text(encoding="utf-8")
    assert 'class="unreadable"' in index and "02_02" in index and "no page:" in index


#: motion names an imported archive or a hand-edited database may hold (issue 22 items 3, 6, 9)
HOSTILE = ["../../ESCAPED_VIEW", "{tmp}/ABSOLUTE_ESCAPE", "index", "INDEX", '<!--<script>x#y?z%20 & "q"',
           "CON", "..\\..\\WIN_ESCAPE", "a" * 300, ".hidden"]


@pytest.fixture(scope="module")
def hostile_db(tmp_path_factory):
    """A database whose motions carry hostile names (set by SQL, as an old or edited database may)."""
    root = tmp_path_factory.mktemp("hostile")
    clips = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("HDM_bd_*.amc"))[:len(HOSTILE)]
    names = [n.format(tmp=root) for n in HOSTILE]
    with mocapdb.connect(root / "h.duckdb") as con:
        mocapdb.ingest(con, clips)
        for mid, name in enumerate(names, 1):
            con.execute("UPDATE motions SET name = ? WHERE motion_id = ?", [name, mid])
    return root, names


def _files(root):
    return {p for p in root.rglob("*") if p.is_file()}


@pytest.mark.slow
@pytest.mark.shared
def test_no_page_lands_outside_the_folder_whatever_the_names(hostile_db, tmp_path):
    """view --all with hostile names: every file inside the folder, one page per motion, and the
    index's links, resolved by the browser, open each motion's own page."""
    root, names = hostile_db
    before = _files(root.parent)
    pages = root / "out" / "pages"
    r = run(root / "h.duckdb", "view", "--all", pages, "--silent")
    assert f"and {len(names)} page(s)" in r.output
    new = _files(root.parent) - before
    assert new and all(p.parent == pages for p in new), sorted(map(str, new - set(pages.iterdir())))
    assert not list(root.parent.rglob("*ESCAPE*")) or all(p.parent == pages for p in root.parent.rglob("*ESCAPE*"))
    assert not (root / "ABSOLUTE_ESCAPE.html").exists()
    assert len(new) == len(names) + 1 and "index.html" in {p.name for p in new}
    assert len({p.name.casefold() for p in new}) == len(new)  # distinct on case-insensitive file systems
    assert all(len(p.name.encode()) <= 255 for p in new)
    # the browser resolves the index's links: each opens the page of its own motion
    probe = pages / "links.html"
    probe.write_text((pages / "index.html").read_text(encoding="utf-8").replace(
        "</body>", "<script>for (const a of document.links) a.setAttribute('data-resolved', a.href)</script>"
                   "</body>"), encoding="utf-8")
    dom, log = dump_dom(probe)
    assert console_errors(log) == []
    links = [e for e in Elements(dom).elements if e[0] == "a"]
    assert sorted(e[2] for e in links) == sorted(names)
    from urllib.parse import unquote, urlparse

    for tag, attrs, text in links:
        target = Path(unquote(urlparse(attrs["data-resolved"]).path))
        assert target.parent == pages and target.is_file(), (text, attrs["data-resolved"])
        data = target.read_text(encoding="utf-8").split('id="mocapdb-data">', 1)[1].split("</script>", 1)[0]
        assert json.loads(data)["name"] == text
    probe.unlink()
    # a page whose name holds "<!--<script>" is whole: its script runs and its self-test passes
    page = next(p for p in new if p.name.startswith("_!--_script_"))
    dom, log = dump_dom(page, "?selftest=1")
    assert console_errors(log) == [] and Elements(dom).by_id("selftest")[1]["data-status"] == "pass"
    assert Elements(dom).by_id("title")[2] == f"{names[4]} — mocapdb"
    # a second run replaces its own pages
    run(root / "h.duckdb", "view", "--all", pages, "--silent")
    assert _files(root.parent) - before == new


@pytest.mark.shared
def test_all_never_overwrites_a_file_it_did_not_write(hostile_db, tmp_path):
    root, names = hostile_db
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "index.html").write_text("my own index", encoding="utf-8")
    (folder / "notes.txt").write_text("x", encoding="utf-8")
    r = run(root / "h.duckdb", "view", "--all", folder, "--silent", code=1)
    assert "index.html" in r.output and "did not write" in r.output
    assert sorted(p.name for p in folder.iterdir()) == ["index.html", "notes.txt"]
    assert (folder / "index.html").read_text(encoding="utf-8") == "my own index"
    # a symbolic link of a page's name is not written through
    other = tmp_path / "other"
    other.mkdir()
    outside = tmp_path / "outside.html"
    outside.write_text("outside", encoding="utf-8")
    (other / "index.html").symlink_to(outside)
    run(root / "h.duckdb", "view", "--all", other, "--silent", code=1)
    assert outside.read_text(encoding="utf-8") == "outside"


@pytest.mark.shared
def test_a_motion_named_index_keeps_its_page(hostile_db, tmp_path, open_db):
    root, names = hostile_db
    written = mocapdb.view(open_db(root / "h.duckdb", read_only=True), all=tmp_path / "p")
    by_motion = {json.loads(p.read_text(encoding="utf-8").split('id="mocapdb-data">', 1)[1]
                            .split("</script>", 1)[0])["name"]: p.name for p in written[1:]}
    assert written[0].name == "index.html"
    assert by_motion["index"] == "index_3.html" and by_motion["INDEX"] == "INDEX_4.html"
    assert by_motion["../../ESCAPED_VIEW"] == "_.._ESCAPED_VIEW.html"
    assert by_motion["CON"] == "_CON.html"


@pytest.mark.slow
@pytest.mark.shared
def test_annotate_eaf_files_stay_in_their_folder(hostile_db, tmp_path):
    root, names = hostile_db
    before = _files(root.parent)
    out = tmp_path / "eaf"
    run(root / "h.duckdb", "annotate", "--format", "eaf", "--out", out, "--silent")
    files = sorted(out.iterdir())
    assert _files(root.parent) - before == set(files)
    assert len(files) == len(names) and all(p.parent == out and p.suffix == ".eaf" for p in files)
    from mocapdb.annotation.elan import read_eaf

    assert all(read_eaf(p, fps=120) is not None for p in files)
