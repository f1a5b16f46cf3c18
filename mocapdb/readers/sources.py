"""Where a recording's bytes come from: a file, a compressed file, or a member of a zip archive.

Recordings are published compressed (``take.bvh.gz``, ``.bz2``, ``.xz``) or
as zip downloads with a folder inside (the CMU and Bandai archives). They
are read in place, never unpacked to disk:

* a **compressed file** ``walk.bvh.gz`` is the motion ``walk.bvh``: its
  format is the suffix before the compression suffix, its bytes the
  decompressed stream;
* a **zip member** is named by the path *through* the archive, as if the
  archive were a folder: ``/data/cmu.zip/subjects/02/02_01.amc`` is the
  member ``subjects/02/02_01.amc`` of ``/data/cmu.zip``. That string is the
  motion's ``source_path``: :func:`read_bytes` re-reads it for the viewer, and
  an AMC inside finds its ASF among its siblings in the same archive
  (:func:`is_file`, :func:`list_dir`). A member may itself be compressed.
  A member whose name would leave its archive — absolute (``/home/u/x.bvh``),
  with a drive letter (``C:/x.bvh``) or with ``..`` — is never read
  (:func:`member_problem`): joined to the archive's path it would name a
  file of the host, not of the archive.

:func:`sha256` hashes the recording's own bytes (decompressed; a member's
bytes) while streaming, so a take stored plain, gzipped or zipped is one
motion, and re-ingest is a no-op. :func:`bytes_file` gives libraries that
need a file name (ezc3d) an in-memory file (``memfd``), not a copy on disk.

Decompression is bounded: a compressed recording or a compressed zip member
may decompress to at most :func:`max_decompressed` bytes (default
:data:`DEFAULT_MAX_DECOMPRESSED`; the environment's ``MOCAPDB_MAX_DECOMPRESSED``,
or :func:`decompression_cap` around a call, change it). A compression bomb —
megabytes that expand to gigabytes — stops at the cap with an ``OSError``
while it is hashed, before any reader holds its bytes; a member whose
declared size is over the cap stops before a byte is read.
"""
from __future__ import annotations

import bz2
import contextlib
import contextvars
import gzip
import hashlib
import io
import lzma
import math
import os
import re
import stat
import tempfile
import threading
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from mocapdb.errors import ParameterError

__all__ = ["COMPRESSED", "ARCHIVES", "split_archive", "plain_file", "motion_suffix", "motion_stem", "read_bytes", "open_stream",
           "sha256", "stream_size", "is_file", "list_dir", "identity", "FileCache", "bytes_file", "special_kind",
           "zip_members", "member_problem", "DEFAULT_MAX_DECOMPRESSED", "max_decompressed", "decompression_cap",
           "parse_size", "format_size", "HOLD_MAX", "read_held", "holding", "as_path"]

#: compression suffix → the module that opens it as a stream
COMPRESSED = {".gz": gzip, ".bz2": bz2, ".xz": lzma}
#: archive suffixes read as folders
ARCHIVES = (".zip",)
_CHUNK = 1 << 20
#: what a damaged compressed stream raises besides OSError
_DECODE_ERRORS = (EOFError, lzma.LZMAError, zlib.error, zipfile.BadZipFile)
#: the bytes a compressed recording or zip member may decompress to, unless the environment's
#: MOCAPDB_MAX_DECOMPRESSED or :func:`decompression_cap` say otherwise: far above any take of the
#: test archives (the largest, 27 MB), and low enough that a bomb stops within seconds
DEFAULT_MAX_DECOMPRESSED = 512 << 20
#: the cap set by :func:`decompression_cap` for the calls inside it (per thread: a context variable)
_CAP = contextvars.ContextVar("mocapdb_max_decompressed", default=None)
_SIZE = re.compile(r"^\s*(\d+(?:\.\d*)?(?:e\d+)?)\s*([kmgt]?)(i?)b?\s*$", re.IGNORECASE)


