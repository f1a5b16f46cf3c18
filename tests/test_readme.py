"""Every example of README.md and docs/*.md runs as printed: their ```bash commands and ```sql blocks.

The ``mocapdb`` commands of the ```bash blocks run in reading order (README, then the guides:
conftest.USER_DOCS) (a command
chained with ``&&`` after installing is run on its own; installing and the
test run itself are not), from a folder beside which ``../shared`` is the
shared data, as from the repository root. Each ```sql block is then pasted
whole into ``mocapdb sql`` (a query that starts with a ``--`` comment
included), as an argument and on stdin, against the database the commands
made.
"""
import re
import shlex
import subprocess
import sys

import pytest
from click.testing import CliRunner

from mocapdb.cli import main

from conftest import SHARED, run, user_docs_text

pytestmark = [pytest.mark.shared, pytest.mark.slow]

README = user_docs_text()


def blocks(language):
    """The text of every fenced block of a language, in reading order."""
    return [m.group(1) for m in re.finditer(rf"^```{language}\n(.*?)^```", README, flags=re.S | re.M)]


def commands():
    """The mocapdb commands of the bash blocks, in order, each split into its arguments."""
    out = []
    for block in blocks("bash"):
        command = ""
        for line in block.replace("\\\n", " ").splitlines():
            command = f"{command}\n{line}" if command else line
            try:
                shlex.split(command, comments=True)
            except ValueError:  # a quoted argument (a query) goes on over the next lines, as in a shell
                continue
            for part in command.split("&&"):
                words = shlex.split(part.strip(), comments=True)
                if words and words[0] == "mocapdb":
                    out.append(words[1:])
            command = ""
        assert not command, f"unclosed quote in the README's bash block: {command!r}"
    return out


def test_the_readme_has_the_examples_this_test_runs():
    assert len(blocks("sql")) >= 2 and any(q.lstrip().startswith("--") for q in blocks("sql"))
    names = [next(w for w in c if not w.startswith("-") and not w.endswith(".duckdb")) for c in commands()]
    assert {"ingest", "annotate", "convert-labels", "ray-annotate", "import-features"} <= set(names)


def _serve_once(args, cwd):
    """``mocapdb … serve`` as printed (on a free port): it listens, and its pages and API answer."""
    import urllib.request

    proc = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", *args, "--port", "0"], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert "Serving" in line, f"mocapdb {shlex.join(args)}: {line}{proc.stderr.read()[-2000:]}"
        url = line.split(" at ", 1)[1].split()[0]
        for path in ("", "stats", "api/motions", "api/stats", "motion/1"):
            with urllib.request.urlopen(url + path, timeout=120) as r:
                assert r.status == 200, path
    finally:
        proc.terminate()
        proc.wait(30)
        proc.stdout.close()
        proc.stderr.close()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """Where the README's commands ran: a folder with ../shared beside it."""
    root = tmp_path_factory.mktemp("readme")
    (root / "shared").symlink_to(SHARED, target_is_directory=True)
    work = root / "repo"
    work.mkdir()
    for args in commands():
        if "--address" in args:  # for a cluster of the reader's own (test_ray runs one, with token auth)
            continue
        if "serve" in args:  # serves until stopped: started, its pages asked for, stopped
            _serve_once(args, work)
            continue
        r = subprocess.run([sys.executable, "-P", "-m", "mocapdb.cli", *args], cwd=work, capture_output=True,
                           text=True, timeout=900)
        failed = re.search(r"(\d+) failed", r.stdout)
        # ingest and ray-annotate exit 1 when a file failed (the README says which do, and why)
        ok = r.returncode == 0 or (r.returncode == 1 and failed and int(failed.group(1)) > 0
                                   and "Error:" not in r.stderr)
        assert ok, f"mocapdb {shlex.join(args)} → exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
    return work


@pytest.mark.parametrize("k", range(len(blocks("sql"))))
def test_every_sql_example_runs_as_printed(workdir, k):
    query = blocks("sql")[k]
    db = workdir / next(c[c.index("--db") + 1] for c in commands() if "--db" in c)  # the README's first database
    r = run(db, "sql", query)
    statements = [s for s in re.split(r";\s*(?:\n|$)", query) if re.sub(r"--[^\n]*", "", s).strip()]
    assert len(re.findall(r"^-{3,}", r.output, flags=re.M)) == len(statements), r.output  # a table each
    # pasted on stdin the same
    assert CliRunner().invoke(main, ["--db", str(db), "sql", "-"], input=query).output == r.output
