"""Build steps: the native DuckDB extension (extension/native_build.py: gcc, the C sources of
extension/src, DuckDB's metadata footer) and numba's cache: the wheel carries both.

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
import re
import runpy
import subprocess
import sys
import time
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


def build_native_extension(package_dir):
    """Compile the native DuckDB extension (extension/native_build.py) into ``package_dir``; a machine
    without a C compiler still installs (the reason is left beside the package: mocapdb extension-path)."""
    here = Path(__file__).resolve().parent
    builder = runpy.run_path(str(here / "extension" / "native_build.py"))
    version = re.search(r'^version = "([^"]+)"', (here / "pyproject.toml").read_text(), re.M).group(1)
    print(f"mocapdb: {builder['build_or_explain'](package_dir, extension_version='v' + version)}", file=sys.stderr)


class BuildPyWithKernels(build_py):
    def run(self):
        super().run()
        # editable installs import extension/ itself: the binary goes there (git ignores it)
        editable = getattr(self, "editable_mode", False)
        build_native_extension(Path(__file__).resolve().parent / "extension" if editable else Path(self.build_lib) / "mocapdb" / "extension")
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
