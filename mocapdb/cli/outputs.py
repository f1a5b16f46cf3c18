"""Commands that draw, show and search (:mod:`mocapdb.api.outputs`), and ``serve`` (:func:`mocapdb.server.serve`)."""
from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

import click

import mocapdb.api as api
import mocapdb.server as server
from mocapdb.cli.options import (FORMATS, keyframes_option, make_parent, map_option, model_option, silent_option,
                                 tau_option, truth_help)
from mocapdb.cli.group import command, open_db, progress_bar, bar_progress
from mocapdb.cli.output import duration, write_rows


@command()
@click.option("--figure", type=click.Choice(["ga", "delta", "template", "tau", "timeline", "annotation"]),
              required=True,
              help="ga: GA precision/recall/fitness over generations (paper Fig. 5); delta: a motion's distance "
                   "functions per class, white above tau (Fig. 3a); template: a class template, real and "
                   "quantized (Fig. 1c/d); tau: P/R/F over tau against --truth (Fig. 8); timeline: a motion's "
                   "labels over time, against --truth if given (Figs. 6/7; 'annotation' is its former name).")
@click.option("--out", required=True, type=click.Path(dir_okay=False, path_type=Path), callback=make_parent,
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

    api.report(open_db(ctx), figure, out, model=model, motion=motion, keyframes=keyframes, tau=tau, truth=truth,
               label_map=label_map, class_name=class_name, sweep_tau=sweep_tau)
    click.echo(f"written {out}")


@command()
@click.argument("motion", required=False)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), callback=make_parent,
              help="The HTML page of MOTION (default: <motion name>.html here).")
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

    with progress_bar(None, "view", silent, unit="page") as bar:
        written = api.view(open_db(ctx), motion, out=out, all=all, model=model, tau=tau, keyframes=keyframes,
                           truth=truth, label_map=label_map, progress=bar_progress(bar))
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
@click.option("--out", type=click.Path(path_type=Path), callback=make_parent,
              help="Write to a file (a directory for html).")
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

    if fmt == "html" and out is None:
        raise click.UsageError("--format html writes pages: give --out DIR")
    html_out = fmt == "html"
    with progress_bar(None, "similar", silent, unit="page") as bar:
        table = api.similar(open_db(ctx), motion, start, end, start_frame=start_frame, end_frame=end_frame,
                            examples=[_stretch(e) for e in examples] or None, limit=limit, features=features,
                            tau=tau, keyframes=keyframes, format="html" if html_out else None,
                            out=out if html_out else None, model=model, progress=bar_progress(bar))
    if html_out:
        click.echo(f"{table.num_rows} result(s) written to {Path(out) / 'index.html'}")
        return
    cols = list(table.column_names)
    write_rows(list(zip(*(table.column(c).to_pylist() for c in cols))), cols, fmt, out)


#: the tables of ``stats``, in printing order
STATS_TABLES = ("formats", "labels", "refused")


@command()
@model_option("Model whose stored annotations give the hours per label.")
@click.option("--table", type=click.Choice(STATS_TABLES),
              help="Print this table only (csv prints one table: give it). Default: all of them.")
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
@click.pass_context
def stats(ctx, model, table, fmt):
    """What the archive holds: hours and motions per source format and rate, annotated hours per label
    (the stored annotations of --model), and the files its ingests refused.

    Refused files (failed, or not a motion file, at their latest ingest) come
    from the database's ingest log; a database without one says nothing
    about them.

    \b
    Examples:
      mocapdb --db a.duckdb stats
      mocapdb --db a.duckdb stats --table labels --format csv
    """

    if fmt == "csv" and table is None:
        raise click.UsageError("--format csv prints one table: give --table formats, labels or refused")
    s = api.stats(open_db(ctx, read_only=True), model=model)
    tables = s.tables()
    if table is not None and table not in tables:
        raise click.UsageError(f"this database keeps no ingest log, so it has no {table} table")
    chosen = [table] if table else list(tables)
    if fmt == "json":
        import json

        out = {name: tables[name].to_pylist() for name in chosen}
        if table is None:
            out = {"model": model, "motions": s.motions, "hours": s.hours, **out}
        click.echo(json.dumps(out, indent=1, default=str))
        return
    titles = {"formats": "hours and motions per source format and rate",
              "labels": f"annotated hours per label (model {model})",
              "refused": "files refused at their latest ingest"}
    if table is None:
        click.echo(f"{s.motions} motion(s), {duration(s.hours * 3600)} in all ({s.hours:.4g} hours)")
    # within the terminal (a line as wide as it wraps on some); piped into a file or grep, whole
    columns = os.environ.get("COLUMNS", "")
    width = (int(columns) if columns.isdigit() else shutil.get_terminal_size().columns if sys.stdout.isatty()
             else None)
    width = None if width is None else width - 1
    for name in chosen:
        t = tables[name]
        if table is None:
            click.echo(f"\n{titles[name]}:")
            if t.num_rows == 0:
                click.echo("  none" if name != "labels" else
                           f"  none stored (mocapdb annotate stores them; models with annotations: "
                           f"{', '.join(s.annotated_models) or 'none'})")
                continue
        cols = list(t.column_names)
        rows = list(zip(*(t.column(c).to_pylist() for c in cols)))
        if fmt == "table" and "hours" in cols:   # for a reader, as the summary page writes it; csv/json keep hours
            k = cols.index("hours")
            rows = [(*r[:k], duration(r[k] * 3600), *r[k + 1:]) for r in rows]
            cols = [*cols[:k], "duration", *cols[k + 1:]]
        write_rows(rows, cols, fmt, width=width if fmt == "table" else None)


@command()
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on (the default answers this machine only; 0.0.0.0 opens it to the network).")
@click.option("--port", type=int, default=8765, show_default=True, help="Port (0: any free port).")
@model_option("Model whose stored annotations the pages show.")
@click.option("--timeout", type=float, default=server.REQUEST_TIMEOUT, show_default=True,
              help="Seconds a request may take before its work is stopped.")
@click.pass_context
def serve(ctx, host, port, model, timeout):
    """Browse the archive in a web browser (needs the 'serve' extra: pip install 'mocapdb[serve]').

    The archive page lists every motion with its format, rate, duration,
    stored labels and a strip of its label timeline, filtered by label,
    format, name and duration, sorted and paged; /stats sums up the archive;
    a motion's page is its viewer page with "find similar" on a stretch
    selected on the timeline, and every segment of a label across the
    archive. JSON under /api/. The database is only read, a request at a
    time: ingest and annotate can run beside the server (pages say "busy"
    while they write). Ctrl-C stops it.

    \b
    Example:
      mocapdb --db a.duckdb serve            # then open http://127.0.0.1:8765/
    """

    db = ctx.obj.get("db")
    if db is None:
        raise click.UsageError("this command needs a database: mocapdb --db FILE …")
    # the server is a face on the API as this command line is, so the CLI starts it itself (nothing in
    # mocapdb.api imports the server)
    server.serve(db, host=host, port=port, model=model, timeout=timeout,
                 ready=lambda url: click.echo(f"Serving {db} at {url} (read only; Ctrl-C stops)"))
