"""The ``mocapdb`` group: the --db option, one-line errors, opening the database, progress bars
and the first run's compile messages."""
from __future__ import annotations

import functools
import os
import re
import sys
import time
from pathlib import Path

import click

import mocapdb.api as api
from mocapdb.errors import MocapdbError, clip_message, os_error_text


#: DuckDB's wrapping of an error raised inside a SQL function: a Python UDF's library error, or the
#: native extension's message (its functions' errors are Invalid Input Errors)
_UDF_WRAPPER = re.compile(r"^Invalid Input Error: (Python exception occurred while executing the UDF: "
                          r"(SchemaError|ParameterError|ParseError|MocapdbError): )?")


def _errors_as_one_line(fn):
    """Every error becomes ``Error: <first line>`` with exit 1; anything that is not a
    library, database or file error is reported as internal, with its type
    (``MOCAPDB_DEBUG=1`` re-raises it with the traceback)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        import duckdb

        try:
            return fn(*args, **kwargs)
        except (click.ClickException, click.exceptions.Exit, click.Abort):
            raise
        except Exception as exc:
            if os.environ.get("MOCAPDB_DEBUG"):
                raise
            # a file error says the path and the reason, never Python's "[Errno 2] …"
            raw = os_error_text(exc) if isinstance(exc, OSError) else str(exc).strip()
            text = raw.splitlines()[0] if raw else ""
            # a library error raised inside a SQL function reaches us wrapped by DuckDB
            text = clip_message(_UDF_WRAPPER.sub("", text))  # a megabyte name is not echoed whole
            if not isinstance(exc, (MocapdbError, duckdb.Error, ImportError, OSError)):
                text = f"internal error ({type(exc).__name__}: {text}); MOCAPDB_DEBUG=1 shows the traceback"
            raise click.ClickException(text or type(exc).__name__) from exc
    return wrapper


def command(name=None, **kwargs):
    """``@main.command`` with one-line errors."""
    def deco(fn):
        return main.command(name, **kwargs)(_errors_as_one_line(fn))
    return deco


def open_db(ctx, *, read_only=False, create=False):
    """The --db database; a missing file is an error unless the command creates one (``create``)."""
    db = ctx.obj.get("db")
    if db is None:
        raise click.UsageError("this command needs a database: mocapdb --db FILE …")

    con = api.connect(db, read_only=read_only, create=create)
    ctx.call_on_close(con.close)
    return con


def progress_bar(total, label, silent, unit="file"):
    """A progress bar on a terminal; nothing with --silent or when stderr is not a TTY."""
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit=unit, disable=silent or not sys.stderr.isatty(), file=sys.stderr,
                leave=False)


def bar_progress(bar):
    """A ``progress(n_done, n_total, ...)`` callback of the API that moves ``bar``."""
    def progress(done, total, *_):
        bar.total, bar.n = total, done
        bar.refresh()
    return progress


#: commands that annotate: they use the kernels the background warm-up compiles
_ANNOTATING = {"annotate", "evaluate", "sql", "view", "report", "learn-keyframes", "train", "similar"}


def _say_when_compiling(ctx, command):
    """Say when kernels compile, and at the end how long that run took (a cold numba cache only).

    ``pip install .`` compiles the kernels at build time (:mod:`mocapdb.warmup`),
    so this happens only where that cache is missing or stale (an editable
    install, another numba version, numba before 0.68 with a wheel's cache:
    :func:`mocapdb.api.kernels.kernels_cold`). A first command that does not annotate (``ingest``)
    then also starts the annotation kernels compiling on the other core, and a
    command that annotates waits for them rather than compiling them again,
    and says so.
    """

    start = time.monotonic()
    if api.kernels_cold():
        # on stderr, for every command that compiles (a query too: stdout stays the query's)
        click.echo("Compiling the numba kernels: this install has no usable compiled cache (a first run, or "
                   "another numba)…", err=True)
        ctx.call_on_close(lambda: click.echo(
            f"First run: {time.monotonic() - start:.0f} s, most of it compiling; later runs skip that.", err=True))
        if command not in _ANNOTATING:
            api.start_background_compile()
    elif command in _ANNOTATING and api.background_compile_running():
        click.echo("Waiting for the numba kernels compiling in the background (first run only)…", err=True)
        api.wait_for_background_compile()
        click.echo(f"…compiled; waited {time.monotonic() - start:.0f} s.", err=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--db", type=click.Path(dir_okay=False, path_type=Path), envvar="MOCAPDB_DB",
              help="DuckDB database file. ingest, import-features, train, define-class and learn-keyframes "
                   "create it if missing; the other commands refuse a missing file. Env: MOCAPDB_DB.")
@click.version_option(package_name="mocapdb")
@click.pass_context
def main(ctx, db):
    """mocapdb: annotate and retrieve motion capture data with SQL.

    \b
    Example:
      mocapdb --db archive.duckdb ingest --sample
      mocapdb --db archive.duckdb annotate
      mocapdb --db archive.duckdb sql "SELECT name, n_frames FROM motions"
    """
    ctx.ensure_object(dict)
    ctx.obj["db"] = db
    if ctx.invoked_subcommand not in (None, "attach", "delete", "drop-index", "export-features", "joint-map-template",
                                      "convert-labels", "relocate", "warmup", "stats"):
        _say_when_compiling(ctx, ctx.invoked_subcommand)
