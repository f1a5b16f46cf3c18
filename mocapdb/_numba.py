"""Numba options for every kernel of the package, set in one place.

``cache=True`` is deliberate: the CLI and the SQL functions start in fresh
processes, and a cold compile of the feature kernels costs seconds.
``nogil=True`` lets a thread pool run kernels side by side (DuckDB calls a
Python UDF from one thread; parallelism happens inside).

The few LLVM intrinsics the kernels share live here too, each with its
plain-Python twin: an intrinsic cannot run as Python, and CI runs the kernels'
twins with ``NUMBA_DISABLE_JIT=1``.
"""
import ctypes

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.cpython.unsafe.numbers import trailing_zeros as _tz_intrinsic  # LLVM cttz (64 for 0)
from numba.extending import intrinsic

#: Serial kernel: compiled once, cached on disk, releases the GIL.
jit = numba.njit(cache=True, nogil=True, error_model="numpy")

#: Parallel kernel: as :data:`jit`, with ``prange`` loops over independent
#: takes, templates or chunks (each iteration writes only its own slice).
pjit = numba.njit(cache=True, nogil=True, parallel=True, error_model="numpy")

#: Small helper inlined into its callers at numba's IR level (the number
#: scanner: a call per token would cost a third of a reader's time).
inline_jit = numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")

prange = numba.prange


def limit_threads(n: int) -> None:
    """Let the parallel kernels of the calling thread use at most ``n`` threads.

    Numba keeps this setting per thread, so a worker calls it in the thread
    that runs the kernels (e.g. a Ray actor with one CPU: 1).
    """
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


@intrinsic
def _address_intrinsic(typingctx, buf):
    """The address of ``buf[0]`` (a contiguous 1-D array) as an int64."""
    if not (isinstance(buf, types.Array) and buf.ndim == 1 and buf.layout == "C"):
        return None
    sig = types.int64(buf)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        return builder.ptrtoint(ary.data, ir.IntType(64))
    return sig, codegen


