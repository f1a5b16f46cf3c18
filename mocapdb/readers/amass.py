"""AMASS and other SMPL-family ``.npz`` motions → the 24 canonical joints.

AMASS re-solves the world's optical mocap archives (CMU, HDM05, ACCAD,
BMLrub, KIT, …) onto one body model and publishes each take as a NumPy
``.npz``: ``poses`` (n × 156 for SMPL-H, n × 165 for SMPL-X; n × 72 for
SMPL files of other tools), one axis-angle rotation per joint; ``trans``,
the pelvis's translation; ``betas``, the body shape; ``gender``;
``mocap_framerate`` (SMPL-H) or ``mocap_frame_rate`` (SMPL-X). Its world is
Z up. :func:`read_amass` runs forward kinematics over the SMPL tree
(:mod:`~mocapdb.bodies.smpl`) from a rest skeleton — the user's body model
for the take's shape and gender (:mod:`~mocapdb.readers.body_model`), or the
generic one shipped with mocapdb — and turns the body to Y up.

References
----------
READERS.md §9; N. Mahmood et al., AMASS: Archive of Motion Capture as
Surface Shapes, ICCV 2019.
"""
from __future__ import annotations

import io
import tokenize
import zipfile
import zlib
from pathlib import Path

import numpy as np

from mocapdb.errors import ParseError
from mocapdb.readers.body_model import GENDERS, find_body_model
from mocapdb.bodies.humanoid import Z_UP_TO_Y_UP, hip_axis_is_x
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.bodies.motion import Motion, check_finite_motion, check_rate, snap_rate
from mocapdb.bodies.smpl import FAMILIES, smpl_forward_kinematics
from mocapdb.readers.generic_body import generic_rest
from mocapdb.readers.sources import format_size, max_decompressed, motion_stem, plain_file, read_bytes

__all__ = ["read_amass", "RATE_KEYS", "SHAPE_FILE_PATTERNS", "UP_ROTATIONS"]

#: where AMASS (and other SMPL tools) keep the frame rate, in the order looked at
RATE_KEYS = ("mocap_framerate", "mocap_frame_rate", "mocap_fps", "frame_rate", "fps")
#: AMASS's body shape files beside the takes (betas and gender, no motion): not motions
SHAPE_FILE_PATTERNS = ("shape.npz", "*_stagei.npz")
#: the signed axis the body stands along → the rotation that stands it along +Y (never a mirror)
UP_ROTATIONS = {
    "+Z": Z_UP_TO_Y_UP,
    "+Y": np.eye(3),
    "-Z": Z_UP_TO_Y_UP.T,
    "-Y": np.diag([1.0, -1.0, -1.0]),
    "+X": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "-X": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
}
_WIDTHS = {v[1]: k for k, v in FAMILIES.items()}
#: what a damaged .npz raises: the zip layer, a deflated stream, NumPy's array header (parsed as a Python
#: literal: a SyntaxError, a tokenize error), a shape beyond memory
_DAMAGED = (zipfile.BadZipFile, EOFError, zlib.error, ValueError, OSError, SyntaxError, tokenize.TokenError,
            MemoryError)


class _Arrays:
    """The arrays of an ``.npz`` (a file, a zip member or a compressed file), each read when asked."""

    def __init__(self, path):
        self.path = path
        try:
            source = path if plain_file(path) else io.BytesIO(read_bytes(path))
            self.npz = np.load(source, allow_pickle=False)
        except _DAMAGED as exc:   # also a pickle, which np.load refuses with allow_pickle=False
            raise ParseError(path, None, f"not an .npz archive of arrays ({exc})") from None
        if not isinstance(self.npz, np.lib.npyio.NpzFile):
            raise ParseError(path, None, "a single .npy array, not an .npz archive of named arrays")
        # an .npz is a zip: deflated arrays (np.savez_compressed) are decompressed as any compressed
        # recording is, so they are held to the same cap (READERS.md §7), by their declared sizes (zipfile
        # stops a member there)
        inflated = sum(i.file_size for i in self.npz.zip.infolist() if i.compress_type != zipfile.ZIP_STORED)
        if inflated > max_decompressed():
            self.npz.close()
            raise ParseError(path, None, f"its compressed arrays decompress to {format_size(inflated)}, more than "
                             f"{format_size(max_decompressed())}, the cap on a recording's decompressed bytes (a "
                             "compression bomb?); a larger cap: ingest --max-decompressed SIZE")
        self.keys = set(self.npz.files)

    def get(self, key, *, numeric=False):
        """The array ``key``, or None; ``numeric``: refused unless its values are numbers."""
        if key not in self.keys:
            return None
        try:
            arr = np.asarray(self.npz[key])
            if numeric and arr.dtype.kind not in "fiub":
                raise ParseError(self.path, None, f"array {key!r} holds {arr.dtype} values, not numbers")
            return arr
        except _DAMAGED as exc:
            if "allow_pickle" in str(exc):   # an object array: reading it would unpickle
                raise ParseError(self.path, None, f"array {key!r} holds Python objects (pickled), which mocapdb "
                                 f"does not load") from None
            raise ParseError(self.path, None, f"damaged .npz archive: array {key!r} cannot be read ({exc})") from None

    def close(self):
        self.npz.close()


