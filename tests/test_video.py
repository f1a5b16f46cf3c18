"""A motion's stick figure as the video ELAN plays beside its tiers (issue 33 item 9).

The drawing kernel against a plain-numpy twin, pixel for pixel; framing that
keeps every joint inside the picture for a take with large vertical motion
and one without root translation; and ``annotate --format eaf --video`` end
to end on the shipped CMU take: an H.264 MP4 of one frame per 30 Hz feature
frame, linked in the ``.eaf`` as ``video/mp4``, the file reading back onto its
document and segments.
"""
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocapdb.annotation import read_eaf
from mocapdb.readers import read_motion
from mocapdb.viewer import BONES
from mocapdb.viewer.video import HEIGHT, WIDTH, _BACKGROUND, _RADII, draw_frames, picture_coordinates

from conftest import SAMPLE_86_09, SAMPLE_86_ASF, run



@pytest.fixture(scope="module")
def joints():
    """The shipped CMU take's joints on its 30 Hz grid (every 4th 120 Hz frame), the first 300."""
    return read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF).joints[::4][:300]


def _naive_frame(uv, floor, f, n_total):
    """One frame drawn the slow, obvious way: every disc of every stamp as a numpy mask."""
    frame = np.empty((HEIGHT, WIDTH, 3), np.uint8)
    frame[:] = _BACKGROUND
    rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH]
    row = int(round(floor)) + 2
    if 0 <= row < HEIGHT:
        frame[row, :] = (170, 170, 170)
    frame[HEIGHT - 4:, :int(WIDTH * (f + 1) / n_total)] = (120, 160, 210)

    def stamp(x, y, radius, color):
        cx, cy = int(round(x)), int(round(y))
        frame[((cols - cx) ** 2 + (rows - cy) ** 2 <= radius * radius)] = color

    for a, b in BONES:
        (x0, y0), (x1, y1) = uv[f, a], uv[f, b]
        steps = int(max(abs(x1 - x0), abs(y1 - y0)) * 2) + 1
        for s in range(steps + 1):
            t = s / steps
            stamp(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, _RADII[0], (40, 70, 130))
    for x, y in uv[f]:
        stamp(x, y, _RADII[1], (200, 80, 40))
    return frame


def test_the_kernel_draws_what_its_naive_twin_draws(joints):
    uv, floor = picture_coordinates(joints)
    frames = draw_frames(joints, first=100, count=3)
    for k in range(3):
        assert np.array_equal(frames[k], _naive_frame(uv, floor, 100 + k, len(joints)))


def _inside(uv):
    return (uv[..., 0] >= 0).all() and (uv[..., 0] < WIDTH).all() and (uv[..., 1] >= 0).all() \
        and (uv[..., 1] < HEIGHT).all()


def test_every_joint_stays_in_the_picture_whatever_the_take_does(joints):
    uv, _ = picture_coordinates(joints)
    assert _inside(uv)
    # a dance-like take: the body thrown 3 m up and down and carried 10 m sideways over the take
    t = np.linspace(0, 4 * np.pi, len(joints))[:, None]
    wild = joints.copy()
    wild[..., 1] += 3.0 * np.abs(np.sin(t))
    wild[..., 0] += 10.0 * t / t.max()
    uv, floor = picture_coordinates(wild)
    assert _inside(uv)
    # the body fills the picture's height at its highest and lowest, not a speck
    assert np.ptp(uv[..., 1]) > 0.7 * HEIGHT and floor <= HEIGHT
    # a take without root translation (the root pinned at the origin), upside down
    pinned = (joints - joints[:, :1]) * np.array([1.0, -1.0, 1.0])
    uv, _ = picture_coordinates(pinned)
    assert _inside(uv)
    # every frame draws the figure: not a blank picture
    frames = draw_frames(wild, first=0, count=len(wild))
    assert all((f != _BACKGROUND).any(axis=-1).sum() > 500 for f in frames)


@pytest.mark.slow
def test_annotate_writes_an_elan_file_with_a_video_that_plays_in_step(tmp_path):
    if shutil.which("ffmpeg") is None:
        pytest.fail("ffmpeg is needed (Debian: apt-get install ffmpeg; .ci/run installs it)")
    db = tmp_path / "a.duckdb"
    run(db, "ingest", str(SAMPLE_86_09), "--asf", str(SAMPLE_86_ASF), "--silent")
    out = tmp_path / "elan" / "86_09.eaf"
    out.parent.mkdir()
    run(db, "annotate", "86_09", "--format", "eaf", "--video", "--out", str(out), "--silent")
    video = out.with_suffix(".mp4")
    probe = json.loads(subprocess.run(
        ["ffprobe", "-v", "error", "-count_frames", "-show_streams", "-of", "json", str(video)],
        capture_output=True, text=True, check=True).stdout)["streams"][0]
    with __import__("mocapdb").connect(db, read_only=True) as con:
        n_frames = con.execute("SELECT n_frames FROM motions WHERE name = '86_09'").fetchone()[0]
    assert probe["codec_name"] == "h264" and probe["pix_fmt"] == "yuv420p"
    assert (int(probe["width"]), int(probe["height"])) == (WIDTH, HEIGHT)
    assert int(probe["nb_read_frames"]) == n_frames and probe["r_frame_rate"] == "30/1"
    text = out.read_text(encoding="utf-8")
    assert 'MIME_TYPE="video/mp4"' in text and f'RELATIVE_MEDIA_URL="./{video.name}"' in text.replace(
        f'RELATIVE_MEDIA_URL="{video.name}"', f'RELATIVE_MEDIA_URL="./{video.name}"')
    # the recording stays the first media: the file reads back onto its document and segments
    truth = read_eaf(out)
    assert {row[0] for row in truth} == {"86_09"} and truth
    # a frame of the video shows the figure
    raw = subprocess.run(["ffmpeg", "-v", "error", "-i", str(video), "-vf", "select=eq(n\\,200)", "-frames:v", "1",
                          "-f", "rawvideo", "-pix_fmt", "rgb24", "-"], capture_output=True, check=True).stdout
    frame = np.frombuffer(raw, np.uint8).reshape(HEIGHT, WIDTH, 3).astype(int)
    assert (np.abs(frame - _BACKGROUND.astype(int)).sum(axis=-1) > 60).sum() > 500


def test_video_needs_eaf_and_ffmpeg(tmp_path, monkeypatch):
    db = tmp_path / "a.duckdb"
    run(db, "ingest", str(SAMPLE_86_09), "--asf", str(SAMPLE_86_ASF), "--silent")
    r = run(db, "annotate", "--format", "csv", "--video", "--out", str(tmp_path / "x.csv"), code=2)
    assert "--video goes with --format eaf" in r.output
    monkeypatch.setenv("PATH", str(tmp_path))  # no ffmpeg here
    r = run(db, "annotate", "--format", "eaf", "--video", "--out", str(tmp_path / "e"), code=1)
    assert "Error: a video needs ffmpeg on PATH" in r.output
    assert not (tmp_path / "e").exists()  # said before anything was written