def _load_intrinsic(bits, nbtype):
    @intrinsic
    def load(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None
        sig = nbtype(addr)

        def codegen(context, builder, signature, args):
            ptr = builder.inttoptr(args[0], ir.IntType(bits).as_pointer())
            return builder.load(ptr, align=1)
        return sig, codegen
    return load


@intrinsic
def _store_i64_intrinsic(typingctx, addr, value):
    """Write the int64 ``value`` at ``addr``."""
    if not (isinstance(addr, types.Integer) and isinstance(value, types.Integer)):
        return None
    sig = types.void(addr, value)

    def codegen(context, builder, signature, args):
        ptr = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        builder.store(context.cast(builder, args[1], signature.args[1], types.int64), ptr)
        return context.get_dummy_value()
    return sig, codegen


def _store_i64_python(addr, value):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    ctypes.c_int64.from_address(int(addr)).value = int(value)


def _address_python(buf):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    return buf.ctypes.data


def _load_u64_python(addr):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    return int.from_bytes(ctypes.string_at(int(addr), 8), "little")


def _load_u8_python(addr):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    return ctypes.string_at(int(addr), 1)[0]


def _tz_python(x):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    x = int(x)
    return (x & -x).bit_length() - 1 if x else 64


# ---- byte-class masks: one vector load of 32 or 64 bytes, compared against a splat, the lanes
# packed into the bits of an integer. LLVM lowers the vector IR for the host: on x86-64 with AVX2
# a vpcmpeqb/vpminub and a vpmovmskb per 32 bytes, with AVX-512BW one mask compare per 64; on
# any other CPU it legalises the vectors into whatever the target has, so the result is the same
# everywhere. The load is unaligned and reads exactly ``width`` bytes from ``addr``: the caller
# keeps them within its buffer (the scalar path takes a text's last bytes).

def _splat(builder, vt, value):
    """``value`` (an integer) truncated to a byte and repeated in every lane of ``vt``."""
    byte = builder.trunc(value, ir.IntType(8))
    one = builder.insert_element(ir.Constant(vt, ir.Undefined), byte, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(one, ir.Constant(vt, ir.Undefined),
                                  ir.Constant(ir.VectorType(ir.IntType(32), vt.count), [0] * vt.count))


def _mask_intrinsic(kind):
    """An intrinsic ``(addr, c) -> uint64``: bit k set when the byte at ``addr + k`` (k < 64) is ``== c``
    (kind "eq") or ``<= c`` unsigned ("le"). One unaligned 64-byte load, a compare against ``c`` in every
    lane, the lanes' results as the bits of one word: LLVM lowers it to the target's byte compares and
    mask moves (AVX-512BW, AVX2 in two halves, NEON, or scalar code elsewhere)."""
    def mask(typingctx, addr, c):
        if not (isinstance(addr, types.Integer) and isinstance(c, types.Integer)):
            return None
        sig = types.uint64(addr, c)

        def codegen(context, builder, signature, cargs):
            cargs = [context.cast(builder, a, t, types.int64) for a, t in zip(cargs, signature.args)]
            vt = ir.VectorType(ir.IntType(8), 64)
            v = builder.load(builder.inttoptr(cargs[0], vt.as_pointer()), align=1)
            hit = builder.icmp_unsigned("==" if kind == "eq" else "<=", v, _splat(builder, vt, cargs[1]))
            return builder.bitcast(hit, ir.IntType(64))
        return sig, codegen

    mask.__name__ = f"_mask64_{kind}_intrinsic"
    return intrinsic(mask)


def _mask_python(kind):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    def mask(addr, c):
        data = ctypes.string_at(int(addr), 64)
        c = int(c) & 255
        hits = [x == c for x in data] if kind == "eq" else [x <= c for x in data]
        return np.uint64(sum(1 << k for k, h in enumerate(hits) if h))
    mask.__name__ = f"_mask64_{kind}_python"
    return mask


# an intrinsic cannot run as plain Python (the NUMBA_DISABLE_JIT job of CI)
#: count of trailing zero bits of an unsigned integer (64 for a uint64 0)
trailing_zeros = _tz_python if numba.config.DISABLE_JIT else _tz_intrinsic
# Reading bytes by address: numba counts the references to an array handed to a function, with an
# atomic add and a call to release it that its pruning cannot remove where the callee branches and
# loops; for a number scanner inlined per token that was most of its time. An address is a plain
# integer. The caller keeps the array alive and the reads within it.
#: ``address(buf)``: the address of ``buf[0]`` (a contiguous 1-D array), an int64
address = _address_python if numba.config.DISABLE_JIT else _address_intrinsic
#: ``load_u64(addr)``: the 8 bytes at ``addr`` as a little-endian uint64 (one unaligned load)
load_u64 = _load_u64_python if numba.config.DISABLE_JIT else _load_intrinsic(64, types.uint64)
#: ``load_u8(addr)``: the byte at ``addr``
load_u8 = _load_u8_python if numba.config.DISABLE_JIT else _load_intrinsic(8, types.uint8)
#: ``store_i64(addr, value)``: write an int64 at ``addr``
store_i64 = _store_i64_python if numba.config.DISABLE_JIT else _store_i64_intrinsic

#: ``mask64_eq(addr, c)``: bit k set where the byte at ``addr + k`` equals ``c`` (uint64)
mask64_eq = _mask_python("eq") if numba.config.DISABLE_JIT else _mask_intrinsic("eq")
#: ``mask64_le(addr, c)``: bit k set where the byte at ``addr + k`` is at most ``c``
#: (unsigned: ``mask64_le(addr, 0x20)`` finds the blanks, line ends and control bytes)
mask64_le = _mask_python("le") if numba.config.DISABLE_JIT else _mask_intrinsic("le")


__all__ = ["jit", "pjit", "inline_jit", "prange", "limit_threads", "trailing_zeros", "address", "load_u64", "load_u8", "store_i64",
           "mask64_eq", "mask64_le"]
