"""A take of any length, in bounded blocks (issue 27 item 3).

A 1,000,000-frame BVH (9 h at 30 fps) peaked at 5.1 GB: its channel values,
joints, the joints resampled to 120 Hz and every feature array were whole.
Now the BVH's channels are parsed, put through forward kinematics and
dropped a block of lines at a time, and the features of a long take are
computed a block of 120 Hz frames at a time (the velocity windows see their
context, the hysteresis runs on). The words must be the whole take's, bit for
bit: checked here on the shipped recordings with tiny blocks, at their own
rate and decimated to other rates; the memory figures of the 9-hour take are
in benchmarks/RESULTS.md (bench_long_take.py).
"""
import lzma
import tracemalloc

import numpy as np
import pytest

import mocapdb.features.pipeline as pipeline
import mocapdb.readers.bvh as bvh_module
import mocapdb.readers.c3d as c3d_module
import mocapdb.readers.c3dfile as c3dfile
from mocapdb.errors import ParseError
from mocapdb.features import motion_features
from mocapdb.bodies import Motion
from mocapdb.writers import euler_angles
from mocapdb.readers import read_c3d, read_motion
from mocapdb.bodies.kinematics import euler_matrix
from mocapdb.readers.sources import bytes_file, motion_stem, open_stream, stream_size

from conftest import SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, SAMPLE_C3D


@pytest.fixture(scope="module")
def sample_motions():
    return [read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF), read_motion(SAMPLE_BVH), read_motion(SAMPLE_C3D)]


def decimated(m: Motion, step: int, fps: float, rotation=True) -> Motion:
    """Every ``step``-th frame of a real take, labelled ``fps``: a take at another rate."""
    rot = m.root_rotation[::step] if (rotation and m.root_rotation is not None) else None
    return Motion(joints=np.ascontiguousarray(m.joints[::step]), root_rotation=rot, fps=fps, name=m.name)


@pytest.mark.slow
def test_features_by_block_are_the_whole_takes_bit_for_bit(sample_motions, monkeypatch):
    takes = list(sample_motions)
    amc = sample_motions[0]   # 4,794 frames at 120 Hz with a root rotation
    takes += [decimated(amc, 2, 60.0), decimated(amc, 4, 30.0), decimated(amc, 5, 24.0, rotation=False),
              decimated(amc, 1, 100.0), decimated(amc, 3, 29.97)]
    for take in takes:
        whole = motion_features(take)
        for block in (12, 257):
            monkeypatch.setattr(pipeline, "BLOCK_FRAMES", block)
            np.testing.assert_array_equal(motion_features(take), whole, err_msg=f"{take.name} at {take.fps} Hz, "
                                                                                 f"blocks of {block}")
        monkeypatch.undo()
        assert whole.any()


def test_a_long_takes_features_hold_a_block_not_the_take(sample_motions, monkeypatch):
    """The 120 Hz joints of a 30 fps take are 4 × its own; by blocks, features hold a block's arrays."""
    amc = sample_motions[0]
    long = Motion(joints=np.ascontiguousarray(np.tile(amc.joints[::4], (8, 1, 1))), root_rotation=None, fps=30.0)
    motion_features(long)   # compile
    resampled = 4 * long.joints.nbytes
    tracemalloc.start()
    motion_features(long)
    whole = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    monkeypatch.setattr(pipeline, "BLOCK_FRAMES", 2048)
    tracemalloc.start()
    by_block = motion_features(long)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert whole > resampled   # the whole take's path holds the resampled joints and more
    assert peak < resampled / 4, (peak, resampled)
    monkeypatch.undo()
    np.testing.assert_array_equal(by_block, motion_features(long))


def _whole_reading(path):
    """The BVH read with every channel value in memory (the path a take with lost tracking takes)."""
    with open_stream(path) as fh:
        data = bvh_module.parse_bvh_stream(fh, path=path, size=stream_size(path))
    return bvh_module.bvh_to_motion(data, name=motion_stem(path))


