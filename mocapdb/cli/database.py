"""Commands on the database and its recordings (:mod:`mocapdb.api.database`, :mod:`mocapdb.api.kernels`)
and ``sql``."""
from __future__ import annotations

from pathlib import Path

import click

import mocapdb.api as api
from mocapdb.errors import escape_control
from mocapdb.cli.options import (UNIT_NAMES, format_option, make_parent, model_option, reader_options,
                                 silent_option)
from mocapdb.cli.group import bar_progress, command, open_db, progress_bar
from mocapdb.cli.output import write_rows, echo_report


@command()
# not exists=True: a path may run through a zip archive (cmu.zip/subjects/02), which is no path on
# disk; a path that is nowhere is the API's one-line error
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option("--sample", is_flag=True,
              help="Also ingest the real recordings shipped with mocapdb (a CMU take, a BVH walk, an HDM05 C3D).")
@reader_options
@click.option("--replace", is_flag=True, help="Read files already stored (same bytes) again and replace their "
                                              "motions, e.g. with a corrected --joint-map (default: skip them).")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path), callback=make_parent,
              help="Also write every file's row of the ingest_log table (outcome, reason, the reader's notes, "
                   "motion_id) to this CSV file.")
@silent_option
@click.pass_context
def ingest(ctx, paths, sample, reader, replace, report, silent):
    """Read ASF/AMC, BVH, C3D and AMASS .npz files (or folders, recursively) into the database.

    Files may be .gz, .bz2 or .xz compressed, and folders may be .zip archives
    (read in place). A broken file changes nothing and the others still go in;
    files already stored (same bytes) are skipped (--replace reads them
    again). The terminal gets one line per failed file and a summary; every
    file's outcome, reason and the reader's notes (a joint placed without
    markers, lost tracking interpolated, frames cut) go to the table
    ingest_log, and with --report FILE to a CSV file too. Exit status 1 when
    any file failed, 0 otherwise.

    \b
    Example (the recordings shipped with mocapdb):
      mocapdb --db demo.duckdb ingest --sample
    """
    if not paths and not sample:
        raise click.UsageError("give files or folders to ingest, or --sample")
    con = open_db(ctx, create=True)
    with progress_bar(None, "ingest", silent) as bar:
        result = api.ingest(con, paths, sample=sample, replace=replace, progress=bar_progress(bar), report=report,
                            **reader)
    echo_report(ctx, result, log_csv=report)


@command()
@click.argument("parts", nargs=-1)
def warmup(parts):
    """Compile the numba kernels now (pip install . has done it already; parts: ingest, search, segments)."""

    click.echo(f"compiled in {api.warmup(parts=parts or None):.1f} s")


@command("extension-path")
def extension_path():
    """Print the absolute path of the native DuckDB extension (LOAD it in any DuckDB client:
    duckdb -unsigned FILE -c "LOAD 'PATH'; ..."; docs/EXTENSION.md)."""

    click.echo(str(api.extension_path()))


@command()
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
def joint_map_template(path):
    """Print a ready-to-edit TOML joint map for a BVH file (for ingest --joint-map).

    Every canonical joint the automatic mapping places is filled in; the
    others are left for you, with the file's own joints listed.
    """

    click.echo(api.joint_map_template(path), nl=False)


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

    report = api.delete(open_db(ctx), motions, all_named=all_named)
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
    try:
        if sql_file is not None:
            query = sql_file.read()
        elif query == "-":
            with click.open_file("-", encoding="utf-8") as stdin:
                query = stdin.read()
    except UnicodeDecodeError as exc:   # a binary file given as the query
        where = getattr(sql_file, "name", "stdin")
        raise click.UsageError(f"{where} is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset "
                               f"{exc.start}): the query must be SQL text") from None
    con = open_db(ctx, read_only=read_only)
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


@command("create-index")
@click.pass_context
def create_index(ctx):
    """(Re)build the keyframe index (schema mocap_index) from the features.

    A new database has the index; ingest and delete keep it up to date while it exists.
    """

    click.echo(f"keyframe index built: {api.create_index(open_db(ctx))} postings")


@command("drop-index")
@click.pass_context
def drop_index(ctx):
    """Remove the keyframe index (annotation then needs --no-keyframes)."""

    api.drop_index(open_db(ctx))
    click.echo("keyframe index dropped")


@command("export-features")
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path))
@click.option("--overwrite", is_flag=True, help="Write into a non-empty directory.")
@click.pass_context
def export_features(ctx, directory, overwrite):
    """Write motions and features to Parquet, partitioned by motion (DIR/features/motion_id=N/)."""

    click.echo(f"{api.export_features(open_db(ctx), directory, overwrite=overwrite)} motion(s) exported to {directory}")


