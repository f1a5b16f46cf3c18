"""The numba kernels' compiled cache: compile it now (``mocapdb warmup``), and the state the
command line's first-run messages need (:mod:`mocapdb.warmup`)."""
from __future__ import annotations

from mocapdb.warmup import (PARTS, background_compile_running, cache_is_cold, compile_kernels,
                            start_background_compile, wait_for_background_compile)


def warmup(*, parts=None) -> float:
    """Compile the numba kernels into numba's cache now.

    ``pip install .`` does this when it builds the package, so a new install
    answers at once; this is for installs without that cache (editable, or
    another numba version). See :mod:`mocapdb.warmup`.

    Parameters
    ----------
    parts : iterable of {"ingest", "search", "segments"}, optional, keyword-only
        Default: all.

    Returns
    -------
    float
        Seconds it took.
    """
    return compile_kernels(parts or PARTS)


#: the numba cache's state and the background compile a cold first run starts, for the command
#: line's messages (not commands)
kernels_cold = cache_is_cold
__all__ = ["warmup", "kernels_cold", "start_background_compile", "background_compile_running",
           "wait_for_background_compile"]
