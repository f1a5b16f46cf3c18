"""Printing results: tables, CSV and JSON rows, ingest reports, scores."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import click

from mocapdb.errors import escape_control


def write_rows(rows, columns, fmt, out=None, *, width=None):
    """Print rows as an aligned table, CSV or JSON (to stdout or ``out``).

    ``width``: a table's lines kept within this many characters (the terminal's), the widest columns
    narrowed and their longer cells cut in the middle (a path keeps its start and its file name).
    """
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
        if width is not None:
            widths = _narrowed(widths, [len(str(c)) for c in columns], width)
            cells = [[_cut(c, w) for c, w in zip(r, widths)] for r in cells]
        stream.write("  ".join(str(c).ljust(w) for c, w in zip(columns, widths)).rstrip() + "\n")
        stream.write("  ".join("-" * w for w in widths) + "\n")
        for r in cells:
            stream.write("  ".join(c.rjust(w) if _numeric(c) else c.ljust(w) for c, w in zip(r, widths)).rstrip()
                         + "\n")
    if out is None:
        click.echo(stream.getvalue(), nl=False)
    else:
        Path(out).write_text(stream.getvalue(), encoding="utf-8")


#: a column narrowed to fit the terminal keeps at least this many characters (or its heading's)
_MIN_COLUMN = 12


def _narrowed(widths, headings, total):
    """Column widths whose table (two spaces between columns) fits ``total`` characters where it can:
    the widest column gives up a character at a time."""
    widths = list(widths)
    floor = [max(h, _MIN_COLUMN) for h in headings]
    while sum(widths) + 2 * (len(widths) - 1) > total:
        k = max(range(len(widths)), key=lambda i: widths[i] - floor[i])
        if widths[k] <= floor[k]:
            break
        widths[k] -= 1
    return widths


def _cut(text, width):
    """``text`` within ``width`` characters: its start and end kept, the middle an ellipsis."""
    if len(text) <= width:
        return text
    tail = (width - 1) // 2
    return text[:width - 1 - tail] + "…" + (text[-tail:] if tail else "")


def duration(seconds) -> str:
    """A duration as the pages of ``serve`` write it (``common.js``): ``12.3 s``, ``3 min 09 s``,
    ``12 h 05 min``."""
    s = float(seconds)
    if s < 59.95:
        return f"{s:.1f} s"
    whole = round(s)
    m, h = whole // 60, whole // 3600
    return f"{h} h {m % 60:02d} min" if h else f"{m} min {whole % 60:02d} s"


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


def echo_report(ctx, report, *, all_must_succeed=True, log_csv=None):
    """One line per file a run could not read (failed, or an unreadable folder entry), then its
    summary and where the rest is (every file's row: the ``ingest_log`` table, ``--report``); exit 1
    when any file failed (``all_must_succeed``), else when no file went in."""
    lines = [f"unreadable {path}: {reason}" for path, reason in getattr(report, "unreadable", ())]
    lines += [f"failed  {reason}" if reason.startswith(path) else f"failed  {path}: {reason}"
              for path, reason in report.failed]
    for line in lines:
        # control characters of a file name or a binary file's bytes are never sent raw
        click.echo(escape_control(line), err=True)
    click.echo(f"{report.summary()} ({report.source_frames} source frames)")
    run_id = getattr(report, "run_id", None)
    if run_id is not None:
        click.echo(f"every file's outcome, reason and notes: ingest_log run {run_id}"
                   + (f", and {log_csv}" if log_csv is not None else
                      f" (SELECT * FROM ingest_log WHERE run_id = {run_id}; --report FILE writes a CSV)"),
                   err=True)
    if report.failed and (all_must_succeed or not (report.ingested or report.skipped)):
        ctx.exit(1)


def frame_rates(table):
    """The rate of each segment's frames (30 Hz feature frames): its frames over its seconds."""
    return [(e - s + 1) / (b - a) for s, e, a, b in zip(*(table.column(c).to_pylist() for c in
                                                       ("start_frame", "end_frame", "start_s", "end_s")))]


def print_scores(rows):
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
