"""The repository explains itself: every document the code or the docs cite is in it (STYLE.md §17).

* A citation ``NAME.md §N`` (with further ``, §M``, ``/§M`` or ranges
  ``§N–§M``, ``§N-M`` after it) of one of the project's documents in code,
  SQL, benchmarks, tests, the README or the docs resolves to ``docs/NAME.md``
  and to a heading of section N there (``## §N Title``).
* Every ``*.md`` file that code or docs name exists in the repository
  (relative to the repository root, ``docs/``, the citing file's folder, or
  by its unique file name); the shared data set's own notes
  (``../shared/…``) are the data's, not documents of the project.
* ``docs/`` does not point into the product specs outside the repository.

Runs in a bare clone: it reads only the repository.
"""
import os
import re
from pathlib import Path

import pytest

from conftest import REPO

DOCS = REPO / "docs"
#: the project's specification documents, each cited as ``NAME.md §N``
DOC_NAMES = ("FEATURES", "TEMPLATES", "KEYFRAMES", "READERS", "CLASSES", "DESIGN", "STYLE")
#: where citations are checked: code, SQL, benchmarks, tests, CI, docs, and files at the root
SCANNED_DIRS = ("mocapdb", "extension", "sql", "benchmarks", "tests", "docs", ".ci")
SCANNED_FILES = ("README.md", "pyproject.toml")
#: text files among them (".ci/run" has no suffix); data such as .parquet and .png are skipped
TEXT_SUFFIXES = {"", ".py", ".md", ".sql", ".toml", ".js", ".html", ".css", ".csv", ".test", ".txt", ".json",
                 ".cfg", ".ini", ".yml", ".yaml", ".sh"}
#: this module holds broken citations on purpose (the checker's own tests)
SELF = Path(__file__).resolve()

_SECTION = r"\d+(?:\.\d+)*[a-z]?"
_CITATION = re.compile(r"(?<![\w/.-])(?:docs/)?(" + "|".join(DOC_NAMES) + r")\.md\b")
_FIRST = re.compile(r"[ \t]*§(" + _SECTION + ")")
_NEXT = re.compile(r"[ \t]*[,/][ \t]*§(" + _SECTION + ")")
_RANGE = re.compile(r"[ \t]*[–-][ \t]*§?(" + _SECTION + r")(?![\w.])")
_HEADING = re.compile(r"^(#{1,6})[ \t]+§(" + _SECTION + r")(?=[ \t]|$)", re.M)
_ANY_HEADING = re.compile(r"^(#{2,6})[ \t]+(.*)$", re.M)
#: a path-like mention of a Markdown file (not part of a URL or of a longer path)
_MD = re.compile(r"(?<![\w/.:-])((?:\.\.?/)*[\w.-]+(?:/[\w.-]+)*\.md)\b")


# --------------------------------------------------------------------------
# the checker


def _split(section):
    """``"2.4.4"`` → ``(("2", "4"), 4)``: the prefix and the last number, or None with a letter."""
    parts = section.split(".")
    if not parts[-1].isdigit():
        return None
    return tuple(parts[:-1]), int(parts[-1])


def _expand(first, last):
    """Sections of a range ``first``–``last`` (``§3–§6``, ``§2-5``, ``§2.4.4–§2.4.5``).

    A bare end (``5`` in ``§2.4-5``) keeps the first's prefix. Ranges whose ends
    differ in their prefix or carry a letter give just the two ends.
    """
    a = _split(first)
    if a is None:
        return [first, last]
    if "." not in last and a[0]:
        last = ".".join(a[0] + (last,))
    b = _split(last)
    if b is None or b[0] != a[0] or b[1] < a[1]:
        return [first, last]
    return [".".join(a[0] + (str(k),)) for k in range(a[1], b[1] + 1)]


def citations(text):
    """Every ``(document, section or None, line)`` a text cites, ranges expanded.

    ``None`` stands for a citation of a whole document (``READERS.md`` alone).
    """
    out = []
    for m in _CITATION.finditer(text):
        name, pos = m.group(1), m.end()
        line = text.count("\n", 0, m.start()) + 1
        first = _FIRST.match(text, pos)
        if first is None:
            out.append((name, None, line))
            continue
        sections = [first.group(1)]
        pos = first.end()
        while True:
            more = _NEXT.match(text, pos)
            if more:
                sections.append(more.group(1))
                pos = more.end()
                continue
            span = _RANGE.match(text, pos)
            if span:
                sections[-1:] = _expand(sections[-1], span.group(1))
                pos = span.end()
                continue
            break
        out.extend((name, s, line) for s in sections)
    return out


def headings(text):
    """The section numbers of a document's headings (``## §2.2 Title`` → ``"2.2"``)."""
    return [m.group(2) for m in _HEADING.finditer(text)]


def broken_citations(text, sections_of):
    """Citations of ``text`` that do not resolve: ``(document, section, line)``.

    ``sections_of`` maps a document name to its section numbers (None: the
    document does not exist).
    """
    bad = []
    for name, section, line in citations(text):
        have = sections_of.get(name)
        if have is None or (section is not None and section not in have):
            bad.append((name, section, line))
    return bad


