"""House rules that keep the package as STYLE.md describes it (checked on the source text)."""
import ast
import re

import pytest

from conftest import REPO

LIBRARY = sorted([*(REPO / "mocapdb").glob("*.py"), *(REPO / "extension").glob("*.py")])


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: p.name)
def test_numba_options_live_in_one_place(path):
    """Kernels use mocapdb._numba.jit / pjit; no module sets numba options of its own."""
    if path.name == "_numba.py":
        return
    text = path.read_text(encoding="utf-8")
    assert not re.search(r"\b(njit|numba\.jit|numba\.njit|nopython\s*=|fastmath\s*=)", text), path.name


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: p.name)
def test_the_library_never_prints(path):
    """Only the CLI writes to the terminal (through click)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    calls = [n.lineno for n in ast.walk(tree)
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "print"]
    assert not calls, f"{path.name}: print() at lines {calls}"


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: p.name)
def test_public_functions_have_docstrings(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    missing = [n.name for n in tree.body
               if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")
               and ast.get_docstring(n) is None and not (path.name == "cli.py")]
    assert not missing, f"{path.name}: no docstring for {missing}"
