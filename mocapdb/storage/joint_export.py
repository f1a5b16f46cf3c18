"""Stored motions' canonical joints out as files (``export-joints``): re-read from their sources.

The joints are not stored (24 × 3 floats per frame would be ~36× the 8-byte
feature word, :mod:`mocapdb.viewer.data`): each motion's source file is read
again with the options it was ingested with (:func:`source_motion`), as the
viewer does, and written by :func:`mocapdb.readers.joints_write.write_joints`.
A motion that cannot be exported is named with the reason; the others are
written.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.readers.joints_write import JOINTS_FORMATS, write_joints
from mocapdb.storage.annotations import motion_sources
from mocapdb.storage.motions import motion_ids, source_motion
from mocapdb.storage.names import file_in, file_stems

__all__ = ["JointsExport", "export_joints"]


@dataclass
class JointsExport:
    """What :func:`export_joints` did: ``written`` ``(motion_id, name, path)`` per file,
    ``failed`` ``(motion_id, name, reason)`` per motion that could not be exported."""

    written: list = field(default_factory=list)
    failed: list = field(default_factory=list)


def export_joints(con, motions, out, *, format="npz", progress=None) -> JointsExport:
    """Write the 24 canonical joints of stored motions, re-read from their sources, as files.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : iterable of int or str
        Motion ids or names (a name names every motion of that name).
    out : str or Path
        One motion and a path ending in ``.<format>``: that file. Otherwise
        a directory (created) receiving ``<motion name>.<format>`` per
        motion (the name made a safe file name, ``<name>_<motion_id>`` where
        names repeat: :func:`mocapdb.storage.names.file_stems`).
    format : {"npz", "csv", "bvh"}, keyword-only
    progress : callable, optional, keyword-only
        ``progress(n_done, n_motions, name)`` once per motion.

    Returns
    -------
    JointsExport

    Raises
    ------
    ParameterError
        An unknown format, or several motions and ``out`` a file name.
    SchemaError
        A motion id or name the database does not have.
    """
    if format not in JOINTS_FORMATS:
        raise ParameterError(f"format must be one of {', '.join(JOINTS_FORMATS)}, got {format!r}")
    ids = list(dict.fromkeys(motion_ids(con, motions)))
    if not ids:
        raise ParameterError("motions: give at least one motion id or name")
    out = Path(out)
    sources = motion_sources(con, ids)
    single = len(sources) == 1 and out.suffix.lower() == f".{format}"
    if not single:
        if out.suffix.lower() == f".{format}":
            raise ParameterError(f"out: {len(sources)} motions give one file each; give a directory, not {out.name}")
        out.mkdir(parents=True, exist_ok=True)
    report = JointsExport()
    for k, (src, stem) in enumerate(zip(sources, file_stems(sources))):
        mid, name = int(src["motion_id"]), src["name"]
        path = out if single else file_in(out, stem, f".{format}")
        try:
            if not os.path.isabs(src["source_path"]):
                raise MocapdbError(f"stored as feature words only ({src['source_path']}): no source file to "
                                   "read the joints from")
            motion = source_motion(con, mid)
            write_joints(path, motion, format=format)
            report.written.append((mid, name, path))
        except (MocapdbError, OSError) as exc:
            text = str(exc).removeprefix(f"motion {mid}: ")   # source_motion's own prefix: named once
            report.failed.append((mid, name, f"motion {mid} ({name}): {text}"))
        if progress is not None:
            progress(k + 1, len(sources), name)
    return report
