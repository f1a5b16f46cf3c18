"""``mocapdb motions``: the archive page of ``mocapdb serve`` on the command line (:mod:`mocapdb.api.browsing`)."""
from __future__ import annotations

import json

import click

import mocapdb.api as api
from mocapdb.cli.group import command, open_db
from mocapdb.cli.options import format_option, model_option
from mocapdb.cli.output import write_rows


@command()
@click.option("--label", help="Motions with a stored segment of this label (of --model).")
@click.option("--source-format", help="Motions of this source format (amc, bvh, c3d, npz, …).")
@click.option("--q", help="Motions whose name or source path contains this, ignoring case (a folder, a session).")
@click.option("--min-s", type=float, help="Motions lasting at least this many seconds.")
@click.option("--max-s", type=float, help="Motions lasting at most this many seconds.")
@click.option("--sort", type=click.Choice(api.SORTS), default="id", show_default=True,
              help="Order: a column, '-' first for descending (id: ingest order).")
@click.option("--limit", type=click.IntRange(1, api.MAX_LIMIT), default=50, show_default=True, help="Rows to print.")
@click.option("--offset", type=click.IntRange(0, None), default=0, show_default=True, help="Rows skipped first.")
@model_option("Model whose stored annotations give the labels.")
@format_option
@click.pass_context
def motions(ctx, label, source_format, q, min_s, max_s, sort, limit, offset, model, fmt):
    """List the archive's motions with their folder and stored labels, filtered and sorted, a page at a
    time: what the archive page of `mocapdb serve` shows (/api/motions takes the same filters:
    label, source_format, q, min_s, max_s, sort, limit, offset; its JSON is --format json).

    \b
    Examples:
      mocapdb --db a.duckdb motions --label kick --sort -seconds
      mocapdb --db a.duckdb motions --q session3/ --format csv
    """

    page = api.motions(open_db(ctx, read_only=True), label=label, source_format=source_format, q=q, min_s=min_s,
                       max_s=max_s, sort=sort, limit=limit, offset=offset, model=model)
    if fmt == "json":
        click.echo(json.dumps({"model": model, "total": page.total, "limit": limit, "offset": offset,
                               "rows": page.rows}, indent=1, default=str))
        return
    cols = list(api.MOTION_COLUMNS)
    rows = [[" ".join(r[c]) if c == "labels" else r[c] for c in cols] for r in page.rows]
    write_rows(rows, cols, fmt)
    if fmt == "table":
        more = f"; --offset {offset + len(rows)} for more" if offset + len(rows) < page.total else ""
        click.echo(f"{len(rows)} of {page.total} motion(s){more}", err=True)