def _scalar(value, key, path):
    if value is None:
        return None
    if value.size != 1:
        raise ParseError(path, None, f"{key!r} has shape {value.shape}; expected one value")
    try:
        v = value.reshape(-1)[0].item()
        if isinstance(v, str):   # NumPy's str scalar, as a plain str (may fail: a damaged array)
            v = "".join(v)
    except (SystemError, UnicodeError) as exc:   # a damaged text array: code points no string can hold
        raise ParseError(path, None, f"{key!r} is not readable text ({exc})") from None
    return v.decode("latin-1") if isinstance(v, bytes) else v


def _float(value, key, path) -> float:
    v = _scalar(value, key, path)
    try:
        return float(v)
    except (TypeError, ValueError):
        raise ParseError(path, None, f"{key!r} is {v!r}; expected a number") from None


def _gender(arrays, notes):
    raw = _scalar(arrays.get("gender"), "gender", arrays.path)
    if raw is None:
        return None
    g = str(raw).strip().lower()
    g = {"m": "male", "f": "female", "n": "neutral"}.get(g, g)
    if g not in GENDERS:
        notes.append(f"gender {str(raw)!r} is none of {', '.join(GENDERS)}: read as neutral")
        return None
    return g


def _pose(arrays, notes):
    """(family, body pose (n, 22, 3)) from ``poses``, or from ``root_orient`` + ``pose_body``."""
    path = arrays.path
    poses = arrays.get("poses", numeric=True)
    if poses is not None:
        if poses.ndim != 2 or poses.shape[1] not in _WIDTHS:
            raise ParseError(path, None, f"poses has shape {poses.shape}; expected n × 72 (SMPL), n × 156 "
                             "(SMPL-H) or n × 165 (SMPL-X) axis-angle values")
        return _WIDTHS[poses.shape[1]], poses[:, :66]
    root, body = arrays.get("root_orient", numeric=True), arrays.get("pose_body", numeric=True)
    if root is not None and body is not None:
        if root.ndim != 2 or root.shape[1] != 3 or body.ndim != 2 or body.shape[1] != 63 \
                or len(root) != len(body):
            raise ParseError(path, None, f"root_orient {root.shape} and pose_body {body.shape}: expected "
                             "n × 3 and n × 63")
        kind = str(_scalar(arrays.get("surface_model_type"), "surface_model_type", path) or "").lower()
        family = kind if kind in FAMILIES else ("smplx" if "pose_jaw" in arrays.keys
                                                else "smplh" if "pose_hand" in arrays.keys else "smpl")
        notes.append("pose from root_orient and pose_body (the file has no poses array)")
        return family, np.concatenate([root, body], axis=1)
    if "betas" in arrays.keys:
        raise ParseError(path, None, "an AMASS body shape file (betas and gender), not a motion: it holds no "
                         "poses")
    raise ParseError(path, None, "not an AMASS motion: no poses array (it holds "
                     + (", ".join(sorted(arrays.keys)) or "no arrays") + ")")


def _signed_axis(v) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] >= 0 else "-") + "XYZ"[k]


def _up_axis(joints) -> str:
    """The signed axis the body stands along: AMASS's +Z, unless the spine (pelvis → neck) points
    along one other axis both in frame 1 and as the median over the take (as the BVH reader judges
    a Z-up file, READERS.md §2): a take lying down for a while keeps AMASS's axis."""
    spine = joints[:, JOINT_INDEX["neck"]] - joints[:, JOINT_INDEX["root"]]
    sample = spine[np.linspace(0, len(spine) - 1, min(len(spine), 257)).astype(np.int64)]
    first, median = _signed_axis(spine[0]), _signed_axis(np.median(sample, axis=0))
    return first if first == median else "+Z"


