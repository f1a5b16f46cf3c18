"""How files are read: one validated, frozen value from the command line down to the readers.

Every way in — ``mocapdb ingest``, ``mocapdb ray-annotate``, their API
functions, the viewer re-reading a stored motion — reads files with the same
options. They are checked once, where they enter (:class:`ReaderOptions` validates
itself on construction: a mapping file is read and checked, a rule set named,
a size parsed), and the value travels as it is: through ``storage.ingest``
(:func:`~mocapdb.storage.ingest_read.prepare_file`), Ray's workers
(``distributed``) and :func:`~mocapdb.readers.files.read_motion`, so a file
reads the same whichever command reads it.

Each option applies to one file type (:data:`APPLIES_TO`); a stored motion
keeps the options of its own type in ``motions.reader_options`` (JSON,
:meth:`ReaderOptions.stored`), from which :meth:`ReaderOptions.from_stored`
rebuilds them when the source is re-read (READERS.md §8).

Adding a reader option (ARCHITECTURE.md, *A reader*): a field here, its check
in ``__post_init__``, its file type in :data:`APPLIES_TO` when it changes how
a motion reads (so it is stored), the reader's use of it in
``readers.files._read``; the API keyword of ``ingest`` and ``ray_annotate``
and the CLI option in ``cli/options.py`` (``reader_options``). Nothing in
storage or distributed changes: they carry the value.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

from mocapdb.errors import ParameterError
from mocapdb.readers.c3d_rules import MARKER_RULES
from mocapdb.readers.mapping import load_mapping
from mocapdb.readers.sources import decompression_cap, motion_suffix, parse_size

__all__ = ["ReaderOptions", "READER_OPTIONS", "APPLIES_TO"]
#: reader option → the file types it changes the reading of; a motion stores those of its own type
APPLIES_TO = {"joint_map": (".bvh",), "marker_map": (".c3d",), "marker_rules": (".c3d",), "body_model": (".npz",)}
#: the options stored with a motion (``motions.reader_options``) and given back to the reader when it
#: re-reads the source; other keys stored there (``notes``, ``source_frames``) only inform
READER_OPTIONS = tuple(APPLIES_TO)


def _frozen(mapping):
    """A checked mapping (:func:`~mocapdb.readers.mapping.load_mapping`) as nested tuples: hashable, immutable."""
    if mapping is None:
        return None
    return tuple((joint, names if isinstance(names, str) else tuple(names)) for joint, names in mapping.items())


def _thawed(frozen):
    """The dict form of a frozen mapping, as :func:`~mocapdb.readers.mapping.load_mapping` returns it."""
    if frozen is None:
        return None
    return {joint: names if isinstance(names, str) else list(names) for joint, names in frozen}


@dataclass(frozen=True)
class ReaderOptions:
    """How recordings are read (every field optional; the defaults read every file by its own rules).

    Built from the API's keywords (files or dicts), checked on construction;
    immutable, hashable and picklable, so one value goes to every thread and
    Ray worker.

    Attributes
    ----------
    asf : str or Skeleton, optional
        The ASF skeleton of every AMC file (an absolute path); default: each
        AMC's own, found by the dataset conventions (:func:`~mocapdb.readers.files.find_skeleton`).
    joint_map : tuple, optional
        BVH files: canonical joint → the file's joint(s) (docs/READING_FILES.md "Mapping
        files"); given as a TOML/JSON file or a dict, kept as ``((joint,
        name or (names…)), …)`` (:meth:`mapping` gives the dict).
    marker_map : tuple, optional
        C3D files: canonical joint → the markers whose mean it is; as ``joint_map``.
    marker_rules : {"toolbox", "anatomical"}
        C3D files of the HDM05/CMU marker set: the toolbox's formulas (default,
        the reference) or anatomical joint centres (READERS.md §3.2).
    body_model : str, optional
        AMASS ``.npz`` files (READERS.md §9): the SMPL-H/SMPL-X body model file
        (``model.npz``, ``SMPLX_*.npz``) whose joint regressor, template and
        shape directions give each take's rest joints from its betas, or a
        folder of them (each take gets the model of its family and gender,
        :func:`~mocapdb.readers.body_model.find_body_model`); an absolute path.
        Without it the reader uses its shipped generic rest skeleton. Stored
        with the motions it reads (:data:`APPLIES_TO`).
    max_decompressed : int, optional
        Bytes a compressed file or zip member may decompress to (given as an
        int or a size such as ``"2GiB"``); default: the environment's
        ``MOCAPDB_MAX_DECOMPRESSED``, else 512 MiB
        (:func:`~mocapdb.readers.sources.max_decompressed`). A limit on
        resources, not on how a file reads: not stored.

    Raises
    ------
    ParameterError
        A mapping file that cannot be read or names no canonical joint, an
        unknown ``marker_rules``, a size that is none, a ``body_model`` that is
        neither a file nor a folder (the message names the parameter and the value).
    """

    asf: object = None
    joint_map: tuple | None = None
    marker_map: tuple | None = None
    marker_rules: str = "toolbox"
    body_model: str | None = None
    max_decompressed: int | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        if self.asf is not None and isinstance(self.asf, (str, os.PathLike)):
            # absolute: threads and Ray workers may run elsewhere than the caller
            set_(self, "asf", os.path.abspath(self.asf))
        for name in ("joint_map", "marker_map"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, tuple):
                set_(self, name, _frozen(load_mapping(value, what=name)))
        if self.marker_rules is None:
            set_(self, "marker_rules", "toolbox")
        if self.marker_rules not in MARKER_RULES:
            raise ParameterError(f"marker_rules must be one of {', '.join(map(repr, MARKER_RULES))} "
                                 f"(--marker-rules), got {self.marker_rules!r}")
        if self.body_model is not None:
            if not (Path(self.body_model).is_file() or Path(self.body_model).is_dir()):
                raise ParameterError(f"body_model: {str(self.body_model)!r} does not exist (give an SMPL-H/SMPL-X "
                                     "model .npz or a folder of them: --body-model PATH)")
            set_(self, "body_model", os.path.abspath(self.body_model))
        if self.max_decompressed is not None:
            set_(self, "max_decompressed", parse_size(self.max_decompressed))

    def mapping(self, name: str) -> dict | None:
        """``joint_map`` or ``marker_map`` as a dict (canonical joint → name or [names]), or None."""
        return _thawed(getattr(self, name))

    def replace(self, **changes) -> "ReaderOptions":
        """A copy with some fields changed (checked again)."""
        return dataclasses.replace(self, **changes)

    def for_file(self, path) -> dict:
        """The options that change how ``path`` reads, as stored with its motion (JSON-able; the
        defaults are left out, so a motion read as before stores what it stored before)."""
        suffix = motion_suffix(path)
        out = {}
        for name, suffixes in APPLIES_TO.items():
            value = getattr(self, name)
            if suffix not in suffixes or value is None or (name == "marker_rules" and value == "toolbox"):
                continue
            out[name] = self.mapping(name) if name in ("joint_map", "marker_map") else value
        return out

    def stored(self, path) -> str | None:
        """:meth:`for_file` as the JSON of ``motions.reader_options``, or None when there is nothing."""
        opts = self.for_file(path)
        return json.dumps(opts, sort_keys=True) if opts else None

    @classmethod
    def from_stored(cls, text, *, asf=None) -> "ReaderOptions":
        """The options a stored motion was read with: its ``motions.reader_options`` JSON (the keys of
        :data:`READER_OPTIONS`; notes and source frames are passed over) and its skeleton."""
        stored = json.loads(text) if text else {}
        return cls(asf=asf, **{k: v for k, v in stored.items() if k in READER_OPTIONS})

    def capped(self):
        """A context in which decompression stops at :attr:`max_decompressed` (this thread;
        :func:`~mocapdb.readers.sources.decompression_cap`)."""
        if self.max_decompressed is None:
            return contextlib.nullcontext()
        return decompression_cap(self.max_decompressed)
