"""Which recordings a path holds: the walk of files, folders and zip archives that ingest reads.

:func:`motion_files` expands what a user names — files, folders (recursively,
symlinked folders once), ``.zip`` archives read as folders, a folder inside
an archive (``cmu.zip/subjects/02``) — into the motion files to read, in a
fixed order, and reports what it passes over: files that are no motions (an
ASF beside its AMCs, an AMASS body shape file, a README), special files (FIFOs, devices, sockets),
folders and archives it cannot read, and zip members whose names would leave
their archive (:func:`~mocapdb.readers.sources.member_problem`). Where the
bytes of each file then come from is :mod:`~mocapdb.readers.sources`; both
``ingest`` (``storage.ingest``) and ``ray-annotate`` (``distributed``) walk
through here, so they read the same files.
"""
from __future__ import annotations

import fnmatch
import os
from pathlib import Path

from mocapdb.errors import ParameterError
from mocapdb.readers.amass import SHAPE_FILE_PATTERNS
from mocapdb.readers.files import SUPPORTED_EXTENSIONS
from mocapdb.readers.sources import (ARCHIVES, COMPRESSED, as_path, is_file, motion_stem, motion_suffix, special_kind,
                                     split_archive, zip_members)

__all__ = ["motion_files", "MOTION_SUFFIXES", "companion_kind"]

#: file extensions ingest reads as motions
MOTION_SUFFIXES = SUPPORTED_EXTENSIONS


def companion_kind(path) -> str | None:
    """What a file that sits beside motions without being one is, or None.

    An ASF skeleton (read with its AMC takes), and AMASS's body shape files
    (``shape.npz``, ``*_stagei.npz``: betas and gender, no motion), which a
    folder walk lists as not motion files rather than failed ones.
    """
    p = as_path(path)
    if motion_suffix(p) == ".asf":
        return "an ASF skeleton (read with its AMC takes)"
    name = (motion_stem(p) + motion_suffix(p)).lower()
    if any(fnmatch.fnmatchcase(name, pattern) for pattern in SHAPE_FILE_PATTERNS):
        return "an AMASS body shape file (betas and gender, no motion)"
    return None


def _hidden(name: str) -> bool:
    # hidden files and folders (.DS_Store, .git) and macOS zip metadata are nobody's motions
    return name.startswith(".") or name == "__MACOSX"


def _hidden_reason(name: str, folder: bool) -> str:
    """Why a hidden entry is passed over (a row of the ingest log: a real take may hide there)."""
    what = ("macOS zip metadata (__MACOSX)" if name == "__MACOSX" else
            f"a hidden {'folder' if folder else 'file'} (its name starts with '.')")
    return f"{what}: not read; name it on the command line to read it"


def _walk(folder: Path, files: list, unsupported, unreadable, hidden=None):
    """Regular files of a folder, recursively (symlinked folders followed once); special files,
    unreadable folders and hidden entries (one for a hidden folder) reported."""
    seen = set()

    def onerror(exc):
        if unreadable is not None:
            unreadable.append((str(exc.filename), f"unreadable folder ({exc.strerror or exc})"))

    for root, dirs, names in os.walk(folder, onerror=onerror, followlinks=True):
        try:
            st = os.stat(root)
        except OSError:
            dirs[:] = []
            continue
        if (st.st_dev, st.st_ino) in seen:   # a symlink loop
            dirs[:] = []
            continue
        seen.add((st.st_dev, st.st_ino))
        if hidden is not None:
            hidden += [(str(Path(root) / d), _hidden_reason(d, True)) for d in sorted(dirs) if _hidden(d)]
        dirs[:] = sorted(d for d in dirs if not _hidden(d))
        here = Path(root)   # parsed once per folder, not once per file
        for name in sorted(names):
            if _hidden(name):
                if hidden is not None:
                    hidden.append((str(here / name), _hidden_reason(name, False)))
                continue
            q = here / name
            kind = special_kind(q)
            if kind is not None:
                if unsupported is not None:
                    unsupported.append((str(q), f"{kind}, not a regular file"))
                continue
            files.append(q)