def _shared_note(name):
    """A mention of the shared data set's own notes (``../shared/…``, ``data/…README.md``,
    ``oracle/…README.md``): the data's documentation, outside the repository by design."""
    return name.startswith("../shared/") or (name.split("/")[0] in ("data", "oracle")
                                             and name.endswith("/README.md"))


def md_mentions(text):
    """Every ``(*.md path, line)`` a text names."""
    return [(m.group(1), text.count("\n", 0, m.start()) + 1) for m in _MD.finditer(text)]


def missing_documents(text, source, repo_md):
    """``*.md`` files ``text`` (of the file ``source``) names that the repository lacks.

    ``repo_md``: the repository's Markdown files, as paths relative to its root.
    """
    missing = []
    for name, line in md_mentions(text):
        if _shared_note(name):
            continue
        places = [(base / name).resolve() for base in (REPO, DOCS, source.parent)]
        if any(p.is_relative_to(REPO) and p.relative_to(REPO) in repo_md for p in places):
            continue
        if "/" not in name and sum(p.name == name for p in repo_md) == 1:
            continue  # a bare file name: the repository's one file of that name
        missing.append((name, line))
    return missing


# --------------------------------------------------------------------------
# the repository


def _skipped_dir(name):
    """Folders that are not the project's: virtual environments, caches, builds, VCS."""
    return ((name.startswith(".") and name != ".ci") or name in ("__pycache__", "build", "dist", "node_modules")
            or name.endswith(".egg-info"))


def _walk(root):
    """Files under ``root``, sorted, without descending into skipped folders."""
    for here, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not _skipped_dir(d))
        for f in sorted(files):
            yield Path(here) / f


def scanned_texts():
    """``(path, text)`` of every text file whose citations must resolve (this module excluded)."""
    paths = [REPO / f for f in SCANNED_FILES if (REPO / f).is_file()]
    for d in SCANNED_DIRS:
        paths += [p for p in _walk(REPO / d) if p.suffix in TEXT_SUFFIXES and p.resolve() != SELF]
    for path in paths:
        try:
            yield path, path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue  # not text after all


def repo_markdown():
    """The repository's Markdown files, relative to its root."""
    return {p.relative_to(REPO) for p in _walk(REPO) if p.suffix == ".md"}


def doc_sections():
    return {name: set(headings((DOCS / f"{name}.md").read_text(encoding="utf-8")))
            for name in DOC_NAMES if (DOCS / f"{name}.md").is_file()}


# --------------------------------------------------------------------------
# the checker on small strings: it must catch what it is for


def test_citations_are_parsed_with_every_section_and_range():
    text = ("see FEATURES.md §1, §2.2, §9; toolbox readAMC.m\n"
            "FEATURES.md §2.4.8/§6 and TEMPLATES.md §3–§5 (KEYFRAMES.md §2-4, §8.1).\n"
            "FEATURES.md §2.4.4–§2.4.5, READERS.md) FEATURES.md §2.3b; DESIGN.md §6: a\n")
    got = [(n, s) for n, s, _ in citations(text)]
    assert got == [("FEATURES", "1"), ("FEATURES", "2.2"), ("FEATURES", "9"),
                   ("FEATURES", "2.4.8"), ("FEATURES", "6"),
                   ("TEMPLATES", "3"), ("TEMPLATES", "4"), ("TEMPLATES", "5"),
                   ("KEYFRAMES", "2"), ("KEYFRAMES", "3"), ("KEYFRAMES", "4"), ("KEYFRAMES", "8.1"),
                   ("FEATURES", "2.4.4"), ("FEATURES", "2.4.5"), ("READERS", None),
                   ("FEATURES", "2.3b"), ("DESIGN", "6")]
    # a section number ends at its last digit: "§2.2." at the end of a sentence is §2.2
    assert [s for _, s, _ in citations("FEATURES.md §2.2.")] == ["2.2"]
    # a word after a section is not part of the citation
    assert [s for _, s, _ in citations("FEATURES.md §6, lower body")] == ["6"]


def test_a_broken_citation_is_caught():
    sections = {"FEATURES": {"1", "2", "2.2", "2.3b"}, "KEYFRAMES": {"1", "2", "3", "5"}}
    assert broken_citations("FEATURES.md §2.2 and §2.3b", sections) == []
    assert broken_citations("x\nFEATURES.md §2.2, §99", sections) == [("FEATURES", "99", 2)]
    assert broken_citations("FEATURES.md §2.3", sections) == [("FEATURES", "2.3", 1)]
    # a range needs every section in it
    assert broken_citations("KEYFRAMES.md §2-5", sections) == [("KEYFRAMES", "4", 1)]
    # a document that is not there at all
    assert broken_citations("DESIGN.md §1", sections) == [("DESIGN", "1", 1)]
    assert broken_citations("STYLE.md", sections) == [("STYLE", None, 1)]


