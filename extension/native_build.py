"""Building ``mocapdb.duckdb_extension``: the C sources of ``extension/src`` compiled with the
system C compiler into a shared library, with DuckDB's extension metadata footer appended.

Plain standard library, no mocapdb import: ``setup.py`` runs this file at build time (before the
package is importable), and the sanitizer test builds a second copy with
``-fsanitize=address,undefined``. The footer (534 bytes) is what ``LOAD`` reads before it opens
the library: a WebAssembly-style custom section named ``duckdb_signature`` holding eight 32-byte
fields, written last field first — metadata version "4", platform, the C API version, the
extension version, the ABI type ``C_STRUCT`` — and 256 bytes of signature (zeros: the extension
is unsigned, so DuckDB loads it only with ``allow_unsigned_extensions`` / ``duckdb -unsigned``).
"""
from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: the file name LOAD derives the entry point ``mocapdb_init_c_api`` from
BINARY_NAME = "mocapdb.duckdb_extension"
#: written beside the package instead of the binary when it could not be built: why
MISSING_NAME = "mocapdb.duckdb_extension.missing"
#: the stable C extension API version the extension targets: every DuckDB from 1.2.0 on loads it
#: (checked: the CLI 1.5.x and Python duckdb 2.0.x); docs/EXTENSION.md
C_API_VERSION = (1, 2, 0)
HERE = Path(__file__).resolve().parent
SOURCES = HERE / "src"
HEADERS = HERE / "third_party" / "duckdb"
#: shipped builds: warnings are errors (issue 31); no fused multiply-add (numba has none: Δ bit for bit)
CFLAGS = ["-std=gnu11", "-O2", "-ffp-contract=off", "-fPIC", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror"]
SANITIZE_FLAGS = ["-O1", "-g", "-fno-omit-frame-pointer", "-fsanitize=address,undefined",
                  "-fno-sanitize-recover=undefined"]


class BuildError(Exception):
    """The extension could not be built here (the message says why, in one line)."""


def duckdb_platform() -> str:
    """DuckDB's name of this machine's platform (``PRAGMA platform``), for the footer."""
    machine = platform.machine().lower()
    arch = {"x86_64": "amd64", "amd64": "amd64", "aarch64": "arm64", "arm64": "arm64"}.get(machine)
    if not sys.platform.startswith("linux") or arch is None:
        raise BuildError(f"the native extension is built on Linux x86-64 and arm64 only, not {sys.platform} "
                         f"{machine}")
    return f"linux_{arch}"


def footer(platform_name: str, extension_version: str) -> bytes:
    """DuckDB's extension metadata footer (unsigned)."""
    major, minor, patch = C_API_VERSION
    fields = ["4", platform_name, f"v{major}.{minor}.{patch}", extension_version, "C_STRUCT", "", "", ""]
    for f in fields:
        if len(f.encode()) > 32:
            raise BuildError(f"extension metadata field {f!r} is longer than 32 bytes")
    meta = b"".join(f.encode().ljust(32, b"\0") for f in reversed(fields))
    # custom section 0, length 531 (LEB128), name of 16 bytes, payload of 512 bytes (LEB128)
    return b"\x00\x93\x04\x10duckdb_signature\x80\x04" + meta + b"\0" * 256


def compiler() -> str:
    """The C compiler to build with: $CC, else gcc or cc on PATH."""
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise BuildError("no C compiler (gcc or cc) on PATH; install one and reinstall mocapdb to get the "
                         "native extension")
    return cc


def build(out: Path, *, extension_version: str = "dev", sanitize: bool = False) -> Path:
    """Compile the extension into ``out`` (written atomically). Raises :class:`BuildError`."""
    out = Path(out)
    plat = duckdb_platform()
    major, minor, patch = C_API_VERSION
    flags = CFLAGS + (SANITIZE_FLAGS if sanitize else [])
    defines = [f"-DDUCKDB_EXTENSION_API_VERSION_MAJOR={major}", f"-DDUCKDB_EXTENSION_API_VERSION_MINOR={minor}",
               f"-DDUCKDB_EXTENSION_API_VERSION_PATCH={patch}"]
    sources = sorted(str(p) for p in SOURCES.glob("*.c"))
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        lib = Path(tmp) / "mocapdb.so"
        cmd = [compiler(), *flags, *defines, "-isystem", str(HEADERS), "-shared", "-o", str(lib), *sources,
               "-lpthread", "-lm"]
        try:
            run = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise BuildError(f"running the C compiler {cmd[0]} failed ({exc.strerror}); install gcc and reinstall "
                             "mocapdb to get the native extension") from None
        if run.returncode != 0:
            first = next((line for line in run.stderr.splitlines() if "error" in line), run.stderr.strip()[:300])
            raise BuildError(f"compiling the native extension failed: {first}")
        with open(lib, "ab") as f:
            f.write(footer(plat, extension_version))
        os.replace(lib, out)
    return out


def build_or_explain(package_dir: Path, *, extension_version: str = "dev") -> str:
    """Build into ``package_dir`` or leave the reason there (``MISSING_NAME``); returns a one-line status."""
    package_dir = Path(package_dir)
    missing = package_dir / MISSING_NAME
    try:
        path = build(package_dir / BINARY_NAME, extension_version=extension_version)
    except BuildError as exc:
        (package_dir / BINARY_NAME).unlink(missing_ok=True)  # never a stale binary beside the reason
        missing.write_text(f"{exc}\n")
        return f"native extension NOT built: {exc}"
    missing.unlink(missing_ok=True)
    return f"native extension built: {path}"
