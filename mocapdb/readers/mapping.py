"""User mapping files: canonical joint → the file's own names (READERS.md §6).

A BVH joint map (``--joint-map FILE``) names, for a canonical joint, the BVH
joint whose origin it is, or two joints whose midpoint it is; a C3D marker
map (``--marker-map FILE``) names the markers whose mean it is. Both are TOML
or JSON objects of the same shape::

    # joints.toml
    root = "Hips"
    lhip = "LeftUpLeg"
    neck = ["Neck", "Neck1"]        # the point between two joints / markers

:func:`load_mapping` reads either form (or takes a dict) and checks it, so a
bad file fails before any recording is read.
"""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_NAMES

__all__ = ["load_mapping"]


def load_mapping(source, *, what: str = "joint_map") -> dict | None:
    """A checked mapping ``{canonical joint: name or [names]}`` from a dict or a TOML/JSON file.

    Parameters
    ----------
    source : dict, str, Path or None
        None gives None (no mapping).
    what : str, keyword-only
        The parameter's name, for messages (``"joint_map"``, ``"marker_map"``).

    Returns
    -------
    dict or None
        Keys are canonical joint names (:data:`~mocapdb.bodies.joints.JOINT_NAMES`);
        values are a name or a non-empty list of names.

    Raises
    ------
    ParameterError
        Unreadable file, unknown canonical joint, or a value that is not a
        name or a list of names.
    """
    if source is None:
        return None
    if isinstance(source, dict):
        raw, where = source, f"{what}"
    else:
        path = Path(source)
        where = f"{what} {path}"
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ParameterError(f"{where}: cannot read it ({exc})") from None
        try:
            raw = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
        except (ValueError, tomllib.TOMLDecodeError) as exc:
            kind = "JSON" if path.suffix.lower() == ".json" else "TOML"
            raise ParameterError(f"{where}: not valid {kind} ({exc})") from None
        if not isinstance(raw, dict):
            raise ParameterError(f"{where}: expected an object of canonical joint = name(s)")
    out = {}
    for key, value in raw.items():
        if key not in JOINT_NAMES:
            raise ParameterError(f"{where}: {key!r} is not a canonical joint (expected one of "
                                 f"{', '.join(JOINT_NAMES)})")
        names = [value] if isinstance(value, str) else value
        if not (isinstance(names, list) and names and all(isinstance(n, str) and n for n in names)):
            raise ParameterError(f"{where}: {key} = {value!r}: expected a name or a list of names")
        out[key] = value if isinstance(value, str) else list(names)
    return out
