"""The user's SMPL-family body model: the rest joints of a take's own body.

A body model file (the ``model.npz`` of SMPL-H, the ``SMPLX_*.npz`` of
SMPL-X, an SMPL ``.npz``; downloaded by the user under the model's licence,
never shipped) gives the rest joints of a body shape ``β``:
``J = J_regressor · (v_template + shapedirs · β)``. The end points that
SMPL lacks as joints come from the same shaped mesh, by geometry alone: the
toe tips are the foremost vertex of each foot (below its ankle, on its side
of the pelvis), the head top the highest vertex; the finger points are the
joints that end the palm (SMPL's hand joint, SMPL-H/X's middle finger base).

``--body-model PATH`` names one model file, used for every take of its
family, or a folder of them: a take then gets the model of its family and
its gender, chosen by the words of the files' paths (``smplh/female/model.npz``,
``SMPLX_NEUTRAL.npz``), the neutral model when its gender has none
(READERS.md §9).

References
----------
READERS.md §9; Loper et al. 2015 (SMPL); Romero et al. 2017 (SMPL-H, MANO);
Pavlakos et al. 2019 (SMPL-X).
"""
from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocapdb.errors import ParseError
from mocapdb.bodies.smpl import BODY_PARENTS, FAMILIES, RestSkeleton
from mocapdb.readers.sources import FileCache

__all__ = ["BodyModel", "load_body_model", "find_body_model", "GENDERS"]

#: the genders a take may name (AMASS writes them lower case)
GENDERS = ("male", "female", "neutral")
_N_BODY = len(BODY_PARENTS)
_JOINT_COUNTS = {v[2]: k for k, v in FAMILIES.items()}
_LEFT_ANKLE, _RIGHT_ANKLE = 7, 8


@dataclass(frozen=True, eq=False)
class BodyModel:
    """What mocapdb keeps of a body model file: the rest joints and end points as linear functions of β.

    Attributes
    ----------
    path : str
    family : str
        ``"smpl"``, ``"smplh"`` or ``"smplx"`` (from its number of joints).
    gender : str or None
        As its path names it (``male``, ``female``, ``neutral``), else None.
    n_shape : int
        Shape components (β) it has.
    points : ndarray, shape (27, 3), float64
        At β = 0: the 22 body joints, then the end points in
        :data:`~mocapdb.bodies.smpl.END_POINTS` order.
    directions : ndarray, shape (27, 3, n_shape), float64
        How each point moves per unit of each β.
    """

    path: str
    family: str
    gender: str | None
    n_shape: int
    points: np.ndarray
    directions: np.ndarray

    def rest(self, betas) -> RestSkeleton:
        """The rest skeleton of the body shape ``betas`` (its first ``n_shape`` values are used)."""
        b = np.zeros(self.n_shape)
        k = min(len(betas), self.n_shape)
        b[:k] = np.asarray(betas, dtype=np.float64)[:k]
        pts = self.points + self.directions @ b
        return RestSkeleton(pts[:_N_BODY], pts[_N_BODY:], f"the body model {self.path}")


def _words(path) -> set:
    return set(re.split(r"[^a-z0-9]+", str(path).lower()))


def _gender_of(path) -> str | None:
    found = [g for g in GENDERS if g in _words(path)]
    return found[0] if len(found) == 1 else None


def _array(npz, key, path):
    try:
        return np.asarray(npz[key])
    except KeyError:
        raise ParseError(path, None, f"body model: no {key!r} array (it holds {', '.join(sorted(npz.files))}); "
                         "give the model's .npz (SMPL-H model.npz, SMPLX_*.npz)") from None
    except ValueError as exc:   # a pickled object array
        raise ParseError(path, None, f"body model: {key!r} is not a plain array ({exc})") from None


def _shape_components(family: str, k: int) -> int:
    # SMPL-X keeps its expression components after the shape ones: 10 + 10 (v1.0) or 300 + 100 (v1.1)
    if family == "smplx" and k in (20, 400):
        return k // 2 if k == 20 else 300
    return k