def parse_size(value, *, what="max_decompressed") -> int:
    """A byte count from an int or a text such as ``"512MiB"``, ``"2G"``, ``"1.5GB"``, ``"1000000"``.

    ``K``/``M``/``G``/``T`` with an ``i`` are powers of 1024, without one powers of 1000.

    Raises
    ------
    ParameterError
        If ``value`` is not a positive size; the message names ``what``.
    """
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        n = value
    else:
        m = _SIZE.match(str(value))
        if m is None:
            raise ParameterError(f"{what}: {value!r} is not a size in bytes (e.g. 512MiB, 2GiB, 1000000000)")
        n = float(m.group(1)) * (1024 if m.group(3) else 1000) ** " kmgt".index((m.group(2) or " ").lower())
    if not (n >= 1 and math.isfinite(n)):   # 1e400 reads as inf: no byte count
        raise ParameterError(f"{what}: {value!r} is not a positive finite size in bytes (e.g. 512MiB)")
    return int(n)


def format_size(n: int) -> str:
    """``536870912`` → ``"512 MiB"``: a byte count for a message."""
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


def max_decompressed() -> int:
    """The cap on a recording's decompressed bytes now: the innermost :func:`decompression_cap`, else
    the environment's ``MOCAPDB_MAX_DECOMPRESSED``, else :data:`DEFAULT_MAX_DECOMPRESSED`."""
    cap = _CAP.get()
    if cap is not None:
        return cap
    env = os.environ.get("MOCAPDB_MAX_DECOMPRESSED", "").strip()
    return parse_size(env, what="MOCAPDB_MAX_DECOMPRESSED") if env else DEFAULT_MAX_DECOMPRESSED


@contextlib.contextmanager
def decompression_cap(cap):
    """Within the block (this thread), recordings may decompress to at most ``cap`` bytes (an int or a
    size text, :func:`parse_size`); None keeps the cap as it is."""
    token = _CAP.set(parse_size(cap) if cap is not None else _CAP.get())
    try:
        yield
    finally:
        _CAP.reset(token)


def _over_cap(cap: int) -> OSError:
    return OSError(f"decompresses to more than {format_size(cap)}, the cap on a recording's decompressed "
                   "bytes (a compression bomb?); a larger cap: ingest --max-decompressed SIZE or "
                   "MOCAPDB_MAX_DECOMPRESSED=SIZE")


def _is_zip(p: Path) -> bool:
    return p.suffix.lower() in ARCHIVES


def as_path(path) -> Path:
    """``path`` as a Path, not parsed again when it is one (a per-file helper is asked ~20 times per take,
    and ``Path(a_path)`` parses the whole path anew): what every per-take step uses instead of ``Path``.
    A string's Path is kept (Paths are immutable): a take's skeleton comes as a string (the options keep
    it absolute) and was parsed twice per take (issue 35)."""
    if isinstance(path, Path):
        return path
    if type(path) is not str:
        return Path(path)
    hit = _PATHS.get(path)
    if hit is None:
        if len(_PATHS) >= 1024:
            _PATHS.clear()
        hit = _PATHS[path] = Path(path)
    return hit


#: strings' Paths for :func:`as_path`
_PATHS = {}


def split_archive(path) -> tuple:
    """``(archive, member)`` when ``path`` runs through a zip archive (a regular file), else ``(path, None)``.

    ``/d/a.zip/x/y.amc`` → ``(Path("/d/a.zip"), "x/y.amc")``; ``/d/a.zip`` itself →
    ``(Path("/d/a.zip"), "")``.
    """
    p = as_path(path)
    text = str(path).lower()
    if not any(a in text for a in ARCHIVES):   # the common case, asked per file many times: no path walk
        return p, None
    for parent in (p, *p.parents):
        if _is_zip(parent):
            try:
                regular = stat.S_ISREG(os.stat(parent).st_mode)
            except OSError:
                continue
            if regular:
                rel = p.relative_to(parent)
                return parent, "" if str(rel) == "." else str(PurePosixPath(*rel.parts))
    return p, None


def plain_file(path) -> bool:
    """True when ``path`` is read as it is on disk (not compressed, not inside a zip archive)."""
    return split_archive(path)[1] is None and as_path(path).suffix.lower() not in COMPRESSED


def motion_suffix(path) -> str:
    """The motion format's suffix, lower case: ``walk.BVH.gz`` → ``.bvh``."""
    p = as_path(path)
    suffix = p.suffix.lower()
    if suffix in COMPRESSED:
        suffix = Path(p.stem).suffix.lower()
    return suffix


