"""Near-duplicate takes are flagged (issue 33): the ``duplicates`` view lists a real take and its twin written in
metres instead of centimetres (the features do not depend on the unit), and no pair of different takes."""
import gzip

import pytest

import mocapdb

from conftest import DATA

pytestmark = pytest.mark.shared  # real takes of ../shared/data/accad_dev and cmu

TAKES = [DATA / "accad_dev" / name for name in ("Male1_A3_SwingArms.bvh.gz", "Male1_C20_Run2Jump2Walk.bvh.gz",
                                                "Male1_B7_WalkBackTurnForward.bvh.gz")]


def _in_metres(src, out):
    """``src`` (a centimetre BVH) with every offset and the root's positions in metres: the same take."""
    text = gzip.decompress(src.read_bytes()).decode("latin-1")
    head, _, motion = text.partition("MOTION")
    lines = []
    for ln in head.splitlines():
        if ln.strip().startswith("OFFSET"):
            indent = ln[:len(ln) - len(ln.lstrip())]
            ln = indent + "OFFSET " + " ".join(f"{float(v) / 100:.7f}" for v in ln.split()[1:])
        lines.append(ln)
    rows = motion.strip().splitlines()
    frames = []
    for ln in rows[2:]:
        v = ln.split()
        frames.append(" ".join([f"{float(x) / 100:.7f}" for x in v[:3]] + v[3:]))
    out.write_text("\n".join(lines) + "\nMOTION\n" + "\n".join(rows[:2] + frames) + "\n")
    return out


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    root = tmp_path_factory.mktemp("duplicates")
    twin = _in_metres(TAKES[0], root / "swing_arms_in_metres.bvh")
    path = root / "dup.duckdb"
    with mocapdb.connect(path) as con:
        report = mocapdb.ingest(con, [*TAKES, twin, *sorted((DATA / "cmu" / "02").glob("02_0[12].amc"))])
        assert not report.failed
    return path


def test_a_take_and_its_twin_in_metres_are_flagged(db):
    with mocapdb.connect(db, read_only=True) as con:
        rows = con.execute("SELECT name, duplicate_name, n_frames, agreement FROM duplicates").fetchall()
        n = con.execute("SELECT count(*) FROM motions").fetchall()[0][0]
    assert n == 6
    assert len(rows) == 1, rows
    name, twin, frames, agreement = rows[0]
    assert {name, twin} == {"Male1_A3_SwingArms", "swing_arms_in_metres"} and frames > 100
    assert agreement >= 0.99


def test_the_view_compares_every_frame(db):
    """A pair agreeing on its 16 sketch frames but not on 99 % of all frames is not a duplicate: the view's
    answer is the full comparison's, made here in Python over the stored words."""
    with mocapdb.connect(db) as con:
        mid = con.execute("SELECT motion_id FROM motions WHERE name = 'swing_arms_in_metres'").fetchall()[0][0]
        n = con.execute("SELECT n_frames FROM motions WHERE motion_id = ?", [mid]).fetchall()[0][0]
        # flip one feature on 2 % of the twin's frames, none of them a sketch frame
        sketch = {1 + (k * (n - 1)) // 15 for k in range(16)}
        flip = [f for f in range(2, n, 7) if f not in sketch][: int(0.02 * n) + 1]
        con.execute("UPDATE features SET bits = xor(bits, 1::UBIGINT) WHERE motion_id = ? AND list_contains(?, frame)",
                    [mid, flip])
        assert con.execute("SELECT count(*) FROM duplicates").fetchall()[0][0] == 0
        # back to 0.5 % of the frames: a near-duplicate again, its agreement what a frame count says
        keep = flip[: int(0.005 * n)]
        con.execute("UPDATE features SET bits = xor(bits, 1::UBIGINT) WHERE motion_id = ? AND list_contains(?, frame)"
                    " AND NOT list_contains(?, frame)", [mid, flip, keep])
        (agreement,) = con.execute("SELECT agreement FROM duplicates").fetchall()[0]
        assert agreement == pytest.approx(1 - len(keep) / n)
