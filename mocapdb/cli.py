"""The ``mocapdb`` command line: one command per API function (sqlite-utils style).

Library exceptions become ``click.ClickException`` here (``Error: …``, exit 1);
progress bars are drawn here and nowhere else.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from .errors import MocapdbError


def _open(ctx, *, read_only=False):
    db = ctx.obj.get("db")
    if db is None:
        raise click.UsageError("this command needs a database: mocapdb --db FILE …")
    from .database import connect

    try:
        con = connect(db, read_only=read_only)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    ctx.call_on_close(con.close)
    return con


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--db", type=click.Path(dir_okay=False, path_type=Path), envvar="MOCAPDB_DB",
              help="DuckDB database file (created if missing). Env: MOCAPDB_DB.")
@click.version_option(package_name="mocapdb")
@click.pass_context
def main(ctx, db):
    """mocapdb: annotate and retrieve motion capture data with SQL.

    \b
    Example:
      mocapdb --db archive.duckdb ingest ../shared/data/cmu/86
      mocapdb --db archive.duckdb annotate
      mocapdb --db archive.duckdb sql "SELECT name, n_frames FROM motions"
    """
    ctx.ensure_object(dict)
    ctx.obj["db"] = db


def _progress_bar(total, label, silent):
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit="file", disable=silent, file=sys.stderr, leave=False)


@main.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@click.option("--asf", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Skeleton for every AMC file (default: found by the dataset conventions: "
                   "same-stem .asf, the CMU subject's NN.asf, HDM05's HDM_<actor>.asf).")
@click.option("--silent", is_flag=True, help="No progress bar.")
@click.pass_context
def ingest(ctx, paths, asf, silent):
    """Read ASF/AMC and BVH files (or folders, recursively) into the database.

    One transaction per file: a broken file changes nothing and the others
    still go in; files already stored (same bytes) are skipped.
    """
    from .ingest import ingest as ingest_files, motion_files

    con = _open(ctx)
    try:
        n = len(motion_files(paths))
        with _progress_bar(n, "ingest", silent) as bar:
            report = ingest_files(con, paths, asf=asf, progress=lambda path, frames: bar.update(1))
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    for path, reason in report.skipped:
        click.echo(f"skipped {path}: {reason}", err=True)
    for path, reason in report.failed:
        click.echo(f"failed  {reason}" if reason.startswith(path) else f"failed  {path}: {reason}", err=True)
    click.echo(f"{report.summary()} ({report.source_frames} source frames)")
    if report.failed and not report.ingested and not report.skipped:
        ctx.exit(1)


@main.command()
@click.argument("motions", nargs=-1, required=True)
@click.pass_context
def delete(ctx, motions):
    """Delete motions (ids or names) with their features, index postings and annotations."""
    from .database import motion_ids
    from .ingest import delete_motions

    con = _open(ctx)
    try:
        n = delete_motions(con, motion_ids(con, motions))
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    click.echo(f"{n} motion(s) deleted")


FORMATS = click.Choice(["table", "csv", "json"])


def write_relation(rel_or_rows, columns, fmt, out=None):
    """Print rows as an aligned table, CSV or JSON (to stdout or ``out``)."""
    import csv
    import io

    rows = rel_or_rows
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
            stream.write("  ".join(c.rjust(w) if _numeric(c) else c.ljust(w) for c, w in zip(r, widths)).rstrip() + "\n")
    text = stream.getvalue()
    if out is None:
        click.echo(text, nl=False)
    else:
        Path(out).write_text(text, encoding="utf-8")


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


@main.command()
@click.argument("query", required=False)
@click.option("--file", "sql_file", type=click.File("r", encoding="utf-8"),
              help="Read the query from a file ('-' for stdin), e.g. one of sql/queries/*.sql.")
@click.option("--format", "fmt", type=FORMATS, default="table", show_default=True)
@click.pass_context
def sql(ctx, query, sql_file, fmt):
    """Run a SQL query with the mocapdb functions registered and print the result.

    \b
    Example:
      mocapdb --db a.duckdb sql "SELECT name, unnest(annotate(motion_id), recursive := true) FROM motions"
      mocapdb --db a.duckdb sql --file sql/queries/long_kicks.sql --format csv
    """
    import duckdb

    if (query is None) == (sql_file is None):
        raise click.UsageError("give a QUERY or --file FILE (not both)")
    if sql_file is not None:
        query = sql_file.read()
    con = _open(ctx)
    try:
        rel = con.sql(query)
    except (duckdb.Error, MocapdbError) as exc:
        raise click.ClickException(str(exc)) from exc
    if rel is None:  # a statement without a result (CREATE, INSERT, …)
        return
    try:
        rows = rel.fetchall()
    except duckdb.Error as exc:
        raise click.ClickException(str(exc)) from exc
    if rel.columns == ["Count"] and fmt == "table":  # DDL/DML: DuckDB reports the rows changed
        click.echo(f"ok, {rows[0][0]} row(s) changed" if rows else "ok")
        return
    write_relation(rows, rel.columns, fmt)


@main.command()
@click.option("--model", required=True, help="Name to store the model under.")
@click.option("--folder", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Clips in the HDM05 cut layout: one folder per class (files read directly).")
@click.option("--labels", "label_csv", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Label CSV document,label,start_frame,end_frame (native frames, 1-based) cutting "
                   "clips out of ingested documents.")
@click.option("--class-labels", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="CSV class,label mapping fine classes to coarse labels (default: the shipped "
                   "HDM05 mapping when it covers every class).")
@click.option("--delta", type=float, default=0.05, show_default=True, help="Quantization threshold δ.")
@click.option("--tau", type=float, default=0.13, show_default=True, help="Hit threshold τ.")
@click.option("--replace", is_flag=True, help="Overwrite a stored model of the same name.")
@click.option("--silent", is_flag=True, help="No progress bar.")
@click.pass_context
def train(ctx, model, folder, label_csv, class_labels, delta, tau, replace, silent):
    """Learn class motion templates from labelled clips and store them as a model.

    \b
    Example:
      mocapdb --db a.duckdb train --model hdm05 --folder ../shared/data/hdm05_cut
    """
    from tqdm import tqdm

    from .api import train as train_model

    con = _open(ctx)
    bar = tqdm(desc="train", unit="step", disable=silent, file=sys.stderr, leave=False)

    def progress(done, total, what):
        bar.total = total
        bar.n = done
        bar.refresh()

    try:
        m = train_model(con, model=model, folder=folder, label_csv=label_csv, class_labels=class_labels,
                        delta=delta, tau=tau, replace=replace, progress=progress)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    finally:
        bar.close()
    for c in m.classes:
        n = getattr(c.template, "n_clips", None)
        click.echo(f"{c.name:32s} -> {c.label:12s} K={len(c.quantized):4d}  clips={n}")
    click.echo(f"model {model!r}: {len(m.classes)} classes, {len(m.labels)} labels")


@main.command("learn-keyframes")
@click.option("--model", default="default", show_default=True, help="The stored model whose classes get queries.")
@click.option("--folder", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Training clips, one folder per class (HDM05 cut layout).")
@click.option("--labels", "label_csv", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Label CSV cutting training clips out of ingested documents.")
@click.option("--classes", help="Comma-separated classes to learn (default: all of the model's).")
@click.option("--runs", type=int, default=20, show_default=True, help="GA runs per class (paper: 100-500).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed: same seed, same queries.")
@click.option("--generations", type=int, default=100, show_default=True, help="Generations per run (paper: 100).")
@click.option("--jobs", "n_jobs", type=int, help="Worker processes (default: all cores).")
@click.option("--silent", is_flag=True, help="No progress bar.")
@click.pass_context
def learn_keyframes_cmd(ctx, model, folder, label_csv, classes, runs, seed, generations, n_jobs, silent):
    """Learn one keyframe query per class with the genetic algorithm (paper Sect. 6).

    T+ = the class's clips, T- = the clips of every other class; the query with
    the consensus of the runs is stored in keyframe_queries with its fitness,
    precision and recall on the training clips.

    \b
    Example:
      mocapdb --db a.duckdb learn-keyframes --model hdm05 --folder ../shared/data/hdm05_cut --runs 20
    """
    from tqdm import tqdm

    from .api import learn_keyframes

    con = _open(ctx)
    bar = tqdm(desc="learn-keyframes", unit="run", disable=silent, file=sys.stderr, leave=False)
    done_by_class = {}

    def progress(cls, done, total):
        done_by_class[cls] = done
        bar.set_description(cls[:28])
        bar.update(sum(done_by_class.values()) - bar.n)

    try:
        learned = learn_keyframes(con, model=model, folder=folder, label_csv=label_csv,
                                  classes=classes.split(",") if classes else None, runs=runs, seed=seed,
                                  n_jobs=n_jobs, progress=progress, generations=generations)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    finally:
        bar.close()
    rows = [(name, lq.query.n_keyframes, f"{lq.fitness:.3f}", f"{lq.precision:.3f}", f"{lq.recall:.3f}")
            for name, lq in learned.items()]
    write_relation(rows, ["class", "keyframes", "fitness", "precision", "recall"], "table")


@main.command()
@click.argument("motions", nargs=-1)
@click.option("--model", default="default", show_default=True,
              help="Model name (the shipped default model is loaded on first use).")
@click.option("--tau", type=float, help="Hit threshold τ for every class (default: each class's, 0.13).")
@click.option("--keyframes/--no-keyframes", default=None,
              help="Keyframe preselection (default: on when the model has keyframe queries).")
@click.option("--format", "fmt", type=FORMATS, default="table", show_default=True)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), help="Write to a file instead of stdout.")
@click.pass_context
def annotate(ctx, motions, model, tau, keyframes, fmt, out):
    """Annotate motions (ids or names; default all) and store the segments in `annotations`.

    Frames are 30 Hz frames, 1-based inclusive; CSV columns
    document,label,start_frame,end_frame,start_s,end_s,cost.

    \b
    Example:
      mocapdb --db a.duckdb annotate --format csv --out segments.csv
    """
    from .api import annotate_motions
    from .database import motion_ids

    con = _open(ctx)
    try:
        ids = motion_ids(con, motions) if motions else None
        table = annotate_motions(con, ids, model=model, tau=tau, keyframes=keyframes)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    cols = ["document", "label", "start_frame", "end_frame", "start_s", "end_s", "cost"]
    rows = list(zip(*(table.column(c).to_pylist() for c in cols)))
    write_relation(rows, cols, fmt, out)


def _print_scores(rows):
    """rows: (setting, Scores) pairs → a table of the paper's six measures."""
    cols = ["", "P1", "R1", "F1", "P2", "R2", "F2", "frames M/A", "segments M/A"]
    out = [[str(name), *(f"{getattr(sc, k):.3f}" for k in ("p1", "r1", "f1", "p2", "r2", "f2")),
            f"{sc.truth_frames}/{sc.auto_frames}", f"{sc.truth_segments}/{sc.auto_segments}"]
           for name, sc in rows]
    write_relation(out, cols, "table")
    dropped = rows[0][1].dropped_truth if rows else {}
    if dropped:
        click.echo("truth labels the model cannot produce (not scored): "
                   + ", ".join(f"{k} ({v})" for k, v in sorted(dropped.items())))