def motion_stem(path) -> str:
    """The file name without compression and format suffixes: ``walk.bvh.gz`` → ``walk``.

    A stem of dots only (``...bvh`` → ``..``) is no name a motion can carry out and back in (a file
    name, ``import-features``): its dots become ``_``."""
    p = as_path(path)
    if p.suffix.lower() in COMPRESSED:
        p = Path(p.stem)
    stem = p.stem
    return stem if stem.strip(".") else "_" * max(len(stem), 1)


# zip archives stay open between reads of their members (an archive of 2,500 takes is
# opened once per thread, not once per take)
_ZIPS = threading.local()


def _zip(archive: Path) -> zipfile.ZipFile:
    st = os.stat(archive)
    key = (str(archive), st.st_size, st.st_mtime_ns)
    cache = getattr(_ZIPS, "cache", None)
    if cache is None:
        cache = _ZIPS.cache = {}
    zf = cache.get(key)
    if zf is None:
        if len(cache) > 8:
            for old in cache.values():
                old.close()
            cache.clear()
        try:
            zf = cache[key] = zipfile.ZipFile(archive)
        except zipfile.BadZipFile as exc:   # as a damaged file: an OSError
            raise OSError(f"not a readable zip archive ({exc})") from None
    return zf


_DRIVE = re.compile(r"^[A-Za-z]:")


def member_problem(name: str) -> str | None:
    """Why a zip member's name cannot be read as a path inside its archive, or None.

    An absolute name, a drive letter or a ``..`` part (``/`` or ``\\`` separated)
    would name a file outside the archive once joined to the archive's path;
    empty and ``.`` parts would name another member than this one.
    """
    if name.startswith(("/", "\\")):
        return "its name is absolute (it would name a file outside the archive)"
    if _DRIVE.match(name):
        return "its name starts with a drive letter (it would name a file outside the archive)"
    parts = re.split(r"[/\\]", name.rstrip("/"))
    if ".." in parts:
        return "its name holds '..' (it would name a file outside the archive)"
    if "" in parts or "." in parts:
        return "its name holds an empty or '.' part (it would name another member)"
    return None


def zip_members(archive, *, refused=None) -> list:
    """Names of the regular members of a zip archive (folders left out) that name a file inside it.

    ``refused`` receives ``(name, reason)`` for members whose names would
    leave the archive (:func:`member_problem`), and for each earlier copy of a
    name the archive holds twice (a path names one member: zipfile reads the
    last); they are not returned.
    """
    try:
        infos = _zip(Path(archive)).infolist()
    except zipfile.BadZipFile as exc:
        raise OSError(f"not a readable zip archive ({exc})") from None
    copies = {}
    for info in infos:
        if not info.is_dir():
            copies[info.filename] = copies.get(info.filename, 0) + 1
    out = []
    for name, n in copies.items():
        problem = member_problem(name)
        if problem is None:
            out.append(name)
        elif refused is not None:
            refused.append((name, problem))
        if n > 1 and refused is not None and problem is None:
            refused += [(name, f"the archive holds {n} members of this name; only the last is read (a path "
                               "names one member)")] * (n - 1)
    return out


def _member_info(archive: Path, member: str) -> zipfile.ZipInfo:
    """The member's entry; KeyError when absent, OSError when its name would leave the archive."""
    problem = member_problem(member)
    if problem is not None:
        raise OSError(f"member {member!r} of {archive} refused: {problem}")
    return _zip(archive).getinfo(member)


def _raw_stream(path):
    """The file's or zip member's bytes as a stream, and whether they are inflated (a compressed member)."""
    archive, member = split_archive(path)
    if member is None:
        return open(archive, "rb"), False
    if member == "":
        raise IsADirectoryError(f"{archive} is a zip archive, not a motion file")
    try:
        info = _member_info(archive, member)
        inflated = info.compress_type != zipfile.ZIP_STORED
        if inflated and info.file_size > max_decompressed():
            raise _over_cap(max_decompressed())   # declared: refused before a byte is inflated
        return _zip(archive).open(info), inflated
    except KeyError:
        raise FileNotFoundError(f"no member {member!r} in {archive}") from None
    except zipfile.BadZipFile as exc:
        raise OSError(f"{archive}: not a readable zip archive ({exc})") from None


