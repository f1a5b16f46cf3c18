"""Build step that fills numba's cache: the wheel carries the compiled kernels.

Everything else about the package is in pyproject.toml. ``pip install .``
builds a wheel on the machine it installs on; after copying the package,
this step runs ``python -m mocapdb.warmup`` on the built copy
(mocapdb/warmup.py), which compiles every kernel the commands use, with the
argument types of real calls, into the built package's ``__pycache__``. numba
uses an entry only for the same numba version, Python, CPU and source bytes,
so a wheel taken to another machine still works: it compiles there as it
goes. ``MOCAPDB_PRECOMPILE=0`` skips the step. A failure of the step never
fails the build.
"""
import os
import subprocess
import sys
import time

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithKernels(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False) or os.environ.get("MOCAPDB_PRECOMPILE", "1") == "0":
            return
        # prepend, never replace: pip's isolated build environment reaches its own
        # packages (numba, duckdb, ...) through PYTHONPATH
        path = os.pathsep.join(p for p in (os.path.abspath(self.build_lib), os.environ.get("PYTHONPATH")) if p)
        env = dict(os.environ, PYTHONPATH=path, NUMBA_DISABLE_JIT="0")
        env.pop("NUMBA_CACHE_DIR", None)  # the cache must land beside the built modules
        cmd = [sys.executable, "-m", "mocapdb.warmup"]
        t0 = time.perf_counter()
        try:
            # reading first, then the two annotation halves side by side (two cores)
            ok = subprocess.run([*cmd, "ingest"], cwd=self.build_lib, env=env).returncode == 0
            if ok:
                procs = [subprocess.Popen([*cmd, part], cwd=self.build_lib, env=env) for part in ("search", "segments")]
                ok = all(p.wait() == 0 for p in procs)
        except OSError as exc:
            ok = False
            print(f"mocapdb: compiling the kernels failed ({exc})", file=sys.stderr)
        print(f"mocapdb: kernels {'compiled' if ok else 'NOT compiled (they compile on first use)'} "
              f"in {time.perf_counter() - t0:.0f} s", file=sys.stderr)


setup(cmdclass={"build_py": BuildPyWithKernels})