def _archive_files(archive: Path, unreadable, refused=None, *, named=False, hidden=None) -> list:
    """The members of a zip archive as paths through it (hidden ones left out, and reported to
    ``hidden``: a hidden folder once); ``refused`` receives the members whose names would leave the
    archive (never joined to its path: an absolute name would replace it) and earlier copies of a
    name, and an unreadable archive that was ``named`` (an argument, not an entry of a folder)."""
    bad = []
    try:
        names = zip_members(archive, refused=bad)
    except OSError as exc:
        if named and refused is not None:
            refused.append((str(archive), f"{archive}: unreadable archive ({exc})"))
        elif unreadable is not None:
            unreadable.append((str(archive), f"unreadable archive ({exc})"))
        return []
    if refused is not None:
        for name, problem in bad:
            where = f"{archive}/{name}"   # text only, for the report
            why = problem if problem.startswith("the archive holds") else \
                f"{problem}; a member must name a file inside its archive"
            refused.append((where, f"{where}: refused: {why}"))
    out, passed = [], {}
    for name in sorted(names):
        parts = name.split("/")
        k = next((i for i, part in enumerate(parts) if _hidden(part)), None)
        if k is None:
            out.append(archive / name)
        else:   # the first hidden part: a hidden folder is one entry of the log, not one per member
            passed.setdefault("/".join(parts[:k + 1]), _hidden_reason(parts[k], k < len(parts) - 1))
    if hidden is not None:
        hidden += [(f"{archive}/{where}", why) for where, why in passed.items()]
    return out


def _classify(q: Path, out: list, unsupported):
    ext = motion_suffix(q)
    if ext in MOTION_SUFFIXES and companion_kind(q) is None:
        out.append(q)
    elif unsupported is not None:
        why = companion_kind(q) or (f"unsupported file type {q.suffix!r}" if q.suffix else "no file extension")
        unsupported.append((str(q), why + " (motions: " + ", ".join(MOTION_SUFFIXES) + ", optionally "
                            + "/".join(COMPRESSED) + " compressed, or in a .zip archive)"))


def motion_files(paths, *, unsupported=None, unreadable=None, refused=None, hidden=None) -> list[Path]:
    """Expand files, folders (recursively) and zip archives into motion files, in sorted order.

    Parameters
    ----------
    paths : iterable of str or Path
        Files (``.amc``, ``.bvh``, ``.c3d``, each possibly ``.gz``/``.bz2``/``.xz``
        compressed), folders, ``.zip`` archives, or paths through an archive
        (``cmu.zip/subjects/02``, a folder inside it).
    unsupported : list, optional, keyword-only
        Receives ``(path, reason)`` for every file of a folder or archive that
        is not a motion file, and every special file (FIFO, device, socket) in
        a folder. A file named explicitly is always returned: reading it says
        what is wrong.
    unreadable : list, optional, keyword-only
        Receives ``(path, reason)`` for folders and archives that cannot be read.
    refused : list, optional, keyword-only
        Receives ``(path, reason)`` for zip members whose names would leave
        their archive (absolute, a drive letter, ``..``;
        :func:`mocapdb.readers.sources.member_problem`): never read; for each
        earlier copy of a member named twice (its path reads the last); and
        for an archive named in ``paths`` that cannot be read.
    hidden : list, optional, keyword-only
        Receives ``(path, reason)`` for each hidden file or folder (a name
        starting with ``.``, macOS's ``__MACOSX``) of a folder or archive,
        passed over unread (a hidden folder once, not each file in it).

    Raises
    ------
    ParameterError
        If a path does not exist.
    """
    out = []
    for p in map(Path, paths):
        archive, member = split_archive(p)
        if member is not None and member != "" and not is_file(p):
            # a folder inside an archive
            inside = []
            members = [q for q in _archive_files(archive, unreadable, refused, hidden=inside)
                       if str(q).startswith(str(p).rstrip("/") + "/")]
            if hidden is not None:
                hidden += [(q, why) for q, why in inside if q.startswith(str(p).rstrip("/") + "/")]
            if not members:
                raise ParameterError(f"paths: {str(p)!r} does not exist (no such member in {archive})")
            for q in members:
                _classify(q, out, unsupported)
        elif member == "":
            for q in _archive_files(archive, unreadable, refused, named=True, hidden=hidden):
                _classify(q, out, unsupported)
        elif p.is_dir():
            found = []
            _walk(p, found, unsupported, unreadable, hidden)
            for q in found:
                if q.suffix.lower() in ARCHIVES:
                    for m in _archive_files(q, unreadable, refused, hidden=hidden):
                        _classify(m, out, unsupported)
                else:
                    _classify(q, out, unsupported)
        elif is_file(p) or os.path.lexists(p):
            out.append(p)   # a special file named directly is refused by name when read
        else:
            raise ParameterError(f"paths: {str(p)!r} does not exist")
    return out
