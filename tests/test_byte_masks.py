"""The byte-vector mask intrinsics of ``mocapdb._numba`` (``mask64_eq``, ``mask64_le``: one vector load,
a compare against a splat, the lanes packed into bits) and their plain-Python twins equal a numpy brute force
at every alignment of random bytes, up to the last byte of a buffer; and the motion-line kernel that uses them
never reads past the text (it ends on a page that is followed by an unreadable one)."""
import ctypes
import mmap

import numba
import numpy as np
import pytest

from mocapdb import _numba as nb
from mocapdb.readers.textscan import parse_rows

KINDS = {  # name -> (the byte compared against, the bytes each sets a bit for)
    "eq": (10, lambda b: b == 10),
    "le": (32, lambda b: b <= 32),
}


def _compiled(kind):
    """A kernel that takes the mask of 64 bytes at every offset of a buffer (the intrinsic compiled;
    under NUMBA_DISABLE_JIT the twin runs as Python)."""
    fn = getattr(nb, f"mask64_{kind}")
    c = KINDS[kind][0]

    @numba.njit
    def masks(buf, out):
        base = nb.address(buf)
        for i in range(out.shape[0]):
            out[i] = fn(base + i, c)
    return masks


def _brute(buf, kind):
    hit = KINDS[kind][1](buf.astype(np.int64))
    return np.array([int(np.packbits(hit[i:i + 64], bitorder="little").view("<u8")[0])
                     for i in range(buf.size - 64 + 1)], dtype=np.uint64)


@pytest.mark.parametrize("kind", list(KINDS))
def test_masks_equal_a_brute_force_at_every_alignment(kind):
    rng = np.random.default_rng(len(kind))
    alphabet = np.frombuffer(b"0123456789 \t\r\n.-+eE\x00\x0b\x7f\x80\xfe\xff", np.uint8)
    for trial in range(6):
        n = int(rng.integers(64, 3 * 64 + 40))
        # a buffer of exactly n bytes: the last mask ends on its last byte
        buf = rng.choice(alphabet, n) if trial % 2 else rng.integers(0, 256, n, dtype=np.uint8)
        ref = _brute(buf, kind)
        got = np.zeros(n - 64 + 1, dtype=np.uint64)
        _compiled(kind)(buf, got)
        assert np.array_equal(got, ref)
        twin = nb._mask_python(kind)
        base = buf.ctypes.data
        assert [int(twin(base + i, KINDS[kind][0])) for i in range(n - 64 + 1)] == ref.tolist()


def _guarded_page():
    """An anonymous mapping of two pages whose second one cannot be read: ``(map, address of page 1's
    first byte, page size)``."""
    page = mmap.PAGESIZE
    m = mmap.mmap(-1, 2 * page)
    addr = ctypes.addressof(ctypes.c_char.from_buffer(m))
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    if libc.mprotect(ctypes.c_void_p(addr + page), page, 0) != 0:  # PROT_NONE
        pytest.fail(f"mprotect failed: errno {ctypes.get_errno()}")
    return m, page


@pytest.mark.parametrize("newline", [b"", b"\n", b" \r\n"])
def test_motion_lines_never_read_past_the_text(newline):
    # the text's last byte is the last readable byte of the process's mapping: a load of one byte past
    # it would crash the test; every length of the last line is tried, so each word and vector read
    # meets the end of the text at each of its bytes
    m, page = _guarded_page()
    rng = np.random.default_rng(len(newline))
    try:
        for trial in range(160):
            n_cols = int(rng.integers(1, 12))
            rows = [[round(float(x), int(rng.integers(0, 7))) for x in rng.normal(0, 80, n_cols)]
                    for _ in range(int(rng.integers(1, 5)))]
            text = b"\n".join(b" ".join(repr(v).encode() for v in r) for r in rows) + newline
            text = b" " * int(rng.integers(0, 70)) + text
            start = page - len(text)
            m[start:page] = text
            view = memoryview(m)[start:page]
            try:
                got = parse_rows(view, 0, len(rows), n_cols, "<guarded>")
            finally:
                view.release()
            assert np.array_equal(got, np.array(rows)), text
    finally:
        m.close()
