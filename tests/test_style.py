"""House rules that keep the package as STYLE.md and docs/ARCHITECTURE.md describe it
(checked on the source text)."""
import ast
import re

import pytest

from conftest import REPO

LIBRARY = sorted([*(REPO / "mocapdb").rglob("*.py"), *(REPO / "extension").glob("*.py")])

#: the sub-packages in pipeline order (docs/ARCHITECTURE.md): each imports only from those before it
LAYERS = ("errors", "_numba", "bodies", "readers", "writers", "features", "templates", "keyframes", "annotation",
          "learning", "retrieval", "evaluation", "storage", "extension", "viewer", "distributed", "warmup", "api", "server", "cli")


def _module(path):
    rel = path.relative_to(REPO)
    parts = list(rel.with_suffix("").parts)
    if parts[0] == "extension":
        parts = ["mocapdb", *parts]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _layer(module):
    """The sub-package (layer) of a module name under mocapdb, or None for mocapdb itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _imports(path):
    """(line, imported module, imported names) of every import statement, also inside functions."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    mod = _module(path)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((node.lineno, a.name, ()) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([node.module] if node.module else []))
            out.append((node.lineno, base, tuple(a.name for a in node.names)))
    return out


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_numba_options_live_in_one_place(path):
    """Kernels use mocapdb._numba.jit / pjit; no module sets numba options of its own."""
    if path.name == "_numba.py":
        return
    text = path.read_text(encoding="utf-8")
    assert not re.search(r"\b(njit|numba\.jit|numba\.njit|nopython\s*=|fastmath\s*=)", text), path.name


