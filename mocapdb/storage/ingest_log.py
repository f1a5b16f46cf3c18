"""The ``ingest_log`` table: one row per file an ingest or import looked at, and what became of it.

Every ``ingest`` and ``import-features`` call is a *run* (``run_id`` from the
sequence ``ingest_run_seq``). Its rows say, per file — for a zip member the
archive's path and the member's — the outcome (``ingested``, ``skipped``,
``failed``, ``not a motion file``), the reason, the reader's notes and the
motion stored.

Transactions (DESIGN.md §6): the row of a stored file is inserted in the
transaction that stores its motion (:meth:`IngestLog.insert_stored`), so the
log never names a motion that is not there and a stored motion never lacks
its row. The other rows describe files that changed nothing; they collect in
the log and are written in transactions of their own (:meth:`IngestLog.flush`)
after each stored batch and at the end of the run, also when the run fails,
so a failed ingest leaves the tables as they were and still leaves its log.
A process killed mid-run loses only the unwritten rows of files since its
last batch.
"""
from __future__ import annotations

import csv
import os
from pathlib import Path

import pyarrow as pa

from mocapdb.errors import ParameterError
from mocapdb.readers.sources import ARCHIVES, split_archive
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction

#: what became of a file
OUTCOMES = ("ingested", "skipped", "failed", "not a motion file")
#: the columns of a run's rows (:func:`run_rows`, the ``--report`` CSV)
COLUMNS = ("path", "member", "outcome", "reason", "notes", "motion_id", "logged_at", "run_id", "command")


def _sql(name):
    return statement("ingest_log.sql", name)


def location(path) -> tuple:
    """``(path, member)`` of a file as the log names it: the absolute path on disk (of the zip archive,
    for a member) and the member inside the archive, or None.

    The member is the text after the archive's path as given, so a member refused for its name
    (``/etc/passwd``, ``../x.bvh``: :func:`mocapdb.readers.sources.member_problem`) keeps it.
    """
    text = str(path)
    if not any(a in text.lower() for a in ARCHIVES):   # the common case, per file of an archive: no path parsed
        return os.path.abspath(text), None
    archive, member = split_archive(text)
    if member:
        i = text.lower().find(".zip/")
        while i >= 0 and os.path.abspath(text[:i + 4]) != os.path.abspath(archive):
            i = text.lower().find(".zip/", i + 1)
        if i >= 0:
            member = text[i + 5:]
    return os.path.abspath(archive), (member or None)


class IngestLog:
    """The log rows of one run, written to ``ingest_log``.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
        A database with the mocapdb schema.
    command : str
        ``"ingest"`` or ``"import-features"``.
    """

    def __init__(self, con, command: str):
        self.con = con
        self.command = command
        self.run_id = int(con.execute(_sql("next_run")).fetchall()[0][0])
        self.pending = []
        self._seen = {}   # report list -> entries kept so far (add_report)

    def add(self, path, outcome: str, reason=None, notes=(), motion_id=None) -> None:
        """Keep a row for the next :meth:`flush` (a file that changed nothing: not stored)."""
        self.pending.append(self._row(path, outcome, reason, notes, motion_id))

    def _row(self, path, outcome, reason, notes, motion_id):
        if outcome not in OUTCOMES:
            raise ParameterError(f"outcome must be one of {', '.join(OUTCOMES)}, got {outcome!r}")
        where, member = location(path)
        return {"path": where, "member": member, "outcome": outcome, "reason": reason,
                "notes": "\n".join(notes) or None, "motion_id": motion_id}

    def add_report(self, report) -> None:
        """Keep a row for every entry of an :class:`~mocapdb.storage.ingest.IngestReport` not kept
        yet: its failed, skipped, not-motion and unreadable files (the stored ones are logged with
        their motions, :meth:`insert_stored`)."""
        for outcome, name in (("failed", "failed"), ("skipped", "skipped"), ("not a motion file", "unsupported"),
                              ("failed", "unreadable")):
            entries = getattr(report, name)
            n = len(entries)   # an entry appended meanwhile (ingest's other thread) is kept next time
            for path, reason in entries[self._seen.get(name, 0):n]:
                self.add(path, outcome, reason)
            self._seen[name] = n

    def insert_stored(self, rows) -> None:
        """Insert the rows of stored files inside the caller's transaction (the one storing them).

        ``rows``: ``(path, motion_id, reason, notes)`` per file; outcome ``ingested``.
        """
        self._insert([self._row(path, "ingested", reason, notes, mid) for path, mid, reason, notes in rows])

    def flush(self) -> None:
        """Write the kept rows, in a transaction of their own."""
        if self.pending:
            rows, self.pending = self.pending, []
            with transaction(self.con):
                self._insert(rows)

    def _insert(self, rows) -> None:
        if not rows:
            return
        table = pa.table({
            "ord": pa.array(range(len(rows)), pa.int64()),
            "run_id": pa.array([self.run_id] * len(rows), pa.int64()),
            "command": pa.array([self.command] * len(rows), pa.string()),
            **{k: pa.array([r[k] for r in rows], pa.int64() if k == "motion_id" else pa.string())
               for k in ("path", "member", "outcome", "reason", "notes", "motion_id")}})
        with registered(self.con, mocap_new_log=table):
            self.con.execute(_sql("insert"))


def run_rows(con, run_id: int) -> tuple:
    """``(columns, rows)`` of one run's log, by path (:data:`COLUMNS`)."""
    cur = con.execute(_sql("run"), {"run_id": int(run_id)})
    return [d[0] for d in cur.description], cur.fetchall()


def write_report(con, run_id: int, path) -> int:
    """Write one run's log rows as CSV (a header, then a row per file; NULL as an empty field; a text
    that would start a spreadsheet formula behind a ``'``).

    Returns
    -------
    int
        The number of rows written.
    """
    columns, rows = run_rows(con, run_id)
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        w.writerows([_cell(v) for v in r] for r in rows)
    return len(rows)


#: a text cell starting with one of these is a formula to a spreadsheet (=HYPERLINK(…) in a file name)
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _cell(v):
    """A CSV cell: NULL empty, a time ISO, and text that a spreadsheet would run as a formula quoted with a
    leading ``'`` (as spreadsheet-safe CSV writers do; the rows in the database keep the names as they are)."""
    if v is None:
        return ""
    if hasattr(v, "isoformat"):
        return v.isoformat(sep=" ")
    if isinstance(v, str) and v.startswith(_FORMULA_START):
        return "'" + v
    return v


__all__ = ["IngestLog", "OUTCOMES", "COLUMNS", "location", "run_rows", "write_report"]