@pytest.mark.slow
def test_a_bvh_is_read_a_block_of_lines_at_a_time_as_if_whole(tmp_path, monkeypatch):
    text = lzma.decompress(SAMPLE_BVH.read_bytes())
    head, _, body = text.partition(b"MOTION")
    lines = body.split(b"\n")
    frames = [ln for ln in lines[3:] if ln.strip()]
    plain = tmp_path / "walk.bvh"
    plain.write_bytes(text)
    # the same walk recorded Z-up (turned back to Y up block by block), and with lost tracking
    # (mended on the whole take's channels)
    data = bvh_module.parse_bvh(text)
    root = data.hierarchy.joints[0]
    assert root.channels[:3] == ("Xposition", "Yposition", "Zposition")
    order = "".join(c[0].lower() for c in root.channels[3:6])
    vals = data.values.copy()
    r0 = euler_matrix(np.array([[np.pi / 2, 0.0, 0.0]]), "xyz")[0]  # +Y -> +Z
    pos, rot = [root.channel_start + i for i in range(3)], [root.channel_start + 3 + i for i in range(3)]
    vals[:, pos] = vals[:, pos] @ r0.T
    vals[:, rot] = np.degrees(euler_angles(r0 @ euler_matrix(np.radians(vals[:, rot]), order), order))
    z_up = tmp_path / "z_up.bvh"
    z_up.write_bytes(head + b"MOTION\n" + lines[1] + b"\n" + lines[2] + b"\n"
                     + "\n".join(" ".join(f"{x:.17g}" for x in row) for row in vals).encode() + b"\n")
    turned, upright = read_motion(z_up).joints, read_motion(plain).joints   # turned Y up (the root's OFFSET aside)
    np.testing.assert_allclose(turned - turned[:, :1], upright - upright[:, :1], atol=1e-6)
    lost = tmp_path / "lost.bvh"
    broken = list(frames)
    broken[500] = b" ".join([b"nan"] * len(frames[500].split()))
    lost.write_bytes(head + b"MOTION\n" + lines[1] + b"\n" + lines[2] + b"\n" + b"\n".join(broken) + b"\n")
    monkeypatch.setattr(bvh_module, "_READ_BLOCK", 1 << 12)
    for path in (plain, SAMPLE_BVH, z_up, lost):
        whole, streamed = _whole_reading(path), read_motion(path)
        np.testing.assert_array_equal(streamed.joints, whole.joints)
        assert streamed.meta == whole.meta and streamed.fps == whole.fps and streamed.skeleton == whole.skeleton
        assert (streamed.root_rotation is None) == (whole.root_rotation is None)
        if whole.root_rotation is not None:
            np.testing.assert_array_equal(streamed.root_rotation, whole.root_rotation)
    assert read_motion(lost).meta["notes"]   # the whole-take path, with its note
    # the read holds the joints, not the channel values as well
    long = tmp_path / "long.bvh"
    long.write_bytes(head + b"MOTION\nFrames: %d\n" % (16 * len(frames)) + lines[2] + b"\n"
                     + b"\n".join(frames * 16) + b"\n")
    read_motion(long)
    tracemalloc.start()
    motion = read_motion(long)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    values = 16 * len(frames) * len(frames[0].split()) * 8
    joints = motion.joints.nbytes + 9 * 8 * motion.n_frames
    assert values > joints / 2
    assert peak < joints + values / 4, (peak, joints, values)


def dense_c3d(path, extra: int, frames: int, *, unnamed=False):
    """The shipped HDM05 C3D cut to ``frames`` frames, with ``extra`` markers more (copies of its 44, each
    moved a few cm, named X0000 …): a dense marker set (``unnamed``: its own 44 renamed too)."""
    import ezc3d

    with bytes_file(lzma.decompress(SAMPLE_C3D.read_bytes()), "mm.c3d") as name:
        src = ezc3d.c3d(str(name))
    pts = src["data"]["points"][:, :, :frames]
    labels = list(src["parameters"]["POINT"]["LABELS"]["value"])
    rng = np.random.default_rng(27)
    copies = rng.integers(0, pts.shape[1], extra)
    moved = pts[:, copies].copy()
    moved[:3] += rng.normal(0, 30, (3, extra, 1))
    out = ezc3d.c3d()
    out["parameters"]["POINT"]["RATE"]["value"] = [120]
    out["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    out["parameters"]["POINT"]["LABELS"]["value"] = ([f"Y{k:04d}" for k in range(len(labels))] if unnamed else labels) \
        + [f"X{k:04d}" for k in range(extra)]
    out["data"]["points"] = np.concatenate([pts, moved], axis=1)
    out.write(str(path))
    return path


@pytest.mark.slow
def test_a_dense_c3d_is_read_a_block_of_frames_at_a_time_holding_the_usable_markers(tmp_path, monkeypatch):
    """ezc3d holds ~200 bytes a point (a 5,000-marker take of 4,000 frames: 4 GB). A large take goes to
    it a block of frames at a time, and only the markers a rule or the map can use stay: the same
    joints, notes and refusals as reading every point of the whole file."""
    path = dense_c3d(tmp_path / "dense.c3d", 300, 600)
    all_points = c3dfile.read_c3d_points(path)
    assert len(all_points.labels) == 344
    real = c3dfile.read_c3d_points
    monkeypatch.setattr(c3d_module, "read_c3d_points", lambda p, keep=None: real(p))   # every point, whole
    whole = {rules: read_c3d(path, marker_rules=rules) for rules in ("toolbox", "anatomical")}
    tracemalloc.start()
    read_c3d(path)
    whole_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    monkeypatch.undo()
    monkeypatch.setattr(c3dfile, "BLOCK_POINTS", 5000)   # blocks of 14 frames
    blocks = c3dfile.read_c3d_points(path)
    for field in ("xyz", "valid"):
        np.testing.assert_array_equal(getattr(blocks, field), getattr(all_points, field))
    assert blocks.labels == all_points.labels and blocks.meta == all_points.meta
    for rules, motion in whole.items():
        got = read_c3d(path, marker_rules=rules)
        np.testing.assert_array_equal(got.joints, motion.joints)
        assert got.meta == motion.meta and got.skeleton == motion.skeleton
    # a marker map's names are held too; a refusal still lists every marker of the file
    mapped = read_c3d(path, marker_map={"lknee": "X0007"})
    assert mapped.skeleton == "c3d:marker_map"
    with pytest.raises(ParseError, match=r"cannot place root, .* from the markers Y0000, .*\(12 of 344\)"):
        read_c3d(dense_c3d(tmp_path / "unnamed.c3d", 300, 100, unnamed=True))
    tracemalloc.start()
    read_c3d(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < whole_peak / 4, (peak, whole_peak)
