"""What an archive holds: hours and motions per source format and rate, annotated hours per label, refused files.

``mocapdb stats`` prints it and ``/stats`` of ``mocapdb serve`` draws it
(``sql/stats.sql``). Refused files come from the ``ingest_log`` table, which
newer databases keep (one row per file an ingest looked at, with its
outcome); a database without that table has nothing to say about them, and
:attr:`ArchiveStats.refused` is then None rather than an empty table. A file
counts as refused when its latest log row says it failed or is not a motion
file (stored later, it no longer does).
"""
from __future__ import annotations

from dataclasses import dataclass

import pyarrow as pa
import pyarrow.compute as pc

from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.sqltext import statement

__all__ = ["ArchiveStats", "archive_stats"]


def _sql(name):
    return statement("stats.sql", name)


@dataclass(frozen=True)
class ArchiveStats:
    """A summary of an archive (:func:`archive_stats`).

    Attributes
    ----------
    model : str
        The model whose stored annotations ``labels`` sums.
    formats : pyarrow.Table
        ``format, source_fps, motions, hours`` per source format and native rate,
        most hours first.
    labels : pyarrow.Table
        ``label, segments, motions, hours`` per label of ``model``'s stored
        annotations, most hours first.
    annotated_models : tuple of str
        Every model with stored annotations.
    refused : pyarrow.Table or None
        ``path, member, outcome, reason, logged_at`` of each file whose latest
        ingest refused it; None when the database keeps no ingest log.
    """

    model: str
    formats: pa.Table
    labels: pa.Table
    annotated_models: tuple
    refused: pa.Table | None

    @property
    def motions(self) -> int:
        """Motions in the archive."""
        return int(pc.sum(self.formats.column("motions")).as_py() or 0)

    @property
    def hours(self) -> float:
        """Hours of motion in the archive (feature frames over their rate)."""
        return float(pc.sum(self.formats.column("hours")).as_py() or 0.0)

    def tables(self) -> dict:
        """The tables by name (``formats``, ``labels``, and ``refused`` when the database logs ingests)."""
        out = {"formats": self.formats, "labels": self.labels}
        if self.refused is not None:
            out["refused"] = self.refused
        return out


def archive_stats(con, *, model=DEFAULT_MODEL) -> ArchiveStats:
    """Summarise an archive (reads only).

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    model : str, keyword-only
        The model whose stored annotations give the hours per label.

    Returns
    -------
    ArchiveStats
    """
    formats = con.sql(_sql("formats")).to_arrow_table()
    labels = con.sql(_sql("labels"), params={"model": model}).to_arrow_table()
    models = tuple(r[0] for r in con.execute(_sql("models")).fetchall())
    refused = None
    if con.execute(_sql("has_ingest_log")).fetchall()[0][0]:
        refused = con.sql(_sql("refused")).to_arrow_table()
    return ArchiveStats(model=model, formats=formats, labels=labels, annotated_models=models, refused=refused)
