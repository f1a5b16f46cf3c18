"""Motion names as file names: the one sanitiser, and the check of names that enter from outside.

A motion's name is data: ingest takes it from the file stem, but an imported
archive (``import-features``) or a hand-edited database can hold any string,
``../../x`` and ``/tmp/x`` included. Every file name that mocapdb derives
from a name (``view --all``, ``annotate --format eaf --out DIR``) goes
through :func:`file_stems` (built on :func:`safe_stem`), so whatever the
names, the files land inside the chosen folder, one per motion, none
overwriting another or a reserved name such as the index page.
:func:`check_motion_names` refuses names that no ingest produces where names
come in from outside.
"""
from __future__ import annotations

import re
import unicodedata
from pathlib import Path

from mocapdb.errors import ParameterError, SchemaError, shorten

__all__ = ["safe_stem", "file_stems", "file_in", "motion_name_problem", "check_motion_names", "MAX_NAME_LENGTH",
           "MAX_STEM_BYTES"]

#: longest motion name accepted from outside (a file name's limit on common file systems)
MAX_NAME_LENGTH = 255
#: longest stem written, in UTF-8 bytes: room for "_<motion id>" and a suffix within 255 bytes
MAX_STEM_BYTES = 180

# path separators of every OS, characters Windows forbids in names, and control characters
_UNSAFE = re.compile(r'[/\\<>:"|?*\x00-\x1f\x7f]')
# names Windows reserves for devices, with any suffix (CON.html opens the console)
_DEVICES = re.compile(r"(?i)^(con|prn|aux|nul|com[0-9]|lpt[0-9])(\..*)?$")


def safe_stem(name) -> str:
    """A file stem for ``name`` that stays inside its folder on every OS.

    Path separators, characters Windows forbids and control characters
    become ``_``; leading dots (``..``, hidden files) and trailing dots and
    spaces go; device names (``CON``, ``NUL``, ``COM1`` …) get a ``_``; the
    result is cut to :data:`MAX_STEM_BYTES` bytes of UTF-8; an empty result
    is ``motion``. Other characters (letters of any script, spaces, ``#``,
    ``%``) are kept: links to the file are URL-quoted where they are written.

    Parameters
    ----------
    name : str

    Returns
    -------
    str
        Never empty, never ``.`` or ``..``, without a separator.
    """
    s = _UNSAFE.sub("_", unicodedata.normalize("NFC", str(name)))
    s = s.lstrip(".").rstrip(". ")
    if _DEVICES.match(s):
        s = "_" + s
    raw = s.encode("utf-8")[:MAX_STEM_BYTES]
    s = raw.decode("utf-8", errors="ignore").rstrip(". ")
    return s or "motion"


def file_stems(sources, *, reserved=()) -> list[str]:
    """One distinct, safe file stem per motion: its name, or ``<name>_<motion_id>`` where needed.

    A motion keeps its (sanitised, :func:`safe_stem`) name where that is
    unique; where names repeat, collide after sanitising or ignoring case
    (macOS and Windows folders), or take a ``reserved`` stem (``index``),
    every motion of the name gets its id appended (and a counter, in the
    rare case that is taken too).

    Parameters
    ----------
    sources : sequence of dict
        ``motion_id`` and ``name`` per motion (as
        :func:`mocapdb.storage.annotations.motion_sources` returns).
    reserved : iterable of str
        Stems that must not be used (compared ignoring case).

    Returns
    -------
    list of str
        In the order of ``sources``; distinct ignoring case.
    """
    stems = [safe_stem(s["name"]) for s in sources]
    taken = {r.casefold() for r in reserved}
    counts = {}
    for st in stems:
        counts[st.casefold()] = counts.get(st.casefold(), 0) + 1
    out, used = [], set(taken)
    for s, st in zip(sources, stems):
        key = st.casefold()
        cand = st if counts[key] == 1 and key not in taken else f"{st}_{int(s['motion_id'])}"
        k = 2
        while cand.casefold() in used:
            cand = f"{st}_{int(s['motion_id'])}_{k}"
            k += 1
        used.add(cand.casefold())
        out.append(cand)
    return out


def file_in(directory, stem, suffix) -> Path:
    """``directory / (stem + suffix)``, checked to lie directly inside ``directory``.

    Raises
    ------
    ParameterError
        If the file would land elsewhere (a stem that did not come from
        :func:`safe_stem`).
    """
    d = Path(directory)
    path = d / f"{stem}{suffix}"
    if path.parent != d or Path(stem).name != stem or stem in ("", ".", ".."):
        raise ParameterError(f"file name {shorten(stem)} would leave the folder {str(d)!r}")
    return path


def motion_name_problem(name):
    """Why ``name`` is not a motion name ingest could have given (a file stem), or None.

    Refused: a non-string or empty name, ``.`` and ``..``, path separators
    (``/``, ``\\``), control characters, more than :data:`MAX_NAME_LENGTH`
    characters.
    """
    if not isinstance(name, str) or not name:
        return "empty or not text"
    if name in (".", ".."):
        return "a directory name"
    if len(name) > MAX_NAME_LENGTH:
        return f"longer than {MAX_NAME_LENGTH} characters ({len(name):,})"
    if "/" in name or "\\" in name:
        return "holds a path separator"
    if re.search(r"[\x00-\x1f\x7f]", name):
        return "holds control characters"
    return None


def check_motion_names(names, *, source) -> None:
    """Refuse motion names from outside (an imported archive) that are not file stems.

    Parameters
    ----------
    names : iterable of str
    source : str or Path
        Where the names come from (named in the error).

    Raises
    ------
    SchemaError
        Naming the first few bad names and why (:func:`motion_name_problem`).
    """
    bad = [(n, why) for n in names if (why := motion_name_problem(n)) is not None]
    if bad:
        shown = "; ".join(f"{shorten(n, 60)}: {why}" for n, why in bad[:5])
        more = f" (and {len(bad) - 5} more)" if len(bad) > 5 else ""
        raise SchemaError(f"{source}: {len(bad)} motion name(s) are not file names ingest could give, refused: "
                          f"{shown}{more}")