class _Stream(io.RawIOBase):
    """A decompressing stream whose damaged data raises OSError (as a damaged file does), not the
    codec's own error types, and that stops with OSError past ``cap`` bytes (None: no cap)."""

    def __init__(self, inner, cap=None):
        self.inner = inner
        self.cap = cap
        self.count = 0

    def readable(self):
        return True

    def read(self, size=-1):
        if (size is None or size < 0) and self.cap is None:
            # nothing inflates here (a plain file, a stored zip member): one read, sized by the file
            # (1 MiB pieces gathered in a BytesIO cost a short take's reading twice over)
            try:
                data = self.inner.read()
            except _DECODE_ERRORS as exc:
                raise OSError(f"corrupt compressed data ({exc})") from None
            self.count += len(data)
            return data
        if size is None or size < 0:
            # read all, a bounded piece at a time: one unbounded read of a bomb would inflate it whole
            out = io.BytesIO()
            while chunk := self.read(_CHUNK):
                out.write(chunk)
            return out.getvalue()
        try:
            data = self.inner.read(size if self.cap is None else min(size, self.cap + 1 - self.count))
        except _DECODE_ERRORS as exc:
            raise OSError(f"corrupt compressed data ({exc})") from None
        self.count += len(data)
        if self.cap is not None and self.count > self.cap:
            raise _over_cap(self.cap)
        return data

    def readinto(self, b):
        data = self.read(len(b))
        b[:len(data)] = data
        return len(data)

    def close(self):
        self.inner.close()
        super().close()


#: a plain file up to this size is read whole, once, when ingest hashes it (:func:`read_held`), and its
#: reader is served from those bytes (:func:`holding`); a larger one is hashed and read as a stream
HOLD_MAX = 64 << 20
#: the bytes :func:`holding` serves in this thread, by path
_HELD = threading.local()


def read_held(path) -> bytes | None:
    """The bytes of a plain regular file of at most :data:`HOLD_MAX` bytes, in one read; None for
    anything else (compressed, a zip member, larger, not a regular file: those are streamed).

    Raises
    ------
    OSError
        The file cannot be read.
    """
    if not plain_file(path):
        return None
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode) or st.st_size > HOLD_MAX:   # opening a FIFO would block
        return None
    with open(path, "rb", buffering=0) as fh:
        data = fh.read(st.st_size + 1)   # sized by the file: a larger request allocates its size first
    return data if len(data) <= st.st_size else None   # grown since: streamed


@contextlib.contextmanager
def holding(path, data):
    """Within the block (this thread), :func:`open_stream`, :func:`read_bytes`, :func:`sha256` and
    :func:`stream_size` of ``path`` give ``data`` (its bytes, read once: ingest hashes a take and reads it
    from the same bytes) instead of reading the file; ``data`` None changes nothing."""
    if data is None:
        yield
        return
    held = _HELD.__dict__.setdefault("items", {})
    key = str(path)
    before = held.get(key)
    held[key] = data
    try:
        yield
    finally:
        if before is None:
            del held[key]
        else:
            held[key] = before


def _held(path):
    """What :func:`holding` serves for ``path`` in this thread, or None."""
    held = getattr(_HELD, "items", None)
    return held.get(str(path)) if held else None


def open_stream(path):
    """A binary stream of the recording's bytes (decompressed); close it after use. Damaged
    compressed data, and decompressed bytes past :func:`max_decompressed`, raise OSError."""
    data = _held(path)
    if data is not None:
        return _Stream(io.BytesIO(data))
    raw, inflated = _raw_stream(path)
    module = COMPRESSED.get(as_path(path).suffix.lower())
    # zipfile stops a member at its declared size (checked above) and then checks its CRC; the count
    # guards the compressed file's own stream
    return _Stream(raw if module is None else module.open(raw),
                   max_decompressed() if inflated or module is not None else None)