@main.command("eval")
@click.option("--truth", required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Ground truth CSV document,label,start_frame,end_frame (native frames, 1-based).")
@click.option("--pred", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Predictions CSV as written by `annotate --format csv` (30 Hz frames); "
                   "without it the truth's documents are annotated from the database.")
@click.option("--map", "label_map", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="CSV class,label renaming truth labels to model labels (e.g. walk -> move).")
@click.option("--labels", "vocabulary", help="Comma-separated labels to score (with --pred; default: "
                                             "every truth label). With a database: the model's labels.")
@click.option("--model", default="default", show_default=True)
@click.option("--tau", type=float, help="Hit threshold τ for every class (default: each class's).")
@click.option("--keyframes/--no-keyframes", default=None, help="Keyframe preselection (default: model's).")
@click.option("--sweep-tau", help="START:STOP:STEP, e.g. 0.05:0.25:0.01 — P/R/F per τ (paper Fig. 8).")
@click.pass_context
def eval_cmd(ctx, truth, pred, label_map, vocabulary, model, tau, keyframes, sweep_tau):
    """Frame-level P1/R1/F1 and segment-level P2/R2/F2 against ground truth (paper Eq. 5-8).

    All documents are concatenated, as in the paper; truth frames are
    converted to the 30 Hz feature grid.

    \b
    Examples:
      mocapdb eval --truth truth.csv --pred segments.csv
      mocapdb --db a.duckdb eval --truth truth.csv --map walk_is_move.csv --sweep-tau 0.05:0.25:0.01
    """
    from .api import evaluate, read_truth
    from .labels import read_segments
    from .metrics import evaluate_annotation, parse_tau_grid

    try:
        if pred is not None:
            if sweep_tau:
                raise click.UsageError("--sweep-tau re-annotates: use it with --db, not with --pred")
            vocab = [v.strip() for v in vocabulary.split(",")] if vocabulary else None
            scores = evaluate_annotation(read_truth(truth, label_map=label_map), read_segments(pred),
                                         labels=vocab)
            _print_scores([("all", scores)])
            return
        if ctx.obj.get("db") is None:
            raise click.UsageError("give --pred FILE, or a database (mocapdb --db FILE eval …) to annotate")
        con = _open(ctx)
        if sweep_tau:
            result = evaluate(con, truth, model=model, keyframes=keyframes, label_map=label_map,
                              taus=parse_tau_grid(sweep_tau))
            _print_scores([(f"tau={t:.3f}", sc) for t, sc in result])
        else:
            _print_scores([("all", evaluate(con, truth, model=model, tau=tau, keyframes=keyframes,
                                            label_map=label_map))])
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc


@main.command()
@click.option("--figure", type=click.Choice(["ga", "annotation"]), required=True,
              help="ga: GA precision/recall/fitness over generations (paper Fig. 5); "
                   "annotation: the labels of one motion over time (paper Fig. 6).")
@click.option("--out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Image file (format from the suffix: .png, .pdf, .svg).")
@click.option("--model", default="default", show_default=True)
@click.option("--motion", help="Motion id or name (for --figure annotation).")
@click.option("--keyframes/--no-keyframes", default=None, help="Keyframe preselection (annotation figure).")
@click.pass_context
def report(ctx, figure, out, model, motion, keyframes):
    """Draw a figure from the database (needs the 'plot' extra: pip install 'mocapdb[plot]').

    \b
    Examples:
      mocapdb --db a.duckdb report --figure ga --out fig5.png
      mocapdb --db a.duckdb report --figure annotation --motion 86_09 --out 86_09.png
    """
    from .api import plot_figure

    con = _open(ctx)
    try:
        plot_figure(con, figure, out, model=model, motion=motion, keyframes=keyframes)
    except (MocapdbError, ImportError) as exc:
        raise click.ClickException(str(exc)) from exc
    click.echo(f"written {out}")


@main.command()
@click.option("--drop", is_flag=True, help="Remove the index instead (DROP SCHEMA mocap_index CASCADE).")
@click.pass_context
def index(ctx, drop):
    """(Re)build the keyframe index (schema mocap_index) from the features, or drop it.

    A new database has the index; ingest and delete keep it up to date while it exists.
    """
    from .postings import create_index, drop_index

    con = _open(ctx)
    if drop:
        drop_index(con)
        click.echo("keyframe index dropped")
        return
    n = create_index(con)
    click.echo(f"keyframe index built: {n} postings")


@main.command("export-features")
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path))
@click.option("--overwrite", is_flag=True, help="Write into a non-empty directory.")
@click.pass_context
def export_features_cmd(ctx, directory, overwrite):
    """Write motions and features to Parquet, partitioned by motion (DIR/features/motion_id=N/)."""
    from .parquet import export_features

    con = _open(ctx, read_only=False)
    try:
        n = export_features(con, directory, overwrite=overwrite)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    click.echo(f"{n} motion(s) exported to {directory}")


@main.command("import-features")
@click.argument("directory", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.pass_context
def import_features_cmd(ctx, directory):
    """Load motions and features exported by export-features (motions already present are kept)."""
    from .parquet import import_features

    con = _open(ctx)
    try:
        mapping = import_features(con, directory)
    except MocapdbError as exc:
        raise click.ClickException(str(exc)) from exc
    click.echo(f"{len(mapping)} motion(s) imported")


if __name__ == "__main__":  # pragma: no cover
    main()