@command("export-joints")
@click.argument("motions", nargs=-1)
@click.option("--all", "all", is_flag=True, help="Every motion (that --where and --label keep).")
@click.option("--where", metavar="SQL", help="Motions a SQL condition over the motions table holds for, e.g. "
                                             "\"format = 'bvh' AND source_path LIKE '%/session1/%'\".")
@click.option("--label", help="Motions with a stored segment of this label (run annotate first; --model's).")
@model_option("Model whose stored segments --label reads (default: the shipped default model).")
@click.option("--format", "fmt", type=click.Choice(("npz", "csv", "bvh")), default="npz", show_default=True,
              help="npz: joints (frames × 24 × 3), fps, joint_names, source_unit; csv: a row per frame (frame, "
                   "time, <joint>_x/_y/_z); bvh: a skeleton of the canonical joints.")
@click.option("--out", required=True, type=click.Path(path_type=Path), callback=make_parent,
              help="The file for one motion (ending in .npz, .csv or .bvh), else a directory (created) of files "
                   "named by motion, with units.json.")
@click.option("--unit", type=click.Choice(UNIT_NAMES),
              help="The unit of BVH sources (default: decided from the legs' length and the bone names; cmu: "
                   "CMU's 1/0.45 inch).")
@click.option("--scale", type=float, help="Or: metres per unit of BVH sources.")
@silent_option
@click.pass_context
def export_joints(ctx, motions, all, where, label, model, fmt, out, unit, scale, silent):
    """Write the 24 canonical joints of motions (ids or names, --all, --where, --label) for other tools.

    Each motion's source file is read again as it was ingested: its joints
    at the recording's own rate, in metres, Y up, in JOINT_NAMES order. A
    BVH file declares no unit: it is the one giving the legs an adult's
    length (each line says which and why; --unit or --scale overrides). A
    motion that cannot be exported (its source moved) is named; the others
    are written, and the exit status is 1.

    \b
    Examples:
      mocapdb --db demo.duckdb export-joints 86_09 --format bvh --out 86_09.bvh
      mocapdb --db demo.duckdb export-joints --where "format = 'bvh'" --out joints/
      mocapdb --db demo.duckdb export-joints --label jump --format csv --out jumps/
    """
    if not motions and not (all or where is not None or label is not None):
        raise click.UsageError("give motion ids or names, --all, --where SQL or --label LABEL")
    if motions and all:
        raise click.UsageError("give motion ids or names, or --all, not both")
    con = open_db(ctx, read_only=True)
    with progress_bar(None, "export-joints", silent, unit="motion") as bar:
        report = api.export_joints(con, list(motions) or None, out, all=all, format=fmt, where=where, label=label,
                                   model=model, unit=unit, scale=scale, progress=bar_progress(bar))
    for mid, name, path, how in report.written:   # a name is data: never its control characters raw
        click.echo(escape_control(f"wrote {path} (motion {mid} {name}; source unit {how})"))
    for mid, name, reason in report.failed:
        click.echo(escape_control(f"failed  {reason}"), err=True)
    if report.failed:
        ctx.exit(1)


@command("import-features")
@click.argument("directory", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.pass_context
def import_features(ctx, directory):
    """Load motions and features exported by export-features or written by ray-annotate.

    Motions already present are kept. Every motion is checked to be exactly
    its frames 1 … n: an incomplete one is refused and named (exit 1), the
    others are imported; an unfinished archive is refused. Every motion's
    outcome goes to the table ingest_log, under its source file, and so do
    the files a ray-annotate run could not read (its errors dataset).
    """

    report = api.import_features(open_db(ctx, create=True), directory)
    for name, reason in report.repaired:
        click.echo(f"repaired {name}: {reason}", err=True)
    for name, reason in report.failed:
        click.echo(f"refused  {reason}", err=True)
    click.echo(report.summary())
    click.echo(f"every motion's outcome: ingest_log run {report.run_id}", err=True)
    if report.failed:
        ctx.exit(1)


@command("convert-labels")
@click.argument("path", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), callback=make_parent,
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

    con = open_db(ctx) if ctx.obj.get("db") is not None else None
    rows = api.convert_labels(con, path, out=out, document=document, document_column=document_column,
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

    moved, refused = api.relocate(open_db(ctx), old_prefix, new_prefix)
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

    db = Path(ctx.obj["db"]) if ctx.obj.get("db") else None
    new = db is not None and not db.exists()
    con = open_db(ctx, create=True)
    try:
        n = api.attach(con, directory)
    except Exception:
        if new:   # a refused archive leaves no empty database behind
            con.close()
            for f in (db, db.with_name(db.name + ".wal")):
                f.unlink(missing_ok=True)
        raise
    click.echo(f"{n} motion(s) of {directory} attached to {ctx.obj['db']}")