@pytest.mark.slow
@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_the_library_never_prints(path):
    """Only the CLI writes to the terminal (through click)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    calls = [n.lineno for n in ast.walk(tree)
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "print"]
    assert not calls, f"{path.name}: print() at lines {calls}"


@pytest.mark.slow
@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_public_functions_have_docstrings(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    missing = [n.name for n in tree.body
               if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")
               and ast.get_docstring(n) is None and "cli" not in path.relative_to(REPO).parts]
    assert not missing, f"{path.name}: no docstring for {missing}"


@pytest.mark.slow
@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_imports_follow_the_pipeline(path):
    """A module imports only from its own sub-package and those before it (no cycles possible),
    and no private name from another sub-package."""
    mod = _module(path)
    own = _layer(mod)
    if own is None:  # mocapdb/__init__.py re-exports the API
        return
    for line, target, names in _imports(path):
        if not target.startswith("mocapdb"):
            continue
        other = _layer(target)
        if other is None:
            pytest.fail(f"{mod}:{line} imports the top-level package mocapdb (import the sub-package)")
        assert LAYERS.index(other) <= LAYERS.index(own), \
            f"{mod}:{line} imports {target}: {other} comes after {own} in the pipeline"
        if other != own:
            private = [n for n in names if n.startswith("_")]
            assert not private, f"{mod}:{line} imports private names {private} from another sub-package"


@pytest.mark.parametrize("path", [p for p in LIBRARY if "bodies" in p.relative_to(REPO).parts],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_bodies_import_no_format(path):
    """Skeletons, poses and their forward kinematics work on arrays and the plain data of bodies.acclaim, below
    every file format (issue 34 item 3): a body module imports from the library only mocapdb.errors,
    mocapdb._numba and bodies, never a reader or a writer (fast-lane guard; the pipeline test is slow)."""
    for line, target, _ in _imports(path):
        if target.startswith("mocapdb"):
            assert target.split(".")[1] in ("bodies", "errors", "_numba"), \
                f"{_module(path)}:{line} imports {target}; a body module imports no format"


@pytest.mark.parametrize("path", [p for p in LIBRARY if "api" in p.relative_to(REPO).parts],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_the_api_imports_neither_of_its_faces(path):
    """No import goes against the pipeline, not even a lazy one: ``mocapdb serve`` is started by the CLI
    (mocapdb.server.serve), so the API no longer imports the server above it (the api ↔ server cycle of
    issue 34; fast-lane guard, the pipeline test is slow)."""
    for line, target, _ in _imports(path):
        assert target.split(".")[:2] not in (["mocapdb", "server"], ["mocapdb", "cli"]), \
            f"{_module(path)}:{line} imports {target}; the server and the CLI sit above the API"


@pytest.mark.parametrize("path", [p for p in LIBRARY if "cli" in p.relative_to(REPO).parts],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_the_cli_imports_only_the_api_the_server_and_the_errors(path):
    """The command line is a skin over mocapdb.api (sqlite-utils style): from the library it imports only
    mocapdb.api, mocapdb.errors and its own modules, and mocapdb.server, which ``mocapdb serve`` starts (the
    server is a second face on the API, above it: were the API to start it, the API would import a layer
    above its own)."""
    for line, target, _ in _imports(path):
        if target.startswith("mocapdb"):
            assert target.split(".")[:2] in (["mocapdb", "api"], ["mocapdb", "server"], ["mocapdb", "errors"],
                                             ["mocapdb", "cli"]), \
                f"{_module(path)}:{line} imports {target}; the CLI calls mocapdb.api (or starts mocapdb.server)"


@pytest.mark.parametrize("path", [p for p in LIBRARY if "server" in p.relative_to(REPO).parts],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_the_server_is_a_face_on_the_api(path):
    """The web app reads the archive through mocapdb.api as the command line does (issue 34): from the library
    it imports only mocapdb.api (the viewer's pages too, through mocapdb.api.pages), mocapdb.errors and its own
    modules."""
    for line, target, _ in _imports(path):
        if target.startswith("mocapdb"):
            assert target.split(".")[1] in ("api", "errors", "server"), \
                f"{_module(path)}:{line} imports {target}; the server calls mocapdb.api"


_SQL_FSTRING = re.compile(r"\.(execute|sql|executemany)\(\s*f[\"']")


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_sql_lives_in_sql_files(path):
    """SQL text is in sql/*.sql (named statements); no statement is built with an f-string."""
    text = path.read_text(encoding="utf-8")
    lines = [text[:m.start()].count("\n") + 1 for m in _SQL_FSTRING.finditer(text)]
    assert not lines, f"{path.relative_to(REPO)}: SQL built with an f-string at lines {lines}; put it in sql/*.sql"


def test_the_api_exports_exactly_the_commands():
    """api.__all__ is the commands: each is a CLI command of the same name (dashes for
    underscores), and every command is in it but sql (``connect(...).sql``) and serve, which is
    mocapdb.server.serve (the server sits above the API)."""
    import mocapdb.api as api
    import mocapdb.server as server
    from mocapdb.cli import main

    commands = {c.replace("-", "_") for c in main.commands} - {"sql", "serve"}
    assert set(api.__all__) == commands | {"connect"}
    assert all(callable(getattr(api, name)) for name in api.__all__)
    assert "serve" in main.commands and "serve" in server.__all__ and not hasattr(api, "serve")


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(REPO)))
def test_modules_stay_small(path):
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= 850, f"{path.relative_to(REPO)} has {n} lines; split it by what it holds"


def test_every_package_is_installed():
    """pyproject.toml lists the packages pip installs (extension/ and sql/ are mapped into
    mocapdb); a sub-package missing there imports in the checkout but not once installed."""
    import tomllib

    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"])
    found = set()
    for init in [*(REPO / "mocapdb").rglob("__init__.py"), *(REPO / "extension").rglob("__init__.py"),
                 *(REPO / "sql").rglob("__init__.py")]:
        parts = list(init.parent.relative_to(REPO).parts)
        if parts[0] != "mocapdb":
            parts = ["mocapdb", *parts]
        found.add(".".join(parts))
    assert found - listed == set(), f"packages missing from pyproject.toml: {sorted(found - listed)}"


def test_the_tests_run_against_the_installed_package():
    """CI installs the package (pip install .) and must test that, not the checkout
    (the README's test command runs ``python -P -m pytest``: no checkout on sys.path)."""
    import importlib.metadata
    import json
    from pathlib import Path

    import mocapdb

    dist = importlib.metadata.distribution("mocapdb")
    direct = dist.read_text("direct_url.json")
    # pip records an editable install in direct_url.json, or (older pips) only by
    # its __editable__ finder files
    editable = bool(direct and json.loads(direct).get("dir_info", {}).get("editable")) or any(
        "__editable__" in str(f) for f in dist.files or ())
    here = Path(mocapdb.__file__).resolve()
    if not editable:
        assert not here.is_relative_to(REPO / "mocapdb"), \
            f"the tests import {here}, the checkout, instead of the installed package; run python -P -m pytest"


def test_import_mocapdb_is_light():
    """``import mocapdb`` loads only the package (its public names load on first use, PEP 562), and
    reading a file loads the readers and features, not the database, SQL functions or learning
    (issue 34 item 1: aim ≤ 40 modules). Counted in a fresh interpreter."""
    import subprocess
    import sys

    code = ("import sys; before = set(sys.modules); {stmt}; "
            "print(len([m for m in sys.modules if m not in before and m.startswith('mocapdb')]), "
            "sorted(m.split('.')[1] for m in sys.modules if m.startswith('mocapdb.') and m.count('.') == 1))")

    def loaded(stmt):
        out = subprocess.run([sys.executable, "-P", "-c", code.format(stmt=stmt)], capture_output=True, text=True,
                             check=True).stdout.split(" ", 1)
        return int(out[0]), out[1]

    n, packages = loaded("import mocapdb")
    assert n <= 40, packages
    n, packages = loaded("from mocapdb import read_motion, ParseError")
    assert n <= 40 and "api" not in packages and "learning" not in packages and "storage" not in packages, packages
    n, packages = loaded("import mocapdb; mocapdb.connect")  # the API loads on first use
    assert "api" in packages and "storage" in packages


@pytest.mark.parametrize("path", sorted((REPO / "mocapdb").rglob("*.py")), ids=lambda p: str(p.relative_to(REPO)))
def test_the_package_never_imports_the_lab(path):
    """lab/ (the development harness) is not installed: nothing under mocapdb/ may import it (issue 34 item 1)."""
    assert not re.search(r"^\s*(from lab[. ]|import lab\b)", path.read_text(encoding="utf-8"), flags=re.M), path
