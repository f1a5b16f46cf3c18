"""Commands that annotate and score (:mod:`mocapdb.api.annotating`)."""
from __future__ import annotations

from pathlib import Path

import click

import mocapdb.api as api
from mocapdb.errors import PartialAnnotationError
from mocapdb.cli.options import (FORMATS, annotation_options, keyframes_option, make_parent, map_option, model_option,
                                 reader_options, silent_option, tau_option, truth_help)
from mocapdb.cli.group import command, open_db, progress_bar, bar_progress
from mocapdb.cli.output import write_rows, echo_report, print_scores, frame_rates


@command()
@click.argument("motions", nargs=-1)
@annotation_options
@click.option("--format", "fmt", type=click.Choice(FORMATS + ("parquet", "eaf")), default="table",
              show_default=True, help="table/csv/json print (or write --out); parquet writes the segments to "
                                      "--out; eaf writes ELAN files (one tier per label, the source file as "
                                      "linked media): --out FILE.eaf for one motion, else a directory.")
@click.option("--out", type=click.Path(path_type=Path), callback=make_parent,
              help="Write to a file (a directory for eaf of several motions) instead of stdout; its folder is "
                   "made.")
@click.option("--video", is_flag=True, help="With --format eaf: also write each motion's stick figure as an MP4 "
                                            "beside its .eaf and link it, so ELAN plays it with the tiers "
                                            "(needs ffmpeg).")
@click.option("--store/--no-store", default=True, show_default=True,
              help="Replace the stored annotations of these motions and this model (a database attached to an "
                   "archive has none of its own: --no-store).")
@silent_option
@click.pass_context
def annotate(ctx, motions, model, tau, keyframes, min_length, min_won, margin, fmt, out, video, store, silent):
    """Annotate motions (ids or names; default all) and store the segments in `annotations`.

    Frames are 30 Hz frames, 1-based inclusive; CSV (and JSON) columns
    document,label,start_frame,end_frame,fps,start_s,end_s,cost,confidence,
    where fps (30) is the rate of the frames: the file reads back as --truth
    or --labels onto exactly its frames. Seconds are rounded to 0.1 ms;
    confidence (0-1) is, under the default model, the share of segments of
    that length and match quality found right on recordings of labs the
    model never saw (docs/MODEL.md); under a model without calibration, how
    far the best match lies below τ (1 − cost/τ). Filter on it to keep the
    surest segments.

    \b
    Examples:
      mocapdb --db a.duckdb annotate --format csv --out segments.csv
      mocapdb --db a.duckdb annotate 86_09 --format eaf --out 86_09.eaf
      mocapdb --db a.duckdb annotate --format eaf --video --out elan/
      mocapdb --db a.duckdb annotate --format parquet --out segments.parquet
    """

    export = fmt in ("parquet", "eaf")
    if export and out is None:
        raise click.UsageError(f"--format {fmt} writes files: give --out")
    if video and fmt != "eaf":
        raise click.UsageError("--video goes with --format eaf")
    failure = None
    with progress_bar(None, "annotate", silent, unit="motion") as bar:
        try:
            table = api.annotate(open_db(ctx), motions or None, model=model, tau=tau, keyframes=keyframes, store=store,
                                 format=fmt if export else None, out=out if export else None,
                                 progress=bar_progress(bar), min_length=min_length, min_won=min_won, margin=margin,
                                 video=video)
        except PartialAnnotationError as exc:  # the others were annotated (and stored): show them
            table, failure = exc.table, exc
    if export:
        click.echo(f"{table.num_rows} segment(s) written to {out}")
    else:
        cols = ["document", "label", "start_frame", "end_frame", "start_s", "end_s", "cost", "confidence"]
        rows = [(d, lab, s, e, round(a, 4), round(b, 4), round(c, 6), round(q, 3))
                for d, lab, s, e, a, b, c, q in zip(*(table.column(c).to_pylist() for c in cols))]
        if fmt != "table":  # a file carries its frame grid (label files read it: the fps column)
            rates = [int(r) if r.is_integer() else r for r in (round(x, 6) for x in frame_rates(table))]
            rows = [(*r[:4], f, *r[4:]) for r, f in zip(rows, rates)]
            cols = cols[:4] + ["fps"] + cols[4:]
        write_rows(rows, cols, fmt, out)
        if out is not None:   # as the file formats say it
            click.echo(f"{len(rows)} segment(s) written to {out}")
    if failure is not None:
        for _, _, reason in failure.failed:
            click.echo(f"failed  {reason}", err=True)
        raise click.ClickException(str(failure))


@command("evaluate")
@click.option("--truth", required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help=truth_help)
@click.option("--pred", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Score this annotation (as written by `annotate --format csv`, 30 Hz frames); "
                   "without it the truth's documents are annotated from the database.")
@map_option
@click.option("--vocabulary", help="Comma-separated labels to score (default: the model's labels; with "
                                   "--pred: every truth label).")
@annotation_options
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

    con = None if pred is not None and ctx.obj.get("db") is None else open_db(ctx)
    vocab = [v.strip() for v in vocabulary.split(",")] if vocabulary else None
    result = api.evaluate(con, truth, pred=pred, model=model, tau=tau, keyframes=keyframes, label_map=label_map,
                          vocabulary=vocab, sweep_tau=sweep_tau, by_label=by_label, min_length=min_length,
                          min_won=min_won, margin=margin)
    if not sweep_tau:
        print_scores(list(result.items()) if by_label else [("all", result)])
    elif by_label:
        print_scores([(f"tau={t:.3f} {lab}", sc) for t, per in result for lab, sc in per.items()])
    else:
        print_scores([(f"tau={t:.3f}", sc) for t, sc in result])


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
@click.option("--batch-files", type=int, default=api.BATCH_FILES, show_default=True,
              help="Files per batch: the unit of work, of retry and of the Parquet parts.")
@click.option("--bucket-motions", type=int, default=api.BUCKET_MOTIONS, show_default=True,
              help="Motions per motion_bucket partition of features, postings and annotations.")
@click.option("--overwrite", is_flag=True, help="Replace an archive already in --out.")
@click.pass_context
def ray_annotate(ctx, sources, out, address, model, tau, keyframes, reader, num_cpus, batch_files, bucket_motions,
                 overwrite):
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

    report = api.ray_annotate(sources, out, address=address, model=model, tau=tau, keyframes=keyframes,
                              database=ctx.obj.get("db"), num_cpus=num_cpus, batch_files=batch_files,
                              bucket_motions=bucket_motions, overwrite=overwrite, **reader)
    # the failed files are data of the archive (its errors dataset): the run failed only if nothing went in
    echo_report(ctx, report, all_must_succeed=False)