def read_amass(path, *, body_model=None) -> Motion:
    """Read an AMASS (or other SMPL-family) ``.npz`` motion into the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
        The ``.npz`` (also compressed, or inside a zip archive).
    body_model : str or Path, optional, keyword-only
        An SMPL-H/SMPL-X/SMPL body model ``.npz``, or a folder of them
        (chosen by family and gender, :func:`~mocapdb.readers.body_model.find_body_model`):
        the rest joints are the take's own, ``J_regressor · (v_template +
        shapedirs · betas)``. Default: the generic rest skeleton
        (:func:`~mocapdb.readers.generic_body.generic_rest`).

    Returns
    -------
    Motion
        Joints in metres, Y up; ``root_rotation`` the pelvis's (its x axis is
        the hip axis); ``source_format`` ``"amass"``; ``meta["notes"]`` names
        the rest skeleton used.

    Raises
    ------
    ParseError
        Not an AMASS motion (a shape file, other arrays, a poses width of no
        SMPL family), no translation or frame rate, non-finite values; a
        body model that does not fit.

    References
    ----------
    READERS.md §9.
    """
    path = Path(path)
    arrays = _Arrays(path)
    notes = []
    try:
        family, body = _pose(arrays, notes)
        trans = arrays.get("trans", numeric=True)
        if trans is None:
            trans = arrays.get("transl", numeric=True)
        if trans is None:
            raise ParseError(path, None, "no trans array (the root's translation); an AMASS motion has poses, "
                             "trans, betas, gender and mocap_framerate")
        rate_key = next((k for k in RATE_KEYS if k in arrays.keys), None)
        if rate_key is None:
            raise ParseError(path, None, "no frame rate (mocap_framerate or mocap_frame_rate)")
        rate = _float(arrays.get(rate_key), rate_key, path)
        gender = _gender(arrays, notes)
        betas = arrays.get("betas", numeric=True)
    finally:
        arrays.close()
    n = body.shape[0]
    if n == 0:
        raise ParseError(path, None, "no frames (poses has 0 rows)")
    if trans.shape != (n, 3):
        raise ParseError(path, None, f"trans has shape {trans.shape}; expected ({n}, 3) for the {n} frames of poses")
    fps = check_rate(snap_rate(rate), path)
    body = np.asarray(body, dtype=np.float64)
    trans = np.asarray(trans, dtype=np.float64)
    bad = ~(np.isfinite(body).all(axis=1) & np.isfinite(trans).all(axis=1))
    if bad.any():
        raise ParseError(path, None, "non-finite pose or translation (NaN or inf)", frame=int(np.argmax(bad)) + 1)
    if body_model is None:
        rest = generic_rest()
        how = ("rest skeleton: " + rest.source + "; --body-model gives the take's own body")
    else:
        betas = _betas(betas, path, notes)
        model, more = find_body_model(body_model, family, gender, take=path)
        notes.extend(more)
        rest = model.rest(betas)
        used = min(len(betas), model.n_shape)
        how = (f"rest skeleton: the body model {model.path} ({gender or 'gender not given'}, "
               f"{used} of the take's {len(betas)} betas)")
    notes.insert(0, how)
    joints, pelvis = smpl_forward_kinematics(rest, body.reshape(n, 22, 3), trans)
    up = _up_axis(joints)
    turn = UP_ROTATIONS[up]
    if up != "+Z":
        notes.append(f"the body stands along {up} (AMASS: +Z): {up} read as up")
    joints = np.ascontiguousarray(joints @ turn.T)
    check_finite_motion(joints, path)
    # feature #40 may read the pelvis's rotation: its x axis runs along the hip axis at rest
    rot = turn @ pelvis if hip_axis_is_x(rest.joints[1] - rest.joints[2]) else None
    return Motion(joints=joints, root_rotation=rot, fps=fps, name=motion_stem(path),
                  skeleton=f"{family}:{'generic' if body_model is None else 'body model'}",
                  source_format="amass",
                  meta={"family": family, "gender": gender, "rate_key": rate_key, "up": up, "unit": "m",
                        "rest": rest.source, "frames": (1, n), "notes": notes})


def _betas(betas, path, notes) -> np.ndarray:
    """The take's shape: ``betas`` (k,), or per frame (n, k) averaged (noted); none: the mean shape."""
    if betas is None:
        notes.append("no betas: the body model's mean shape")
        return np.zeros(0)
    b = np.asarray(betas, dtype=np.float64)
    if b.ndim == 2 and b.shape[0] >= 1:
        notes.append(f"betas per frame ({b.shape[0]} × {b.shape[1]}): their mean used")
        b = b.mean(axis=0)
    if b.ndim != 1 or not np.isfinite(b).all():
        raise ParseError(path, None, f"betas of shape {np.asarray(betas).shape} (or non-finite): expected k values")
    return b
