"""Made-up SMPL-family files for the tests: AMASS-format takes changed array by array, and body
models of the SMPL family's array layout built around a rest skeleton (none of SMPL's numbers)."""
import numpy as np

from mocapdb.bodies.smpl import BODY_PARENTS, FAMILIES


def rewrite(path, out, **changes):
    """The arrays of ``path`` with some replaced (None: removed), saved as ``out``."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k, None)
        else:
            arrays[k] = v
    np.savez(out, **arrays)
    return out


def make_body_model(path, rest, *, family="smplh", seed=0, n_shape=16):
    """A made-up body model of the SMPL family's array layout: per joint four vertices around the
    rest joint (their mean is the joint: the regressor averages them), a vertex at each toe tip and
    one at the head top, random shape directions. Returns the arrays written."""
    rng = np.random.default_rng(seed)
    n_joints = FAMILIES[family][2]
    fingers = FAMILIES[family][3]
    first_hand = 25 if family == "smplx" else 22       # SMPL-X: jaw and eyes on the head first
    per_hand = (n_joints - first_hand) // 2
    parents = [*BODY_PARENTS, *[15] * (first_hand - 22), *[20] * per_hand, *[21] * per_hand]
    joints = np.empty((n_joints, 3))
    joints[:22] = rest.joints
    for k in range(22, n_joints):   # near their wrist or the head
        joints[k] = joints[parents[k]] + rng.normal(scale=0.02, size=3)
    joints[list(fingers)] = rest.ends[3:]
    verts, rows = [], []
    for k in range(n_joints):
        off = rng.normal(scale=0.004, size=(4, 3))
        off -= off.mean(axis=0)
        rows.append(range(len(verts), len(verts) + 4))
        verts.extend(joints[k] + off)
    verts.extend(rest.ends[:3])   # the toe tips, the head top
    verts = np.array(verts)
    reg = np.zeros((n_joints, len(verts)))
    for k, r in enumerate(rows):
        reg[k, list(r)] = 0.25
    # SMPL-X (v1.1) keeps 100 expression directions after 300 shape ones
    dirs = rng.normal(scale=0.01, size=(len(verts), 3, 400 if family == "smplx" else n_shape))
    tree = np.array([[2 ** 32 - 1, *parents[1:]], list(range(n_joints))], dtype=np.int64)
    arrays = {"J_regressor": reg, "v_template": verts, "shapedirs": dirs, "kintree_table": tree,
              "f": np.zeros((1, 3), np.int64)}
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)
    return arrays
