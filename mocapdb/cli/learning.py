"""Commands that build models (:mod:`mocapdb.api.learning`)."""
from __future__ import annotations

from pathlib import Path

import click

import mocapdb.api as api
from mocapdb.cli.options import folder_option, labels_option, model_option, silent_option
from mocapdb.cli.group import command, open_db, progress_bar, bar_progress
from mocapdb.cli.output import write_rows


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

    con = open_db(ctx, create=True)
    with progress_bar(None, "train", silent, unit="step") as bar:
        m = api.train(con, model=model, folder=folder, labels=labels, class_labels=class_labels, delta=delta,
                      tau=tau, replace=replace, progress=bar_progress(bar), definitions=list(definitions) or None)
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

    con = open_db(ctx, create=True)
    done_by_class = {}
    with progress_bar(None, "learn-keyframes", silent, unit="run") as bar:
        def progress(cls, done, total):
            done_by_class[cls] = done
            bar.set_description(cls[:28])
            bar.update(sum(done_by_class.values()) - bar.n)

        learned = api.learn_keyframes(con, model=model, folder=folder, labels=labels,
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
    compiled to a quantized template and a keyframe query (docs/MODEL.md "Class
    definitions"; paper Sect. 8). A [[keyframes]] table gives a class the
    model already has (a learned one) a designed keyframe query; with
    template = "NAME", a new class with that class's template and the query.

    \b
    Example:
      mocapdb --db a.duckdb define-class my_classes.toml --model mine
    """

    m = api.define_class(open_db(ctx, create=True), list(definitions), model=model, replace=replace)
    for c in m.classes:
        q = c.keyframe_query
        click.echo(f"{c.name:32s} -> {c.label:12s} K={len(c.quantized):4d}  keyframes={q.n_keyframes if q else 0}  "
                   f"tau={c.tau:g}")
    click.echo(f"model {model!r}: {len(m.classes)} classes, {len(m.labels)} labels")
