"""The Acclaim skeleton and a take's DOF values: the data the ASF/AMC readers produce and forward
kinematics, the BVH writer and the SMPL rest skeleton consume.

They live in ``bodies`` (below ``readers``), not in the ASF and AMC readers, so that the body
modules work on them without importing a file format (docs/ARCHITECTURE.md: bodies import no
format). :func:`mocapdb.readers.read_asf` builds a :class:`Skeleton`, :func:`mocapdb.readers.read_amc`
an :class:`AmcMotion`.

References
----------
FEATURES.md §1 (units), §2.2 (skeleton nodes); toolbox ``tools/parser/ASFAMCparser/readASF.m``,
``readAMC.m``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Bone", "Skeleton", "AmcMotion", "column_layout", "INCH_TO_TOOLBOX", "ROOT_DOFS", "BONE_DOFS",
           "DEFAULT_FPS"]

#: the toolbox multiplies ASF lengths (after dividing by ``:units length``) by 2.54
INCH_TO_TOOLBOX = 2.54

#: DOF tokens of the root ``order`` line (lower case), in canonical column order
ROOT_DOFS = ("tx", "ty", "tz", "rx", "ry", "rz")

#: rotational DOFs a bone may have; Acclaim also allows tx/ty/tz/l on bones,
#: which the toolbox ignores and we reject (they would silently change nothing)
BONE_DOFS = ("rx", "ry", "rz")

#: toolbox default when an AMC has no ``:SAMPLES-PER-SECOND`` (readAMC.m)
DEFAULT_FPS = 120.0


@dataclass(frozen=True)
class Bone:
    """One ASF bone (a skeleton node; its position is the bone's distal tip).

    Attributes
    ----------
    name : str
    id : int or None
        The ``id`` field (informative only; bones are addressed by name).
    direction : ndarray, shape (3,), float64
        Unit direction in the global rest frame, re-normalised from the file
        (files store 6 significant digits). Zero for a zero direction.
    length : float
        Length in toolbox units (file length / ``:units length`` · 2.54).
    axis : ndarray, shape (3,), float64
        ``axis`` angles as written, in the skeleton's angle unit.
    axis_order : str
        Order token of the ``axis`` line (only ``XYZ`` is accepted).
    dof : tuple of str
        Rotational DOFs in file order, subset of ``("rx", "ry", "rz")``.
    limits : tuple of (float, float)
        ``limits`` pairs as written (informative only).
    parent : str
        Parent bone name, or ``"root"``.
    offset : ndarray, shape (3,), float64
        Bone vector at rest, ``direction · length`` in toolbox units, rounded
        as the toolbox does (``(unit · (length / L)) · 2.54``).
    line : int
        Line of the bone's ``begin`` (for error messages).
    """

    name: str
    id: int | None
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str
    dof: tuple
    limits: tuple
    parent: str
    offset: np.ndarray
    line: int = 0


@dataclass(frozen=True)
class Skeleton:
    """An Acclaim skeleton as read from an ASF file.

    Attributes
    ----------
    name : str
        The ``:name`` field (``"VICON"`` in all CMU/HDM05 files), else the stem.
    bones : tuple of Bone
        In ``:bonedata`` file order (node k+1 = k-th bone, FEATURES.md §2.2).
    root_order : tuple of str
        AMC root value order, lower case, e.g. ``("tx","ty","tz","rx","ry","rz")``.
    root_axis : str
        ``axis`` token of the root (only ``XYZ`` is accepted).
    root_position : ndarray, shape (3,)
        Root ``position`` in toolbox units (added to every AMC translation).
    root_orientation : ndarray, shape (3,)
        Root ``orientation`` numbers in file order and the skeleton's angle unit;
        applied as O = Rz(o1)·Rx(o2)·Ry(o3) (toolbox ``euler2quat`` default).
    length_unit : float
        ``:units length`` (file lengths are divided by it, then · 2.54).
    mass_unit : float
        ``:units mass`` when a number (1 when the file names a unit: mass is
        never used).
    angle_unit : str
        ``"deg"`` or ``"rad"`` (``:units angle``): unit of axis, orientation
        and — unless the AMC says otherwise — of AMC angles.
    documented_fps : float or None
        A frame rate the ``:documentation`` section notes (``fps:30``): the
        rate of AMC takes that carry no ``:SAMPLES-PER-SECOND``.
    notes : tuple of str
        ``:units`` entries that were kept as written (unknown keys or names).
    path : str
    """

    name: str
    bones: tuple
    root_order: tuple = ROOT_DOFS
    root_axis: str = "XYZ"
    root_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    root_orientation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    length_unit: float = 1.0
    mass_unit: float = 1.0
    angle_unit: str = "deg"
    documented_fps: float | None = None
    notes: tuple = ()
    path: str = ""

    @property
    def bone_names(self) -> tuple:
        return tuple(b.name for b in self.bones)

    @property
    def bone_index(self) -> dict:
        """bone name -> index in :attr:`bones` (exact spelling)."""
        return {b.name: i for i, b in enumerate(self.bones)}

    def bone(self, name: str) -> Bone:
        """The bone called ``name`` (case-insensitive, as the toolbox matches)."""
        key = name.lower()
        for b in self.bones:
            if b.name.lower() == key:
                return b
        raise KeyError(name)

    def children(self, name: str) -> tuple:
        """Names of the bones whose parent is ``name`` (file order)."""
        return tuple(b.name for b in self.bones if b.parent == name)

    def topological_order(self) -> np.ndarray:
        """Bone indices ordered so that every parent precedes its children.

        File order when it already is one (all files here), else a stable
        breadth-first order from the root.
        """
        done = {"root"}
        order: list[int] = []
        pending = list(range(len(self.bones)))
        while pending:
            rest = []
            for i in pending:
                if self.bones[i].parent in done:
                    order.append(i)
                    done.add(self.bones[i].name)
                else:
                    rest.append(i)
            if len(rest) == len(pending):  # pragma: no cover - read_asf rejects cycles
                raise ValueError("skeleton hierarchy has a cycle: " + ", ".join(
                    self.bones[i].name for i in rest))
            pending = rest
        return np.asarray(order, dtype=np.int64)


@dataclass(frozen=True)
class AmcMotion:
    """DOF values of an AMC file.

    Attributes
    ----------
    values : ndarray, shape (n_frames, n_columns), float64
        Raw values as written (angles in :attr:`angle_unit`, root translation
        in ASF length units). Columns: root (in the ASF ``order``), then every
        ASF bone with DOFs, in ASF file order, each in its ``dof`` order.
    columns : dict str -> slice
        Columns of each bone (``"root"`` included), keyed by ASF bone name.
    dof_names : dict str -> tuple of str
        DOF names of each bone's columns (``"tx"``, ..., ``"rz"``).
    fps : float
        ``:SAMPLES-PER-SECOND``, else the rate the ASF's ``:documentation`` notes,
        else 120.
    angle_unit : str
        ``"deg"`` or ``"rad"``.
    first_frame : int
        Frame number of the first frame in the file (1 in all files here).
    path : str
    """

    values: np.ndarray
    columns: dict
    dof_names: dict
    fps: float = DEFAULT_FPS
    angle_unit: str = "deg"
    first_frame: int = 1
    path: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def dofs(self) -> dict:
        """bone name -> ``(n_frames, n_dofs)`` view of its values."""
        return {name: self.values[:, sl] for name, sl in self.columns.items()}

    def column(self, bone: str, dof: str) -> int:
        """Column index of ``dof`` of ``bone``, or -1 when the bone lacks that DOF."""
        names = self.dof_names.get(bone, ())
        if dof not in names:
            return -1
        return self.columns[bone].start + names.index(dof)


def column_layout(skeleton: Skeleton):
    """Columns of the AMC value array for ``skeleton``.

    Returns ``(names, ndof, col_start, columns, dof_names)``: index 0 is the
    root, index k the (k-1)-th bone in file order.
    """
    names = ["root"] + [b.name for b in skeleton.bones]
    dofs = [tuple(skeleton.root_order)] + [tuple(b.dof) for b in skeleton.bones]
    ndof = np.array([len(d) for d in dofs], dtype=np.int64)
    col_start = np.zeros(len(names), dtype=np.int64)
    col_start[1:] = np.cumsum(ndof)[:-1]
    columns = {n: slice(int(s), int(s + k)) for n, s, k in zip(names, col_start, ndof) if k}
    dof_names = {n: d for n, d in zip(names, dofs) if d}
    return names, ndof, col_start, columns, dof_names