def _read_model(path: Path) -> BodyModel:
    try:
        npz = np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise ParseError(path, None, f"not a body model .npz file ({exc}); a .pkl model must be converted "
                         "to .npz first") from None
    with npz:
        reg = _array(npz, "J_regressor", path).astype(np.float64)
        template = _array(npz, "v_template", path).astype(np.float64)
        dirs = _array(npz, "shapedirs", path).astype(np.float64)
        tree = _array(npz, "kintree_table", path)
    if reg.ndim != 2 or reg.shape[0] not in _JOINT_COUNTS:
        raise ParseError(path, None, f"body model: J_regressor has shape {reg.shape}; expected 24 (SMPL), "
                         "52 (SMPL-H) or 55 (SMPL-X) joints by vertices")
    family = _JOINT_COUNTS[reg.shape[0]]
    n_vert = reg.shape[1]
    if template.shape != (n_vert, 3) or dirs.ndim != 3 or dirs.shape[:2] != (n_vert, 3):
        raise ParseError(path, None, f"body model: v_template {template.shape} and shapedirs {dirs.shape} do "
                         f"not fit J_regressor {reg.shape} (expected ({n_vert}, 3) and ({n_vert}, 3, k))")
    parents = np.asarray(tree, dtype=np.int64).reshape(2, -1)[0] if tree.size == 2 * reg.shape[0] else None
    if parents is None or [int(p) for p in parents[1:_N_BODY]] != list(BODY_PARENTS[1:]):
        raise ParseError(path, None, f"body model: its kintree_table is not the SMPL family's kinematic tree "
                         f"({FAMILIES[family][0]}, {reg.shape[0]} joints)")
    if not (np.isfinite(reg).all() and np.isfinite(template).all() and np.isfinite(dirs).all()):
        raise ParseError(path, None, "body model: non-finite values in J_regressor, v_template or shapedirs")
    n_shape = _shape_components(family, dirs.shape[2])
    dirs = dirs[:, :, :n_shape]
    rows = [*range(_N_BODY), *FAMILIES[family][3]]
    joints = reg[rows] @ template
    jdirs = np.einsum("jv,vxk->jxk", reg[rows], dirs)
    tips = _tip_vertices(template, joints, path)
    # in END_POINTS order: the toe tips, the head top, the finger points
    points = np.concatenate([joints[:_N_BODY], template[tips[:2]], template[tips[2:]], joints[_N_BODY:]])
    directions = np.concatenate([jdirs[:_N_BODY], dirs[tips[:2]], dirs[tips[2:]], jdirs[_N_BODY:]])
    return BodyModel(str(path), family, _gender_of(path), n_shape, points, directions)


def _tip_vertices(template, joints, path) -> np.ndarray:
    """Vertex indices of the left toe tip, the right toe tip and the head top (at β = 0).

    The body's own frame: Y up, facing +Z, its left at +X. A toe tip is the
    foremost vertex below the ankle on that side of the pelvis; the head top
    the highest vertex.
    """
    x, y, z = template[:, 0], template[:, 1], template[:, 2]
    out = []
    for ankle, side in ((_LEFT_ANKLE, 1.0), (_RIGHT_ANKLE, -1.0)):
        foot = np.flatnonzero((side * (x - joints[0, 0]) > 0.0) & (y < joints[ankle, 1]))
        if foot.size == 0:
            raise ParseError(path, None, "body model: no vertex below an ankle (is it an SMPL-family model "
                             "standing Y up?)")
        out.append(int(foot[np.argmax(z[foot])]))
    out.append(int(np.argmax(y)))
    return np.array(out, dtype=np.int64)


# models are large (SMPL-X: ~100 MB of shape directions) and shared by every take of an ingest:
# keep what is needed of each, by file identity
_MODELS = FileCache(8)


def load_body_model(path) -> BodyModel:
    """A body model file, read once per file identity (path, size, modification time).

    Raises
    ------
    ParseError
        Not an SMPL-family ``.npz`` model (the message names the file and
        what is missing or wrong).
    OSError
        The file cannot be read.
    """
    return _MODELS.get(Path(path), _read_model)


def find_body_model(path, family: str, gender: str | None, *, take="<take>"):
    """The body model for a take of ``family`` and ``gender``: ``(BodyModel, notes)``.

    Parameters
    ----------
    path : str or Path
        A model file (used whatever the take's gender; it must be of the
        take's family), or a folder searched (recursively) for ``.npz`` files
        whose path names the family (``smplh``, ``smplx``, ``smpl``) and the
        gender (``male``, ``female``, ``neutral``): the take's gender first,
        else the neutral model (noted).
    family : str
    gender : str or None
        The take's (None: not given, read as neutral).
    take : str or Path, keyword-only
        The take's file, named in errors.

    Raises
    ------
    ParseError
        No model of the family (and gender or neutral) in the folder, or a
        model file of another family; the message names the take and the model.
    """
    p = Path(path)
    name = FAMILIES[family][0]
    notes = []
    if p.is_dir():
        found = sorted(q for q in p.rglob("*.npz") if not any(part.startswith(".") for part in q.parts)
                       and family in _words(q))
        wanted = gender if gender in GENDERS else "neutral"
        exact = [q for q in found if _gender_of(q) == wanted]
        neutral = [q for q in found if _gender_of(q) == "neutral"]
        if exact:
            file = exact[0]
        elif neutral:
            file = neutral[0]
            notes.append(f"no {wanted} {name} body model in {p}: the neutral one used")
        else:
            raise ParseError(take, None, f"no {name} body model for gender {wanted!r} (nor a neutral one) in "
                             f"{p} (looked for .npz files whose path names {family} and the gender, as "
                             f"{family}/{wanted}/model.npz)")
    else:
        file = p
    try:
        model = load_body_model(file)
    except OSError as exc:
        raise ParseError(file, None, f"cannot read the body model of {take} ({exc.strerror or exc})") from None
    if model.family != family:
        raise ParseError(take, None, f"the body model {file} is {FAMILIES[model.family][0]} "
                         f"({FAMILIES[model.family][2]} joints) and this take is {name}; give the {name} model "
                         "(or a folder of models: --body-model DIR)")
    if p.is_file() and gender in ("male", "female") and model.gender not in (None, gender):
        notes.append(f"the take is {gender}; the body model {file} is {model.gender}: used as given")
    return model, notes
