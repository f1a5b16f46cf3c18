"""The ``mocapdb`` command line: one command per function of :mod:`mocapdb.api`, same names and options.

Every command opens the database, calls its API function and prints the
result; nothing is computed here. Every error is one line ``Error: …`` with
exit status 1 (sqlite-utils style); progress bars are drawn here and nowhere
else (on a terminal, unless ``--silent``).
"""
from __future__ import annotations

import csv
import functools
import io
import json
import os
import re
import sys
import time
from pathlib import Path

import click

from mocapdb.distributed import BATCH_FILES, BUCKET_MOTIONS
from mocapdb.errors import MocapdbError, clip_message, escape_control

# -- shared options ---------------------------------------------------------------

FORMATS = ("table", "csv", "json")


def model_option(help="Model name (default: the shipped default model)."):
    return click.option("--model", default="default", show_default=True, help=help)


tau_option = click.option("--tau", type=float,
                          help="Hit threshold τ for every class (default: each class's; paper 0.13).")
keyframes_option = click.option("--keyframes/--no-keyframes", default=None,
                                help="Keyframe preselection (default: on when the model has keyframe "
                                     "queries; --no-keyframes is the toolbox's reference mode).")
silent_option = click.option("--silent", is_flag=True, help="No progress bar.")
min_length_option = click.option("--min-length/--no-min-length", default=None,
                                 help="Drop segments shorter than their label's minimum (default: on; models "
                                      "without minimums, as the toolbox's, keep every segment).")
min_won_option = click.option("--min-won/--no-min-won", default=None,
                              help="Drop segments whose label is the best label on fewer than a third of its "
                                   "minimum length (default: on; no effect on models without minimums).")
margin_option = click.option("--margin", type=float,
                             help="Leave frames unlabelled where the best label wins by less than this "
                                  "(default: the model's margin, 0 for the shipped models = off, as the paper).")
format_option = click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
folder_option = click.option("--folder", type=click.Path(exists=True, file_okay=False, path_type=Path),
                             help="Clips in the HDM05 cut layout: one folder per class (files read directly).")
labels_option = click.option("--labels", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                             help="Label file document,label,start_frame,end_frame (native frames, 1-based) "
                                  "or ELAN .eaf file cutting clips out of ingested documents.")
truth_help = ("Ground truth: a CSV document,label,start_frame,end_frame[,fps] (native frames, 1-based, unless an fps "
              "column gives their rate; `annotate --format csv` output reads back as it is) or an ELAN .eaf file "
              "(each annotation's value is the label; the document is the linked media file's stem). Other "
              "formats: `mocapdb convert-labels`.")