def test_headings_carry_their_numbers():
    text = "# Title\n\n## §1 One\n### §1.2 Sub\n#### §2.4.4 Deep\n### §2.3b BVH\nnot ## §9 a heading\n"
    assert headings(text) == ["1", "1.2", "2.4.4", "2.3b"]


def test_a_missing_document_is_caught():
    repo_md = {Path("README.md"), Path("docs/ARCHITECTURE.md"), Path("benchmarks/RESULTS.md")}
    source = REPO / "mocapdb" / "x.py"
    text = ("see docs/ARCHITECTURE.md, RESULTS.md and README.md; "
            "https://example.org/spec/NOTES.md is a URL\n"
            "the data's notes ../shared/data/README.md and data/README.md\n"
            "but NOTES.md and ../shared/spec/FEATURES.md? and specs/FEATURES.md\n")
    missing = [name for name, _ in missing_documents(text, source, repo_md)]
    assert missing == ["NOTES.md", "specs/FEATURES.md"]
    # the shared folder holds data, not the project's documents
    assert _shared_note("../shared/spec/FEATURES.md")
    assert not _shared_note("spec/FEATURES.md")


# --------------------------------------------------------------------------
# the repository


def test_every_document_is_in_docs_with_numbered_sections():
    """docs/NAME.md exists for every cited name; every heading below the title
    carries its number, at the depth the number says (## §2, ### §2.2, #### §2.4.4)."""
    missing = [name for name in DOC_NAMES if not (DOCS / f"{name}.md").is_file()]
    assert not missing, f"docs/ lacks {', '.join(n + '.md' for n in missing)}"
    problems = []
    for name in DOC_NAMES:
        text = (DOCS / f"{name}.md").read_text(encoding="utf-8")
        numbers = headings(text)
        dup = sorted({n for n in numbers if numbers.count(n) > 1})
        if dup:
            problems.append(f"docs/{name}.md: sections {dup} appear twice")
        if not numbers:
            problems.append(f"docs/{name}.md: no numbered section")
        for m in _ANY_HEADING.finditer(text):
            level, title = len(m.group(1)), m.group(2)
            num = re.match(r"§(" + _SECTION + r")\s", title + " ")
            if num is None:
                problems.append(f"docs/{name}.md: heading {title!r} has no § number")
            elif level != 2 + num.group(1).count("."):
                problems.append(f"docs/{name}.md: heading §{num.group(1)} at level {level}")
    assert not problems, "\n".join(problems)


def test_every_citation_resolves_to_a_section():
    sections = doc_sections()
    bad = []
    for path, text in scanned_texts():
        for name, section, line in broken_citations(text, sections):
            what = f"{name}.md" + (f" §{section}" if section else "")
            bad.append(f"{path.relative_to(REPO)}:{line}: {what} has no "
                       + ("such section" if name in sections else "document in docs/"))
    assert not bad, f"{len(bad)} citations do not resolve:\n" + "\n".join(bad)


def test_no_document_outside_the_repository_is_named():
    repo_md = repo_markdown()
    bad = []
    for path, text in scanned_texts():
        for name, line in missing_documents(text, path, repo_md):
            bad.append(f"{path.relative_to(REPO)}:{line}: names {name}, which the repository does not have")
    assert not bad, "\n".join(bad)


def test_docs_do_not_point_into_the_product_specs():
    bad = []
    for path in [REPO / "README.md", *sorted(DOCS.glob("*.md"))]:
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"shared/spec\b|\.\./spec/", line):
                bad.append(f"{path.relative_to(REPO)}:{k}: {line.strip()}")
    assert not bad, "docs point outside the repository:\n" + "\n".join(bad)


@pytest.mark.parametrize("name", DOC_NAMES)
def test_each_document_cites_the_paper(name):
    """The specification is the paper's, in the project's words: each document names
    the paper's sections it implements (STYLE.md and DESIGN.md describe the house)."""
    text = (DOCS / f"{name}.md").read_text(encoding="utf-8")
    if name in ("STYLE",):
        return
    assert re.search(r"\bSect\. \d", text), f"docs/{name}.md cites no section of the paper"


def test_the_cli_reference_is_what_the_commands_say():
    """docs/CLI.md is generated from --help (mocapdb.cli.reference): a changed option changes it."""
    from mocapdb.cli.reference import cli_reference

    current = (DOCS / "CLI.md").read_text(encoding="utf-8")
    assert current == cli_reference(), "docs/CLI.md is stale: python -m mocapdb.cli.reference > docs/CLI.md"


def test_the_readme_is_a_front_door():
    """The README stays short: what it is, the two commands, a taste of SQL, a picture, links (issue 34)."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    assert max(len(line) for line in readme.splitlines() if not line.startswith("python3 -m venv")) <= 400
    for doc in ("USER_GUIDE", "CLI", "READING_FILES", "MODEL", "CLUSTER"):
        assert f"(docs/{doc}.md)" in readme, doc
