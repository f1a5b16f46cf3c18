"""The in-memory result of reading a recording: what every reader returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Motion:
    """One recording, resolved to the 24 canonical joints.

    Attributes
    ----------
    joints : ndarray, shape (n_frames, 24, 3), float64
        Joint positions in the order of :data:`mocapdb.readers.joints.JOINT_NAMES`,
        Y up, in the toolbox's length unit (ASF lengths / ``:units length`` ·
        2.54). Features do not depend on the unit.
    root_rotation : ndarray, shape (n_frames, 3, 3), float64, or None
        Rotation of the root as recorded (AMC ``Rz·Ry·Rx``, without the ASF
        root orientation); feature #40 reads its x axis. None for
        position-only sources (then #40 uses the hip axis, FEATURES.md §6).
    fps : float
        Native sampling rate in Hz.
    name : str
        Document name (file stem).
    skeleton : str
        Skeleton identifier (ASF name/path or BVH skeleton family).
    source_format : str
        ``"amc"``, ``"bvh"``, ...
    """

    joints: np.ndarray
    root_rotation: np.ndarray | None
    fps: float
    name: str = ""
    skeleton: str = ""
    source_format: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.joints.shape[0])


__all__ = ["Motion"]
