"""Stored motions' canonical joints out as files (``export-joints``): re-read from their sources.

The joints are not stored (24 × 3 floats per frame would be ~36× the 8-byte
feature word, :mod:`mocapdb.viewer.data`): each motion's source file is read
again with the options it was ingested with (:func:`source_motion`), as the
viewer does, and written by :func:`mocapdb.writers.joints_write.write_joints`.
A motion that cannot be exported is named with the reason; the others are
written. Each file's source unit and how it was decided (a BVH declares
none: :mod:`mocapdb.bodies.units`) is in the report and, for a folder, in
its ``units.json``.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from mocapdb.errors import MocapdbError, ParameterError, os_error_text
from mocapdb.writers.joints_write import JOINTS_FORMATS, write_joints
from mocapdb.bodies.units import check_override
from mocapdb.storage.annotations import motion_sources
from mocapdb.storage.motions import motion_ids, select_motions, source_motion
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.names import file_in, file_stems

__all__ = ["JointsExport", "export_joints", "UNITS_FILE"]

#: the file of a folder export naming each file's source unit (CSV and BVH have no place for it)
UNITS_FILE = "units.json"


@dataclass
class JointsExport:
    """What :func:`export_joints` did: ``written`` ``(motion_id, name, path, source unit and how it
    was known)`` per file, ``failed`` ``(motion_id, name, reason)`` per motion that could not be exported."""

    written: list = field(default_factory=list)
    failed: list = field(default_factory=list)


def export_joints(con, motions, out, *, format="npz", where=None, label=None, model=DEFAULT_MODEL, unit=None,
                  scale=None, progress=None) -> JointsExport:
    """Write the 24 canonical joints of stored motions, re-read from their sources, as files.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motions : iterable of int or str, or None
        Motion ids or names (a name names every motion of that name); None:
        every motion (that ``where`` and ``label`` keep).
    out : str or Path
        One motion and a path ending in ``.<format>``: that file (its folder
        created). Otherwise a directory (created) receiving
        ``<motion name>.<format>`` per motion (the name made a safe file
        name, ``<name>_<motion_id>`` where names repeat:
        :func:`mocapdb.storage.names.file_stems`) and :data:`UNITS_FILE`.
    format : {"npz", "csv", "bvh"}, keyword-only
    where : str, optional, keyword-only
        Keep the motions a SQL condition over ``motions``' columns holds for.
    label, model : str, optional, keyword-only
        Keep the motions with a stored segment of ``label`` (of ``model``).
    unit, scale : optional, keyword-only
        A BVH source's unit or metres per unit, overriding the reader's decision.
    progress : callable, optional, keyword-only
        ``progress(n_done, n_motions, name)`` once per motion.

    Returns
    -------
    JointsExport

    Raises
    ------
    ParameterError
        An unknown format or unit, a bad scale or filter, no motion
        selected, several motions and ``out`` a file name, or ``out`` a
        folder that cannot be made.
    SchemaError
        A motion id or name the database does not have.
    """
    if format not in JOINTS_FORMATS:
        raise ParameterError(f"format must be one of {', '.join(JOINTS_FORMATS)}, got {format!r}")
    check_override(unit, scale)   # before any motion is read
    ids = None if motions is None else list(dict.fromkeys(motion_ids(con, motions)))
    if where is not None or label is not None or ids is None:
        kept = select_motions(con, where=where, label=label, model=model)
        ids = kept if ids is None else [i for i in ids if i in set(kept)]
    if not ids:
        raise ParameterError("motions: none selected (give motion ids or names, all of them, or a filter that "
                             "keeps some)")
    out = Path(out)
    sources = motion_sources(con, ids)
    single = len(sources) == 1 and out.suffix.lower() == f".{format}"
    if not single and out.suffix.lower() == f".{format}":
        raise ParameterError(f"out: {len(sources)} motions give one file each; give a directory, not {out.name}")
    folder = out.parent if single else out
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"out: cannot make the folder ({os_error_text(exc)})") from None
    report = JointsExport()
    for k, (src, stem) in enumerate(zip(sources, file_stems(sources))):
        mid, name = int(src["motion_id"]), src["name"]
        path = out if single else file_in(out, stem, f".{format}")
        try:
            if not os.path.isabs(src["source_path"]):
                raise MocapdbError(f"stored as feature words only ({src['source_path']}): no source file to "
                                   "read the joints from")
            motion = source_motion(con, mid)
            how = write_joints(path, motion, format=format, unit=unit, scale=scale)
            report.written.append((mid, name, path, how))
        except MocapdbError as exc:
            text = str(exc).removeprefix(f"motion {mid}: ")   # source_motion's own prefix: named once
            report.failed.append((mid, name, f"motion {mid} ({name}): {text}"))
        except OSError as exc:
            report.failed.append((mid, name, f"motion {mid} ({name}): cannot write {os_error_text(exc)}"))
        if progress is not None:
            progress(k + 1, len(sources), name)
    if not single and report.written:
        units = [{"motion_id": mid, "name": name, "file": path.name, "source_unit": how}
                 for mid, name, path, how in report.written]
        (out / UNITS_FILE).write_text(json.dumps({"unit": "m", "files": units}, indent=1, ensure_ascii=False),
                                      encoding="utf-8")
    return report
