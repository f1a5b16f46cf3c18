"""Seeded mutations of real motion files (the fuzz tests' generator).

Each case is one real file (a short AMC take, its ASF, BVH files of other
tools) with one to three mutations: bytes changed, spans cut or repeated,
truncation, a number replaced by a hostile one (NaN, 1e309, 5e-324, ``1x``,
``1.#QNAN``, 1e36, a frame count of 10^12), structural tokens inserted, line
ends changed. :func:`pack` wraps a case as trackers and archives ship it:
compressed (gzip, bzip2, xz) or a zip member, the packing itself sometimes
damaged.
"""
import re

import numpy as np

HOSTILE_NUMBERS = [b"nan", b"NaN", b"inf", b"-inf", b"1e309", b"-1e308", b"5e-324", b"1e-320", b"1x", b"",
                   b"999999999999999999999999", b"0", b"-0", b"1e12", b"1000000000000", b"0.0", b"+", b"-",
                   b".", b"e5", b"0x10", b"1_000", b"\xff", b"12.5.3",
                   # lost tracking as trackers write it (read as a gap in BVH)
                   b"1.#QNAN", b"-1.#IND", b"1.#INF", b"-nan(ind)", b"Infinity", b"1e36", b"-1e36", b"#", b"1.#"]
INSERTS = [b"{", b"}", b" JOINT x {", b"End Site { OFFSET 0 0 0 }", b"\nFrames: 1000000000000\n",
           b"\nFrame Time: 5e-324\n", b"\n:DEGREES\n", b"\nroot 0 0 0 0 0 0\n", b"\n1\n", b"\x00",
           b"\nbegin\n", b"\nend\n", b"CHANNELS 99 Xposition", b"OFFSET 1e300 0 0", b"\r",
           b"\n:units\n  length 0\n", b"  length -1", b"\nFrame Time: 0\n", b"\nFrame Time: -1\n",
           b"\n" + b"JOINT j {\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" * 3]
_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    """One to three random mutations of ``data``."""
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        op = int(rng.integers(0, 8))
        n = len(out)
        if n == 0:
            out = bytearray(b"x")
            n = 1
        i = int(rng.integers(0, n))
        if op == 0:    # change a few bytes
            for _ in range(int(rng.integers(1, 6))):
                out[int(rng.integers(0, n))] = int(rng.integers(0, 256))
        elif op == 1:  # cut a span
            j = min(n, i + int(rng.integers(1, 200)))
            del out[i:j]
        elif op == 2:  # repeat a span
            j = min(n, i + int(rng.integers(1, 400)))
            out[i:i] = out[i:j] * int(rng.integers(1, 4))
        elif op == 3:  # truncate
            del out[i:]
        elif op == 4 or op == 5:  # a hostile number in place of a real one
            nums = list(_NUMBER.finditer(bytes(out)))
            if nums:
                m = nums[int(rng.integers(0, len(nums)))]
                out[m.start():m.end()] = HOSTILE_NUMBERS[int(rng.integers(0, len(HOSTILE_NUMBERS)))]
        elif op == 6:  # insert a structural token
            out[i:i] = INSERTS[int(rng.integers(0, len(INSERTS)))]
        else:          # line ends: LF -> CR, CRLF or nothing
            to = [b"\r", b"\r\n", b" "][int(rng.integers(0, 3))]
            out = bytearray(bytes(out).replace(b"\n", to))
    return bytes(out)


def pack(data: bytes, name: str, folder, rng: np.random.Generator):
    """``data`` written under ``folder`` as ``name`` plain, compressed or inside a zip archive (the
    packed bytes cut or changed in a quarter of the cases); returns the path to read."""
    import bz2
    import gzip
    import lzma
    import zipfile

    how = int(rng.integers(0, 5))
    if how == 0:
        path = folder / name
        path.write_bytes(data)
        return path
    if how == 4:
        archive = folder / f"{name}.zip"
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr(f"takes/{name}", data)
        path, packed = archive / "takes" / name, archive
    else:
        suffix, module = ((".gz", gzip), (".bz2", bz2), (".xz", lzma))[how - 1]
        packed = folder / (name + suffix)
        packed.write_bytes(module.compress(data))
        path = packed
    if rng.random() < 0.25:
        raw = bytearray(packed.read_bytes())
        if rng.random() < 0.5:
            del raw[int(rng.integers(1, len(raw))):]
        else:
            for _ in range(int(rng.integers(1, 4))):
                raw[int(rng.integers(0, len(raw)))] = int(rng.integers(0, 256))
        packed.write_bytes(bytes(raw))
    return path


_MIB = 1 << 20


def bomb(kind: str, expanded: int, *, head: bytes = b"", line: bytes = b"\0") -> bytes:
    """A compression bomb: ``head``, then ``line`` repeated to about ``expanded`` bytes, compressed as
    ``kind`` (``"gz"``, ``"bz2"``, ``"xz"``) in milliseconds — one compressed MiB of it repeated as
    concatenated streams, which each format reads as one (2 GiB of a frame line: ~2 MB of gzip)."""
    import bz2
    import gzip
    import lzma

    module = {"gz": gzip, "bz2": bz2, "xz": lzma}[kind]
    unit = module.compress(line * (_MIB // len(line)))
    return module.compress(head) + unit * max(1, expanded // _MIB)


def zip_bomb(path, name: str, expanded: int, *, declared: int | None = None, others=()):
    """A zip archive whose member ``name`` inflates to ``expanded`` bytes of zeros (declared as
    ``declared``, default the truth: a lying header declares less), beside ``others`` ((name, bytes)
    members, deflated); written by hand in milliseconds: one MiB of zeros deflated and full-flushed,
    the self-contained blocks repeated."""
    import struct
    import zlib

    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    unit = c.compress(bytes(_MIB)) + c.flush(zlib.Z_FULL_FLUSH)
    members = [(name, unit * max(1, expanded // _MIB) + b"\x03\x00", 0,
                expanded if declared is None else declared)]
    for other, data in others:
        z = zlib.compressobj(9, zlib.DEFLATED, -15)
        members.append((other, z.compress(data) + z.flush(), zlib.crc32(data), len(data)))
    out, central = bytearray(), bytearray()
    for member, packed, crc, size in members:
        encoded = member.encode()
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0x21, crc, len(packed),
                               size, len(encoded), 0, 0, 0, 0, 0, len(out)) + encoded
        out += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0x21, crc, len(packed), size,
                           len(encoded), 0) + encoded + packed
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(members), len(members), len(central), len(out), 0)
    path.write_bytes(bytes(out + central + end))
    return path
