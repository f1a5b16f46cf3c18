"""A small sqllogictest runner: every tests/sql/*.test file on a fresh database file.

The format follows DuckDB's own test files (test/sql/**/*.test):

``statement ok`` / ``statement error`` + SQL
    The statement must run / must fail; after ``statement error`` an optional
    ``----`` line is followed by a text the error message must contain.
``query <types> [rowsort]`` + SQL + ``----`` + expected rows
    One row per line, values separated by tabs (or runs of 2+ spaces), NULL
    as ``NULL``, doubles compared to 1e-6; ``rowsort`` sorts both sides.
``ingest <path>`` (mocapdb)
    ``mocapdb.ingest`` of files or folders under ../shared/data, or of the recordings
    shipped with mocapdb (``sample/<file>``: a file that ingests only those runs in a
    bare clone too; the others are marked ``shared``).
``reopen [read_only]`` (mocapdb)
    Close the connection and open the same file again through ``mocapdb.connect``.

Records are separated by blank lines; ``#`` starts a comment line.
"""
import re
from pathlib import Path

import pytest

import mocapdb

from conftest import DATA, SAMPLE, SAMPLE_86_09

TESTS = sorted((Path(__file__).parent / "sql").glob("*.test"))


def source(arg):
    """The file or folder an ``ingest`` argument names: ``sample/…`` is shipped with mocapdb."""
    return SAMPLE / arg.removeprefix("sample/") if arg.startswith("sample/") else DATA / arg


def records(path):
    """(line number, header words, body lines) of every record of a .test file."""
    out, cur = [], None
    for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if cur is None:
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            cur = (no, line.split(), [])
            continue
        if not line.strip():
            out.append(cur)
            cur = None
        else:
            cur[2].append(line)
    if cur is not None:
        out.append(cur)
    return out


def split_result(body):
    if "----" in body:
        k = body.index("----")
        return "\n".join(body[:k]), body[k + 1:]
    return "\n".join(body), None


def cell(v):
    if v is None:
        return "NULL"
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def same_value(got, want):
    if got == want:
        return True
    try:
        return abs(float(got) - float(want)) <= 1e-6 * max(1.0, abs(float(want)))
    except ValueError:
        return False


class Runner:
    def __init__(self, path, db):
        self.path, self.db = path, db
        self.con = mocapdb.connect(db)

    def where(self, no):
        return f"{self.path.name}:{no}"

    def run(self):
        try:
            for no, head, body in records(self.path):
                getattr(self, "do_" + head[0])(no, head[1:], body)
        finally:
            self.con.close()

    def do_ingest(self, no, args, body):
        report = mocapdb.ingest(self.con, [source(a) for a in args])
        assert not report.failed, f"{self.where(no)}: ingest failed: {report.failed}"

    def do_reopen(self, no, args, body):
        self.con.close()
        self.con = mocapdb.connect(self.db, read_only="read_only" in args)

    def do_statement(self, no, args, body):
        sql, expected = split_result(body)
        if args[0] == "ok":
            try:
                self.con.execute(sql)
            except Exception as exc:
                pytest.fail(f"{self.where(no)}: statement failed: {exc}")
            return
        assert args[0] == "error", f"{self.where(no)}: statement ok|error, got {args}"
        with pytest.raises(Exception) as info:
            self.con.execute(sql).fetchall()
        if expected:
            message = "\n".join(expected)
            assert message in str(info.value), f"{self.where(no)}: error {str(info.value)!r} lacks {message!r}"

    def do_query(self, no, args, body):
        sql, expected = split_result(body)
        assert expected is not None, f"{self.where(no)}: a query needs ---- and its result"
        rows = [[cell(v) for v in r] for r in self.con.execute(sql).fetchall()]
        want = [re.split(r"\t| {2,}", line.strip()) for line in expected]
        if "rowsort" in args[1:]:
            rows, want = sorted(rows), sorted(want)
        ncol = len(args[0])
        assert all(len(r) == ncol for r in rows), f"{self.where(no)}: expected {ncol} columns"
        assert len(rows) == len(want), f"{self.where(no)}: {len(rows)} rows, expected {len(want)}:\n{rows}"
        for k, (g, w) in enumerate(zip(rows, want)):
            assert len(g) == len(w) and all(same_value(a, b) for a, b in zip(g, w)), \
                f"{self.where(no)}: row {k + 1} is {g}, expected {w}"


def test_the_sql_test_files_exist():
    assert len(TESTS) >= 4


def _needs_shared(path):
    return any(not a.startswith("sample/") for _, head, _ in records(path) if head[0] == "ingest" for a in head[1:])


@pytest.mark.slow
@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem, marks=[pytest.mark.shared] if _needs_shared(p) else [])
                                  for p in TESTS])
def test_sql_file(path, tmp_path):
    Runner(path, tmp_path / "test.duckdb").run()


def test_every_readme_sql_example_runs_on_a_fresh_database(tmp_path, open_db):
    """Each ```sql block of the README and docs, statement by statement, on a new database with one motion."""
    from conftest import user_docs_text

    readme = user_docs_text()
    blocks = re.findall(r"```sql\n(.*?)```", readme, flags=re.S)
    statements = [s.strip() for b in blocks for s in re.sub(r"(?m)^--.*$", "", b).split(";") if s.strip()]
    assert len(statements) >= 3
    con = open_db(tmp_path / "fresh.duckdb")
    mocapdb.ingest(con, [SAMPLE_86_09])
    for sql in statements:
        con.execute(sql).fetchall()
