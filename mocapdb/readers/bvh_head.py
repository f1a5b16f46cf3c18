"""The start of a BVH file: its header read (``HIERARCHY`` … the ``Frame Time`` line), and what cannot
be a BVH refused from its first bytes.

A BVH file's header is short lines of hierarchy; its motion lines follow. What a reader sees first
decides: a file whose first word is not ``HIERARCHY``, or a "line" of megabytes (a 0.5 MB ``.bvh.gz``
holding 500 MiB of NUL bytes), is refused after one block, not after reading it to its end (197 s and
1.3 GB before, issue 33). The rest of the file is :mod:`mocapdb.readers.bvh`'s.
"""
from __future__ import annotations

import io
import re

from mocapdb.errors import ParseError
from mocapdb.readers.textscan import longest_line

__all__ = ["MAX_HEADER_LINE", "READ_BLOCK", "FRAMES", "FRAME_TIME", "find_motion", "read_head", "check_bvh_start"]

#: the MOTION section's lines: ``Frames:``, ``Frame Time:`` and MOTION itself
FRAMES = re.compile(rb"Frames\s*:?\s*(\S*)", re.IGNORECASE)
FRAME_TIME = re.compile(rb"Frame\s*Time\s*:?\s*([^\s]*)", re.IGNORECASE)
_WORD_BYTES = frozenset(b"abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_")


def find_motion(data, pos: int = 0):
    """``(start, end)`` of the first ``MOTION`` line at or after ``pos``: what the regular expression
    ``(?m)^[ \t]*MOTION\b`` searched from ``pos`` matches (start = the line's start, end = after the
    keyword), or None. By ``bytes.find`` of the keyword: the expression, tried at every byte of the
    header, cost ~45 µs a take (issue 35)."""
    at = data.find(b"MOTION", pos)
    while at >= 0:
        line = data.rfind(b"\n", 0, at) + 1
        end = at + 6
        if (line >= pos and not data[line:at].strip(b" \t")
                and (end == len(data) or data[end] not in _WORD_BYTES)):
            return line, end
        at = data.find(b"MOTION", at + 1)
    return None


#: bytes of a BVH file read and parsed at a time: the text is never held whole
READ_BLOCK = 1 << 22


#: the longest line of a BVH header (HIERARCHY … Frame Time): a few hundred bytes in any file seen; a
#: "line" of megabytes (a file of NUL bytes) is no BVH, refused at once instead of read to its end
MAX_HEADER_LINE = 1 << 14
_WORD = re.compile(rb"[^\s\x00]{1,16}")
#: what a UTF-8 byte-order mark is made of (stripped before the first word)
_BOM_BYTES = re.compile(rb"[\xef\xbb\xbf]*")


def read_head(fh, path, block=READ_BLOCK):
    """The file's bytes up to the end of the ``Frame Time`` line (or all, if there is none), and
    whether the stream is exhausted.

    Decided from the first bytes: a file whose first word is not ``HIERARCHY`` is refused after one
    block, and a header line longer than :data:`MAX_HEADER_LINE` as soon as it is read, so a
    hostile file (500 MiB of NUL bytes in a 0.5 MB ``.bvh.gz``) costs one block, not its size.
    Linear in what it reads: each block is searched once (with the few bytes before it)."""
    head = b""      # the first read as it came (a short take's whole text: no copy), a bytearray after
    carry = 0       # the unfinished line's length so far (before MOTION)
    motion = None   # where MOTION starts, once found
    decided = False
    while True:
        chunk = fh.read(block)
        start = len(head)
        if not start:
            head = chunk
        elif chunk:
            if not isinstance(head, bytearray):
                head = bytearray(head)
            head += chunk
        if not decided and (len(head) >= 1024 or not chunk):   # the first word, once there are bytes enough
            decided = True
            # the first word after the byte-order mark's bytes, searched in place (lstrip copied the head)
            first = _WORD.search(head, _BOM_BYTES.match(head).end())
            if first is not None and first.group().upper() != b"HIERARCHY":
                raise ParseError(path, 1, "expected 'HIERARCHY' (not a BVH file?)")
        if not chunk:
            return bytes(head), True
        if motion is None:
            m = find_motion(head, max(0, start - 64))
            motion = None if m is None else m[0]
            longest, carry = longest_line(chunk if motion is None else chunk[:max(0, motion - start)], carry)
            if longest > MAX_HEADER_LINE:
                raise ParseError(path, None, f"a header line longer than {MAX_HEADER_LINE:,} bytes (a BVH "
                                 "header's lines are short: not a BVH file?)")
        if motion is not None:
            tm = FRAME_TIME.search(head, motion, motion + 4096)
            if tm is not None and head.find(b"\n", tm.end()) >= 0:
                return bytes(head), False


def check_bvh_start(data: bytes, path) -> None:
    """Refuse what cannot be a BVH file from its first bytes (:func:`read_head`'s checks: the first word,
    the header's line lengths).

    Raises
    ------
    ParseError
    """
    read_head(io.BytesIO(data), path)