map_option = click.option("--label-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                          help="CSV class,label renaming truth labels to model labels (e.g. walk -> move).")


def reader_options(fn):
    """``--asf``, ``--joint-map`` and ``--marker-map``: how files are read (ingest, ray-annotate)."""
    fn = click.option("--marker-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                      help="TOML/JSON file: canonical joint = the C3D markers whose mean it is.")(fn)
    fn = click.option("--joint-map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                      help="TOML/JSON file: canonical joint = the BVH joint (its origin), \"Joint/end\" (its End "
                           "Site) or a list of joints (their mean); overrides the automatic mapping of every "
                           "BVH file.")(fn)
    return click.option("--asf", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                        help="Skeleton for every AMC file (default: found by the dataset conventions: "
                             "same-stem .asf, the CMU subject's NN.asf, HDM05's HDM_<actor>.asf).")(fn)


_UDF_WRAPPER = re.compile(r"^Invalid Input Error: Python exception occurred while executing the UDF: "
                          r"(SchemaError|ParameterError|ParseError|MocapdbError): ")


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
            text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
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


def _open(ctx, *, read_only=False, create=False):
    """The --db database; a missing file is an error unless the command creates one (``create``)."""
    db = ctx.obj.get("db")
    if db is None:
        raise click.UsageError("this command needs a database: mocapdb --db FILE …")
    from mocapdb.api import connect

    con = connect(db, read_only=read_only, create=create)
    ctx.call_on_close(con.close)
    return con


def _progress(total, label, silent, unit="file"):
    """A progress bar on a terminal; nothing with --silent or when stderr is not a TTY."""
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit=unit, disable=silent or not sys.stderr.isatty(), file=sys.stderr,
                leave=False)


def _set_bar(bar):
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
    so this happens only where that cache is missing (an editable install,
    another numba version). A first command that does not annotate (``ingest``)
    then also starts the annotation kernels compiling on the other core, and a
    command that annotates waits for them rather than compiling them again,
    and says so.
    """
    import mocapdb.api as api

    start = time.monotonic()
    if api.kernels_cold():
        if command == "sql":  # a query need not compile anything; its output stays clean
            return
        click.echo("Compiling the numba kernels: this install has no compiled cache yet (first run only)…",
                   err=True)
        ctx.call_on_close(lambda: click.echo(
            f"First run: {time.monotonic() - start:.0f} s, most of it compiling; later runs skip that.", err=True))
        if command not in _ANNOTATING:
            api.start_background_compile()
    elif command in _ANNOTATING and api.background_compile_running():
        click.echo("Waiting for the numba kernels compiling in the background (first run only)…", err=True)
        api.wait_for_background_compile()
        click.echo(f"…compiled; waited {time.monotonic() - start:.0f} s.", err=True)


# -- the group --------------------------------------------------------------------

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
                                      "convert-labels", "relocate", "warmup"):
        _say_when_compiling(ctx, ctx.invoked_subcommand)


# -- output -----------------------------------------------------------------------

def write_rows(rows, columns, fmt, out=None):
    """Print rows as an aligned table, CSV or JSON (to stdout or ``out``)."""
    stream = io.StringIO()
    if fmt == "csv":
        w = csv.writer(stream, lineterminator="\n")
        w.writerow(columns)
        w.writerows(rows)
    elif fmt == "json":
        json.dump([dict(zip(columns, r)) for r in rows], stream, indent=1, default=_json_default)
        stream.write("\n")
    else:
        cells = [[_cell(v) for v in r] for r in rows]
        widths = [max([len(str(c))] + [len(r[i]) for r in cells]) for i, c in enumerate(columns)]
        stream.write("  ".join(str(c).ljust(w) for c, w in zip(columns, widths)).rstrip() + "\n")
        stream.write("  ".join("-" * w for w in widths) + "\n")
        for r in cells:
            stream.write("  ".join(c.rjust(w) if _numeric(c) else c.ljust(w) for c, w in zip(r, widths)).rstrip()
                         + "\n")
    if out is None:
        click.echo(stream.getvalue(), nl=False)
    else:
        Path(out).write_text(stream.getvalue(), encoding="utf-8")


def _cell(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return "NULL" if v is None else str(v)


def _numeric(s):
    try:
        float(s)
    except ValueError:
        return False
    return "_" not in s  # float() accepts "86_09"


def _json_default(v):
    if hasattr(v, "isoformat"):
        return v.isoformat()
    if hasattr(v, "tolist"):
        return v.tolist()
    return str(v)


# -- commands ---------------------------------------------------------------------

@command()
# not exists=True: a path may run through a zip archive (cmu.zip/subjects/02), which is no path on
# disk; a path that is nowhere is the API's one-line error
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option("--sample", is_flag=True,
              help="Also ingest the real recordings shipped with mocapdb (a CMU take, a BVH walk, an HDM05 C3D).")
@reader_options
@click.option("--marker-rules", type=click.Choice(("toolbox", "anatomical")), default=None,
              help="C3D files of the HDM05/CMU marker set: the toolbox's formulas (default, the reference) or "
                   "anatomical joint centres (closer to the same take's AMC).")
@click.option("--replace", is_flag=True, help="Read files already stored (same bytes) again and replace their "
                                              "motions, e.g. with a corrected --joint-map (default: skip them).")
@silent_option
@click.pass_context
def ingest(ctx, paths, sample, asf, joint_map, marker_map, marker_rules, replace, silent):
    """Read ASF/AMC, BVH and C3D files (or folders, recursively) into the database.

    Files may be .gz, .bz2 or .xz compressed, and folders may be .zip archives
    (read in place). A broken file changes nothing and the others still go in;
    files already stored (same bytes) are skipped (--replace reads them
    again). Lines starting "note" say what a reader decided for a stored file
    (a joint placed without markers, lost tracking interpolated, frames cut).
    Exit status 1 when any file failed (each is listed with its reason), 0
    otherwise.

    \b
    Example (the recordings shipped with mocapdb):
      mocapdb --db demo.duckdb ingest --sample
    """
    from mocapdb.api import ingest as api_ingest
    from mocapdb.storage.ingest import motion_files

    if not paths and not sample:
        raise click.UsageError("give files or folders to ingest, or --sample")
    con = _open(ctx, create=True)
    with _progress(len(motion_files(paths)), "ingest", silent) as bar:
        report = api_ingest(con, paths, sample=sample, asf=asf, joint_map=joint_map, marker_map=marker_map,
                            marker_rules=marker_rules, replace=replace,
                            progress=lambda path, frames: bar.update(1))
    _echo_report(ctx, report)


def _echo_report(ctx, report, *, all_must_succeed=True):
    """The files a run did not store, a line each, what the readers noted about the stored ones,
    then its summary; exit 1 when any file failed (``all_must_succeed``), else when no file went in."""
    lines = [f"not a motion file {path}: {reason}" for path, reason in report.unsupported]
    lines += [f"unreadable {path}: {reason}" for path, reason in getattr(report, "unreadable", ())]
    lines += [f"skipped {path}: {reason}" for path, reason in report.skipped]
    lines += [f"repaired {path}: {reason}" for path, reason in getattr(report, "repaired", ())]
    lines += [f"failed  {reason}" if reason.startswith(path) else f"failed  {path}: {reason}"
              for path, reason in report.failed]
    lines += [f"replaced motion {old} by {path}" for path, old in getattr(report, "replaced", ())]
    lines += [f"note    {path}: {note}" for path, note in getattr(report, "notes", ())]
    for line in lines:
        # control characters of a file name or a binary file's bytes are never sent raw
        click.echo(escape_control(line), err=True)
    click.echo(f"{report.summary()} ({report.source_frames} source frames)")
    if report.failed and (all_must_succeed or not (report.ingested or report.skipped)):
        ctx.exit(1)


@command()
@click.argument("parts", nargs=-1)
def warmup(parts):
    """Compile the numba kernels now (pip install . has done it already; parts: ingest, search, segments)."""
    from mocapdb.api import warmup as api_warmup

    click.echo(f"compiled in {api_warmup(parts=parts or None):.1f} s")


@command()
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
def joint_map_template(path):
    """Print a ready-to-edit TOML joint map for a BVH file (for ingest --joint-map).

    Every canonical joint the automatic mapping places is filled in; the
    others are left for you, with the file's own joints listed.
    """
    from mocapdb.api import joint_map_template as api_template

    click.echo(api_template(path), nl=False)


@command()
@click.argument("motions", nargs=-1, required=True)
@click.option("--all-named", is_flag=True, help="A name that names several motions (an AMC and a C3D of one "
                                                "take) deletes all of them; without it, that is an error.")
@click.pass_context
def delete(ctx, motions, all_named):
    """Delete motions (ids or names) with their features, index postings and annotations.

    Says which motions it deleted. An id or name that is not there is
    reported and is no error (a delete run twice succeeds).
    """
    from mocapdb.api import delete as api_delete

    report = api_delete(_open(ctx), motions, all_named=all_named)
    for mid, name, fmt, path in report.deleted:
        click.echo(f"deleted motion {mid} {name} ({fmt}, {path})")
    for m in report.absent:
        click.echo(f"no motion {str(m)!r} (nothing to delete)", err=True)
    click.echo(f"{len(report.deleted)} motion(s) deleted")


@command(context_settings={"ignore_unknown_options": True})
@click.argument("query", required=False)
@click.option("--file", "sql_file", type=click.File("r", encoding="utf-8"),
              help="Read the query from a file ('-' for stdin), e.g. one of sql/queries/*.sql.")
@format_option
@click.option("--read-only", is_flag=True, help="Open the database read-only.")
@click.pass_context
def sql(ctx, query, sql_file, fmt, read_only):
    """Run SQL with the mocapdb functions registered and print each statement's result.

    The query is an argument (it may start with a -- comment), '-' for
    stdin, or --file FILE.

    \b
    Example:
      mocapdb --db a.duckdb sql "SELECT name, unnest(annotate(motion_id), recursive := true) FROM motions"
      mocapdb --db a.duckdb sql --file sql/queries/long_kicks.sql --format csv
      mocapdb --db a.duckdb sql - < query.sql
    """
    if (query is None) == (sql_file is None):
        raise click.UsageError("give a QUERY, '-' (stdin) or --file FILE (one of them)")
    if sql_file is not None:
        query = sql_file.read()
    elif query == "-":
        with click.open_file("-", encoding="utf-8") as stdin:
            query = stdin.read()
    con = _open(ctx, read_only=read_only)
    statements = con.extract_statements(query)
    if not statements:
        raise click.UsageError("the query holds no SQL statement")
    for k, st in enumerate(statements):
        cur = con.execute(st.query)
        columns = [d[0] for d in cur.description] if cur.description else []
        rows = cur.fetchall() if columns else []
        if k and fmt == "table":
            click.echo()
        if not columns:  # a statement without a result
            click.echo("ok")
        elif columns == ["Count"] and st.type.name != "SELECT" and fmt == "table":
            click.echo(f"ok, {rows[0][0]} row(s) changed" if rows else "ok")
        else:
            write_rows(rows, columns, fmt)


@command()
@click.option("--model", required=True, help="Name to store the model under.")
@folder_option
@labels_option
@click.option("--class-labels", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="CSV class,label mapping fine classes to coarse labels (default: the shipped "
                   "HDM05 mapping when it covers every class).")
@click.option("--delta", type=float, default=0.05, show_default=True, help="Quantization threshold δ.")
@click.option("--tau", type=float, default=0.13, show_default=True, help="Hit threshold τ.")
@click.option("--replace", is_flag=True, help="Overwrite a stored model of the same name.")
@click.option("--definitions", type=click.Path(exists=True, path_type=Path), multiple=True,
              help="Class definition file (TOML) or folder of them: hand-designed classes added to the "
                   "learned ones (repeatable; README \"Class definitions\").")
@silent_option
@click.pass_context
def train(ctx, model, folder, labels, class_labels, delta, tau, replace, definitions, silent):
    """Learn class motion templates from labelled clips and store them as a model.

    \b
    Example:
      mocapdb --db a.duckdb train --model hdm05 --folder ../shared/data/hdm05_cut
    """
    from mocapdb.api import train as api_train

    con = _open(ctx, create=True)
    with _progress(None, "train", silent, unit="step") as bar:
        m = api_train(con, model=model, folder=folder, labels=labels, class_labels=class_labels, delta=delta,
                      tau=tau, replace=replace, progress=_set_bar(bar), definitions=list(definitions) or None)
    for c in m.classes:
        click.echo(f"{c.name:32s} -> {c.label:12s} K={len(c.quantized):4d}  clips={getattr(c.template, 'n_clips', None)}")
    click.echo(f"model {model!r}: {len(m.classes)} classes, {len(m.labels)} labels")


@command("learn-keyframes")
@model_option("The stored model whose classes get queries.")
@folder_option
@labels_option
@click.option("--classes", help="Comma-separated classes to learn (default: all of the model's).")
@click.option("--runs", type=int, default=20, show_default=True, help="GA runs per class (paper: 100-500).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed: same seed, same queries.")
@click.option("--generations", type=int, default=100, show_default=True, help="Generations per run (paper: 100).")
@click.option("--jobs", type=int, help="Worker processes (default: all cores).")
@silent_option
@click.pass_context
def learn_keyframes(ctx, model, folder, labels, classes, runs, seed, generations, jobs, silent):
    """Learn one keyframe query per class with the genetic algorithm (paper Sect. 6).

    T+ = the class's clips, T- = the clips of every other class; the query with
    the consensus of the runs is stored in keyframe_queries with its fitness,
    precision and recall on the training clips.

    \b
    Example:
      mocapdb --db a.duckdb learn-keyframes --model hdm05 --folder ../shared/data/hdm05_cut --runs 20
    """
    from mocapdb.api import learn_keyframes as api_learn_keyframes

    con = _open(ctx, create=True)
    done_by_class = {}
    with _progress(None, "learn-keyframes", silent, unit="run") as bar:
        def progress(cls, done, total):
            done_by_class[cls] = done
            bar.set_description(cls[:28])
            bar.update(sum(done_by_class.values()) - bar.n)

        learned = api_learn_keyframes(con, model=model, folder=folder, labels=labels,
                                      classes=classes.split(",") if classes else None, runs=runs, seed=seed,
                                      jobs=jobs, generations=generations, progress=progress)
    rows = [(name, lq.query.n_keyframes, f"{lq.fitness:.3f}", f"{lq.precision:.3f}", f"{lq.recall:.3f}")
            for name, lq in learned.items()]
    write_rows(rows, ["class", "keyframes", "fitness", "precision", "recall"], "table")


@command("define-class")
@click.argument("definitions", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@model_option("The model the classes join (created if the database has none of that name).")
@click.option("--replace", is_flag=True, help="Redefine classes the model already has.")
@click.pass_context
def define_class(ctx, definitions, model, replace):
    """Add hand-designed classes from class definition files (TOML) to a model.

    Each class is phases of 0/1/* values of named features with durations,
    compiled to a quantized template and a keyframe query (README "Class
    definitions"; paper Sect. 8). A [[keyframes]] table gives a class the
    model already has (a learned one) a designed keyframe query.

    \b
    Example:
      mocapdb --db a.duckdb define-class my_classes.toml --model mine
    """
    from mocapdb.api import define_class as api_define_class

    m = api_define_class(_open(ctx, create=True), list(definitions), model=model, replace=replace)
    for c in m.classes:
        q = c.keyframe_query
        click.echo(f"{c.name:32s} -> {c.label:12s} K={len(c.quantized):4d}  keyframes={q.n_keyframes if q else 0}  "
                   f"tau={c.tau:g}")
    click.echo(f"model {model!r}: {len(m.classes)} classes, {len(m.labels)} labels")


@command()
@click.argument("motions", nargs=-1)
@model_option()
@tau_option
@keyframes_option
@min_length_option
@min_won_option
@margin_option
@click.option("--format", "fmt", type=click.Choice(FORMATS + ("parquet", "eaf")), default="table",
              show_default=True, help="table/csv/json print (or write --out); parquet writes the segments to "
                                      "--out; eaf writes ELAN files (one tier per label, the source file as "
                                      "linked media): --out FILE.eaf for one motion, else a directory.")
@click.option("--out", type=click.Path(path_type=Path), help="Write to a file (a directory for eaf of several "
                                                             "motions) instead of stdout.")
@click.option("--store/--no-store", default=True, show_default=True,
              help="Replace the stored annotations of these motions and this model (a database attached to an "
                   "archive has none of its own: --no-store).")
@silent_option
@click.pass_context
def annotate(ctx, motions, model, tau, keyframes, min_length, min_won, margin, fmt, out, store, silent):
    """Annotate motions (ids or names; default all) and store the segments in `annotations`.

    Frames are 30 Hz frames, 1-based inclusive; CSV (and JSON) columns
    document,label,start_frame,end_frame,fps,start_s,end_s,cost, where fps
    (30) is the rate of the frames: the file reads back as --truth or
    --labels onto exactly its frames. Seconds are rounded to 0.1 ms.

    \b
    Examples:
      mocapdb --db a.duckdb annotate --format csv --out segments.csv
      mocapdb --db a.duckdb annotate 86_09 --format eaf --out 86_09.eaf
      mocapdb --db a.duckdb annotate --format parquet --out segments.parquet
    """
    from mocapdb.api import annotate as api_annotate
    from mocapdb.storage.annotations import PartialAnnotationError

    export = fmt in ("parquet", "eaf")
    if export and out is None:
        raise click.UsageError(f"--format {fmt} writes files: give --out")
    failure = None
    with _progress(None, "annotate", silent, unit="motion") as bar:
        try:
            table = api_annotate(_open(ctx), motions or None, model=model, tau=tau, keyframes=keyframes, store=store,
                                 format=fmt if export else None, out=out if export else None,
                                 progress=_set_bar(bar), min_length=min_length, min_won=min_won, margin=margin)
        except PartialAnnotationError as exc:  # the others were annotated (and stored): show them
            table, failure = exc.table, exc
    if export:
        click.echo(f"{table.num_rows} segment(s) written to {out}")
    else:
        cols = ["document", "label", "start_frame", "end_frame", "start_s", "end_s", "cost"]
        rows = [(d, lab, s, e, round(a, 4), round(b, 4), round(c, 6))
                for d, lab, s, e, a, b, c in zip(*(table.column(c).to_pylist() for c in cols))]
        if fmt != "table":  # a file carries its frame grid (label files read it: the fps column)
            rates = [int(r) if r.is_integer() else r for r in (round(x, 6) for x in _frame_rates(table))]
            rows = [(*r[:4], f, *r[4:]) for r, f in zip(rows, rates)]
            cols = cols[:4] + ["fps"] + cols[4:]
        write_rows(rows, cols, fmt, out)
    if failure is not None:
        for _, _, reason in failure.failed:
            click.echo(f"failed  {reason}", err=True)
        raise click.ClickException(str(failure))


def _frame_rates(table):
    """The rate of each segment's frames (30 Hz feature frames): its frames over its seconds."""
    return [(e - s + 1) / (b - a) for s, e, a, b in zip(*(table.column(c).to_pylist() for c in
                                                       ("start_frame", "end_frame", "start_s", "end_s")))]


def _print_scores(rows):
    """rows: (setting, Scores) pairs → a table of the paper's six measures."""
    cols = ["", "P1", "R1", "F1", "P2", "R2", "F2", "frames M/A", "segments M/A"]
    out = [[str(name), *(f"{getattr(sc, k):.3f}" for k in ("p1", "r1", "f1", "p2", "r2", "f2")),
            f"{sc.truth_frames}/{sc.auto_frames}", f"{sc.truth_segments}/{sc.auto_segments}"]
           for name, sc in rows]
    write_rows(out, cols, "table")
    dropped = rows[0][1].dropped_truth if rows else {}
    if dropped:
        click.echo("truth labels outside the scored vocabulary (not scored): "
                   + ", ".join(f"{k} ({v})" for k, v in sorted(dropped.items())))


@command("evaluate")
@click.option("--truth", required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help=truth_help)
@click.option("--pred", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Score this annotation (as written by `annotate --format csv`, 30 Hz frames); "
                   "without it the truth's documents are annotated from the database.")
@map_option
@click.option("--vocabulary", help="Comma-separated labels to score (default: the model's labels; with "
                                   "--pred: every truth label).")
@model_option()
@tau_option
@keyframes_option
@min_length_option
@min_won_option
@margin_option
@click.option("--sweep-tau", help="START:STOP:STEP, e.g. 0.05:0.25:0.01 — P/R/F per τ (paper Fig. 8).")
@click.option("--by-label", is_flag=True, help="Also score every label on its own.")
@click.pass_context
def evaluate(ctx, truth, pred, label_map, vocabulary, model, tau, keyframes, min_length, min_won, margin,
             sweep_tau, by_label):
    """Frame-level P1/R1/F1 and segment-level P2/R2/F2 against ground truth (paper Eq. 5-8).

    All documents are concatenated, as in the paper; truth frames are
    converted to the 30 Hz feature grid.

    \b
    Examples:
      mocapdb evaluate --truth truth.csv --pred segments.csv
      mocapdb --db a.duckdb evaluate --truth truth.csv --label-map walk_is_move.csv --sweep-tau 0.05:0.25:0.01
    """
    from mocapdb.api import evaluate as api_evaluate

    con = None if pred is not None and ctx.obj.get("db") is None else _open(ctx)
    vocab = [v.strip() for v in vocabulary.split(",")] if vocabulary else None
    result = api_evaluate(con, truth, pred=pred, model=model, tau=tau, keyframes=keyframes, label_map=label_map,
                          vocabulary=vocab, sweep_tau=sweep_tau, by_label=by_label, min_length=min_length,
                          min_won=min_won, margin=margin)
    if not sweep_tau:
        _print_scores(list(result.items()) if by_label else [("all", result)])
    elif by_label:
        _print_scores([(f"tau={t:.3f} {lab}", sc) for t, per in result for lab, sc in per.items()])
    else:
        _print_scores([(f"tau={t:.3f}", sc) for t, sc in result])


@command()
@click.option("--figure", type=click.Choice(["ga", "delta", "template", "tau", "timeline", "annotation"]),
              required=True,
              help="ga: GA precision/recall/fitness over generations (paper Fig. 5); delta: a motion's distance "
                   "functions per class, white above tau (Fig. 3a); template: a class template, real and "
                   "quantized (Fig. 1c/d); tau: P/R/F over tau against --truth (Fig. 8); timeline: a motion's "
                   "labels over time, against --truth if given (Figs. 6/7; 'annotation' is its former name).")
@click.option("--out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Image file (format from the suffix: .png, .pdf, .svg).")
@model_option()
@click.option("--motion", help="Motion id or name (delta, timeline).")
@click.option("--class", "class_name", help="Class of the model (template).")
@click.option("--truth", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Ground truth for tau and timeline: " + truth_help)
@map_option
@tau_option
@keyframes_option
@click.option("--sweep-tau", help="START:STOP:STEP of the tau figure (default 0.05:0.25:0.01).")
@click.pass_context
def report(ctx, figure, out, model, motion, class_name, truth, label_map, tau, keyframes, sweep_tau):
    """Draw a figure of the paper from the database (needs the 'plot' extra: pip install 'mocapdb[plot]').

    \b
    Examples:
      mocapdb --db a.duckdb report --figure ga --out fig5.png
      mocapdb --db a.duckdb report --figure delta --motion 86_09 --out fig3.png
      mocapdb --db a.duckdb report --figure template --class squat1Reps --out fig1.png
      mocapdb --db a.duckdb report --figure tau --truth truth.csv --label-map walk_is_move.csv --out fig8.png
      mocapdb --db a.duckdb report --figure timeline --motion 86_09 --truth truth.eaf --out fig7.png
    """
    from mocapdb.api import report as api_report

    api_report(_open(ctx), figure, out, model=model, motion=motion, keyframes=keyframes, tau=tau, truth=truth,
               label_map=label_map, class_name=class_name, sweep_tau=sweep_tau)
    click.echo(f"written {out}")


@command()
@click.argument("motion", required=False)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), help="The HTML page of MOTION.")
@click.option("--all", "all", type=click.Path(file_okay=False, path_type=Path),
              help="Instead: write one page per motion and index.html into this directory.")
@model_option()
@tau_option
@keyframes_option
@click.option("--truth", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Ground truth for the truth lane: " + truth_help)
@map_option
@silent_option
@click.pass_context
def view(ctx, motion, out, all, model, tau, keyframes, truth, label_map, silent):
    """Write a self-contained HTML page: the skeleton animated above its labels over time.

    The page works offline (no libraries, no network): drag to orbit, wheel to
    zoom, play/pause, scrubber and speed; the annotation, the ground truth and
    the distance functions (paper Fig. 3) as lanes; click a segment to jump there.

    \b
    Examples:
      mocapdb --db a.duckdb view 86_09 --out 86_09.html
      mocapdb --db a.duckdb view --all pages/ --truth truth.csv
    """
    from mocapdb.api import view as api_view

    with _progress(None, "view", silent, unit="page") as bar:
        written = api_view(_open(ctx), motion, out=out, all=all, model=model, tau=tau, keyframes=keyframes,
                           truth=truth, label_map=label_map, progress=_set_bar(bar))
    click.echo(f"written {written[0]}" + (f" and {len(written) - 1} page(s)" if all is not None else ""))


def _stretch(text):
    """``MOTION`` or ``MOTION:A-B`` (30 Hz frames, 1-based inclusive) of --example."""
    m = re.fullmatch(r"(.+?)(?::(\d+)-(\d+))?", text.strip())
    name, a, b = m.group(1), m.group(2), m.group(3)
    return name if a is None else (name, int(a), int(b))


@command()
@click.argument("motion")
@click.option("--start-frame", type=int, help="First frame of the query stretch (30 Hz, 1-based, as annotate prints).")
@click.option("--end-frame", type=int, help="Last frame of the query stretch (inclusive).")
@click.option("--start", type=float, help="Or: start of the stretch in seconds.")
@click.option("--end", type=float, help="Or: end of the stretch in seconds.")
@click.option("--example", "examples", multiple=True, metavar="MOTION[:A-B]",
              help="A further example stretch (frames A-B, 1-based inclusive; whole motion without them); "
                   "repeatable: a template is learned from all the stretches (\"more like these\").")
@click.option("--limit", type=int, default=10, show_default=True, help="Number of results.")
@click.option("--features", default="all", show_default=True,
              help="all, upper (arms, features 1-14), lower (legs, 15-26) or comma-separated feature names.")
@click.option("--tau", type=float, help="Hit threshold on the weighted cost (default: 3/4 of the query's chance "
                                        "level).")
@click.option("--keyframes/--no-keyframes", default=None,
              help="Preselect with keyframes taken from the query: --keyframes always, --no-keyframes never "
                   "(default: as far as the archive's size needs to keep a query's work bounded).")
@click.option("--format", "fmt", type=click.Choice(FORMATS + ("html",)), default="table", show_default=True,
              help="table/csv/json print (or write --out); html writes --out DIR/index.html listing the results, "
                   "linked to a viewer page per motion at each hit.")
@click.option("--out", type=click.Path(path_type=Path), help="Write to a file (a directory for html).")
@model_option("Model whose annotation the html pages show.")
@silent_option
@click.pass_context
def similar(ctx, motion, start_frame, end_frame, start, end, examples, limit, features, tau, keyframes, fmt, out,
            model, silent):
    """Find the stretches of the archive most like a stretch of MOTION (query by example).

    MOTION is a motion id or name; without a range the whole motion is the
    query. Results are ranked by cost, never overlap each other or the query,
    and come from any motion (the query's own included). Columns
    document,motion_id,start_frame,end_frame,start_s,end_s,cost (30 Hz frames,
    1-based inclusive).

    \b
    Examples:
      mocapdb --db a.duckdb similar HDM_bd_kickLFront1Reps_001_120 --limit 5
      mocapdb --db a.duckdb similar 86_09 --start 12.5 --end 15 --features lower
      mocapdb --db a.duckdb similar 86_09 --start-frame 380 --end-frame 450 --format html --out hits/
      mocapdb --db a.duckdb similar kick1 --example kick2 --example 86_09:100-160
    """
    from mocapdb.api import similar as api_similar

    if fmt == "html" and out is None:
        raise click.UsageError("--format html writes pages: give --out DIR")
    html_out = fmt == "html"
    with _progress(None, "similar", silent, unit="page") as bar:
        table = api_similar(_open(ctx), motion, start, end, start_frame=start_frame, end_frame=end_frame,
                            examples=[_stretch(e) for e in examples] or None, limit=limit, features=features,
                            tau=tau, keyframes=keyframes, format="html" if html_out else None,
                            out=out if html_out else None, model=model, progress=_set_bar(bar))
    if html_out:
        click.echo(f"{table.num_rows} result(s) written to {Path(out) / 'index.html'}")
        return
    cols = list(table.column_names)
    write_rows(list(zip(*(table.column(c).to_pylist() for c in cols))), cols, fmt, out)


@command("create-index")
@click.pass_context
def create_index(ctx):
    """(Re)build the keyframe index (schema mocap_index) from the features.

    A new database has the index; ingest and delete keep it up to date while it exists.
    """
    from mocapdb.api import create_index as api_create_index

    click.echo(f"keyframe index built: {api_create_index(_open(ctx))} postings")


@command("drop-index")
@click.pass_context
def drop_index(ctx):
    """Remove the keyframe index (annotation then needs --no-keyframes)."""
    from mocapdb.api import drop_index as api_drop_index

    api_drop_index(_open(ctx))
    click.echo("keyframe index dropped")


@command("export-features")
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path))
@click.option("--overwrite", is_flag=True, help="Write into a non-empty directory.")
@click.pass_context
def export_features(ctx, directory, overwrite):
    """Write motions and features to Parquet, partitioned by motion (DIR/features/motion_id=N/)."""
    from mocapdb.api import export_features as api_export_features

    click.echo(f"{api_export_features(_open(ctx), directory, overwrite=overwrite)} motion(s) exported to {directory}")


@command("import-features")
@click.argument("directory", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.pass_context
def import_features(ctx, directory):
    """Load motions and features exported by export-features or written by ray-annotate.

    Motions already present are kept. Every motion is checked to be exactly
    its frames 1 … n: an incomplete one is refused and named (exit 1), the
    others are imported; an unfinished archive is refused.
    """
    from mocapdb.api import import_features as api_import_features

    report = api_import_features(_open(ctx, create=True), directory)
    for name, reason in report.repaired:
        click.echo(f"repaired {name}: {reason}", err=True)
    for name, reason in report.failed:
        click.echo(f"refused  {reason}", err=True)
    click.echo(report.summary())
    if report.failed:
        ctx.exit(1)



@command("convert-labels")
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="The label CSV to write (default: print it).")
@click.option("--document", help="Per-frame labels: the document (default: the file's stem); a segment table: "
                                 "keep only its rows.")
@click.option("--document-column", default="document", show_default=True, help="Segment table: the document column.")
@click.option("--label-column", default="label", show_default=True, help="Segment table: the label column.")
@click.option("--start-column", default="start_frame", show_default=True, help="Segment table: the first frame.")
@click.option("--end-column", default="end_frame", show_default=True, help="Segment table: the last frame.")
@click.option("--names", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Per-frame labels: file of '<id> <name>' lines naming the label ids.")
@click.option("--frames-per-label", type=click.IntRange(min=1),
              help="Per-frame labels: frames each id covers (mocap6: 12). This or --names reads per-frame labels.")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True),
              help="The rate of the file's frames, when not the recording's own (written as the fps column).")
@click.pass_context
def convert_labels(ctx, path, out, document, document_column, label_column, start_column, end_column, names,
                   frames_per_label, fps):
    """Convert another project's label file into a label CSV (for --truth and --labels).

    A segment table with other column names, or per-frame label ids (one per
    frame or per block of frames) with a file naming them. With --db, per-frame
    labels of an ingested document end at its last frame.

    \b
    Examples:
      mocapdb convert-labels ../shared/data/labels/cmu86_segmentation/cmu86_09_segments.csv \\
          --document-column trial --out 86_09_truth.csv
      mocapdb --db a.duckdb convert-labels ../shared/data/labels/cmu_mocap6/13_29.txt --frames-per-label 12 \\
          --names ../shared/data/labels/cmu_mocap6/action_names.txt --out 13_29_truth.csv
    """
    from mocapdb.api import convert_labels as api_convert_labels

    con = _open(ctx) if ctx.obj.get("db") is not None else None
    rows = api_convert_labels(con, path, out=out, document=document, document_column=document_column,
                              label_column=label_column, start_column=start_column, end_column=end_column,
                              names=names, frames_per_label=frames_per_label, fps=fps)
    if out is None:
        cols = ["document", "label", "start_frame", "end_frame"] + (["fps"] if fps is not None else [])
        write_rows([(r["document"], r["label"], int(r["start"]), int(r["end"]), *([f"{fps:g}"] if fps else []))
                    for r in rows], cols, "csv")
    else:
        click.echo(f"{len(rows)} segment(s) of {len(set(rows['document']))} document(s) written to {out}")


@command()
@click.argument("old_prefix")
@click.argument("new_prefix")
@click.pass_context
def relocate(ctx, old_prefix, new_prefix):
    """Repoint the stored source files after moving them: OLD_PREFIX/… becomes NEW_PREFIX/….

    Only motions whose file (and ASF) is at the new place with the bytes that
    were ingested are repointed; the others are listed. `view` and the figures
    re-read the sources.

    \b
    Example:
      mocapdb --db a.duckdb relocate /old/disk/mocap /new/disk/mocap
    """
    from mocapdb.api import relocate as api_relocate

    moved, refused = api_relocate(_open(ctx), old_prefix, new_prefix)
    for mid, path, why in refused:
        click.echo(f"not moved: motion {mid}: {why}", err=True)
    click.echo(f"{len(moved)} motion(s) repointed" + (f", {len(refused)} not" if refused else ""))
    if refused:
        ctx.exit(1)


@command("attach")
@click.argument("directory", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.pass_context
def attach(ctx, directory):
    """Query a ray-annotate archive in place: --db becomes views over its Parquet.

    motions, features, annotations and the keyframe index of the new database
    are views of the archive (nothing is copied); the SQL functions and the
    reading commands work on them.

    \b
    Example:
      mocapdb ray-annotate '../shared/data/hdm05_cut/**/*.amc' --out archive
      mocapdb --db archive_views.duckdb attach archive
      mocapdb --db archive_views.duckdb sql "SELECT count(*) FROM keyframe_search('kickLFront1Reps')"
    """
    from mocapdb.api import attach as api_attach

    n = api_attach(_open(ctx, create=True), directory)
    click.echo(f"{n} motion(s) of {directory} attached to {ctx.obj['db']}")


@command("ray-annotate")
@click.argument("sources", nargs=-1, required=True)
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Archive folder for the Parquet datasets (on storage every node sees).")
@click.option("--address", help="Ray cluster address (e.g. auto, ray://head:10001); default: a local Ray.")
@model_option("Model name: a shipped model, or one stored in the --db database.")
@tau_option
@keyframes_option
@reader_options
@click.option("--num-cpus", type=int, help="CPUs of the local Ray (default: all cores).")
@click.option("--batch-files", type=int, default=BATCH_FILES, show_default=True,
              help="Files per batch: the unit of work, of retry and of the Parquet parts.")
@click.option("--bucket-motions", type=int, default=BUCKET_MOTIONS, show_default=True,
              help="Motions per motion_bucket partition of features, postings and annotations.")
@click.option("--overwrite", is_flag=True, help="Replace an archive already in --out.")
@click.pass_context
def ray_annotate(ctx, sources, out, address, model, tau, keyframes, asf, joint_map, marker_map, num_cpus,
                 batch_files, bucket_motions, overwrite):
    """Ingest and annotate files, folders or glob patterns on a Ray cluster; write Parquet.

    Needs the ray extra (pip install 'mocapdb[ray]'). Writes the datasets
    motions, features, postings, annotations (the columns of the database
    tables) and errors (file, reason) under --out; `import-features` loads
    them into a database and DuckDB reads them in place.

    \b
    Example:
      mocapdb ray-annotate '../shared/data/hdm05_cut/**/*.amc' --out archive
      mocapdb --db archive.duckdb import-features archive
    """
    from mocapdb.api import ray_annotate as api_ray_annotate

    report = api_ray_annotate(sources, out, address=address, model=model, tau=tau, keyframes=keyframes,
                              database=ctx.obj.get("db"), asf=asf, joint_map=joint_map, marker_map=marker_map,
                              num_cpus=num_cpus, batch_files=batch_files, bucket_motions=bucket_motions,
                              overwrite=overwrite)
    # the failed files are data of the archive (its errors dataset): the run failed only if nothing went in
    _echo_report(ctx, report, all_must_succeed=False)


if __name__ == "__main__":  # pragma: no cover
    main()
