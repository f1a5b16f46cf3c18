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


__all__ = ["jit", "pjit", "inline_jit", "prange", "limit_threads", "trailing_zeros", "address", "load_u64", "load_u8", "store_i64"]