def stream_size(path) -> int | None:
    """The recording's size in bytes when known without reading it (a plain file, a zip member), else None."""
    data = _held(path)
    if data is not None:
        return len(data)
    archive, member = split_archive(path)
    if as_path(path).suffix.lower() in COMPRESSED:
        return None
    if member is None:
        return os.stat(path).st_size
    return _member_info(archive, member).file_size


def read_bytes(path) -> bytes:
    """The recording's bytes (decompressed, or the zip member's).

    Raises
    ------
    OSError
        Missing or unreadable file, bad archive or compressed stream.
    """
    data = _held(path)
    if data is not None:
        return data
    with open_stream(path) as fh:
        return fh.read()


def sha256(path) -> str:
    """SHA-256 of the recording's bytes, read in 1 MiB chunks (memory does not grow with the file)."""
    data = _held(path)
    if data is not None:
        return hashlib.sha256(data).hexdigest()
    h = hashlib.sha256()
    with open_stream(path) as fh:
        for chunk in iter(lambda: fh.read(_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


def is_file(path) -> bool:
    """True for a regular file, or a member of a zip archive."""
    archive, member = split_archive(path)
    if member is None:
        return as_path(path).is_file()
    if not member:
        return False
    try:
        info = _member_info(archive, member)
    except (KeyError, OSError, zipfile.BadZipFile):
        return False
    return not info.is_dir()


def list_dir(path) -> list:
    """The entries of a folder (or a folder inside a zip archive) as paths; [] when unreadable."""
    archive, member = split_archive(path)
    if member is None:
        try:
            return list(Path(path).iterdir())
        except OSError:
            return []
    prefix = f"{member}/" if member else ""
    try:
        names = zip_members(archive)
    except OSError:
        return []
    out = set()
    for name in names:
        if name.startswith(prefix):
            first = name[len(prefix):].split("/", 1)[0]
            if first:
                out.add(first)
    return [Path(path) / name for name in sorted(out)]


def identity(path) -> tuple:
    """A key that changes when the recording's bytes may have changed (for caches)."""
    archive, member = split_archive(path)
    st = os.stat(archive)
    # the file itself by device and inode (what a symlink or a relative path leads to), not by a resolved
    # path: resolving walks every component (a lstat each), asked per take for its skeleton
    if member is None:
        return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    info = _member_info(archive, member)
    return (st.st_dev, st.st_ino, member, st.st_size, st.st_mtime_ns, info.CRC)


class FileCache:
    """Objects read from files, kept by the file's :func:`identity` (thread-safe).

    Skeletons and body models are read again for every take that uses them
    during an ingest; the objects are immutable, so one read serves all. A
    changed file (size, modification time, a member's CRC) is read anew;
    beyond ``limit`` entries the cache starts over.
    """

    def __init__(self, limit: int):
        self.limit = limit
        self._items: dict = {}
        self._lock = threading.Lock()

    def get(self, path, read):
        """``read(path)``, or what it gave for the same file before."""
        key = identity(path)
        with self._lock:
            hit = self._items.get(key)
        if hit is None:
            hit = read(path)
            with self._lock:
                if len(self._items) > self.limit:
                    self._items.clear()
                self._items[key] = hit
        return hit


def special_kind(path) -> str | None:
    """What a non-regular, non-folder file is (``"a FIFO (named pipe)"``, …), or None.

    Reading such a file could block for ever (a FIFO) or never end (a device).
    """
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return "not a regular file"


@contextlib.contextmanager
def bytes_file(data: bytes, name: str = "recording"):
    """``data`` behind a file name, for libraries that open files themselves: an anonymous in-memory
    file (Linux ``memfd``, named ``/proc/self/fd/N``), or, where that does not exist, a temporary
    file removed on exit."""
    if hasattr(os, "memfd_create") and os.path.isdir("/proc/self/fd"):
        fd = os.memfd_create(f"mocapdb-{name}"[:240])
        try:
            with io.FileIO(fd, "wb", closefd=False) as fh:
                fh.write(data)
            yield Path(f"/proc/self/fd/{fd}")
        finally:
            os.close(fd)
        return
    tmp = tempfile.NamedTemporaryFile(delete=False, suffix=Path(name).suffix)
    try:
        with tmp:
            tmp.write(data)
        yield Path(tmp.name)
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp.name)
