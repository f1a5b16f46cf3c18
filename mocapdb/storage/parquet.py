"""Moving features between a mocap database and Parquet files.

Layout written by :func:`export_features` (DuckDB reads it in place)::

    DIR/motions.parquet                       one row per motion (the motions table), written last
    DIR/features/motion_id=<id>/*.parquet     frame, bits of that motion (hive partitioning)

:func:`import_features` also reads the archives that ``mocapdb.distributed``
writes on a Ray cluster, whose datasets have the columns of the tables
(:func:`table_schemas`)::

    DIR/motions/*.parquet                              the motions table
    DIR/features/motion_bucket=<k>/*.parquet           motion_id, frame, bits
    DIR/annotations/motion_bucket=<k>/*.parquet        the annotations table (imported too)
    DIR/manifest.json                                  written last: the run finished

An archive is imported a batch of motions at a time (memory of one batch,
one transaction each), and every motion is checked to be exactly its frames
1 … ``n_frames``: a motion whose features are missing, partial or unreadable
is refused and named, never stored, and the others go in. A Ray archive
without its manifest (a run that did not finish) is refused whole, because
the batches that never ran left no trace in it to check against.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import duckdb
import numpy as np
import pyarrow as pa
import pyarrow.compute  # noqa: F401 - pa.compute
import pyarrow.parquet as pq

from mocapdb.errors import MocapdbError, ParameterError, SchemaError, shorten
from mocapdb.storage.ingest import insert_features, remove_motions
from mocapdb.storage.ingest_log import IngestLog
from mocapdb.storage.motions import (BATCH_FRAMES, check_frames, frame_batches, incomplete_motions,
                                     incomplete_reason)
from mocapdb.storage.names import check_motion_names
from mocapdb.storage.schema import open_database
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction

#: the file that marks a finished ``ray_annotate`` archive (written last, by the driver)
MANIFEST = "manifest.json"
#: the motions of an export (written last: an export without it did not finish)
EXPORT_MOTIONS = "motions.parquet"
_PART = re.compile(r"^part-(\d+)-(\d+)\.parquet$")
_MOTION_DIR = re.compile(r"^motion_id=(\d+)$")


def _sql(name):
    return statement("parquet.sql", name)


def export_features(con, directory, *, overwrite: bool = False) -> int:
    """Write ``motions`` and ``features`` to Parquet, partitioned by motion.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    directory : str or Path
        Target folder; must be empty or absent unless ``overwrite``, which
        replaces an earlier export's ``features/`` and ``motions.parquet``
        (and nothing else in the folder): a partition of a motion no longer
        exported would otherwise stay behind for in-place readers.
    overwrite : bool, keyword-only

    Returns
    -------
    int
        Number of motions written.

    Notes
    -----
    ``motions.parquet`` is written last, under a temporary name and renamed:
    a folder without it is an export that did not finish. Before it,
    ``digests.json`` records every part's SHA-256, which
    :func:`import_features` checks.
    """
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ParameterError(f"directory: {str(d)!r} is a file; give a folder")
    if d.exists() and any(d.iterdir()) and not overwrite:
        raise ParameterError(f"directory: {str(d)!r} is not empty; pass overwrite=True (--overwrite)")
    d.mkdir(parents=True, exist_ok=True)
    (d / EXPORT_MOTIONS).unlink(missing_ok=True)
    shutil.rmtree(d / "features", ignore_errors=True)
    (d / EXPORT_DIGESTS).unlink(missing_ok=True)
    con.execute(_sql("export_features"), {"path": str(d / "features")})
    tmp = d / f".{EXPORT_MOTIONS}.tmp"
    con.execute(_sql("export_motions"), {"path": str(tmp)})
    # each part's digest (motions.parquet's under its final name), before the rename that finishes the export
    parts = [f.relative_to(d).as_posix() for f in sorted((d / "features").rglob("*.parquet"))]
    digests = {**part_digests(d, parts), EXPORT_MOTIONS: file_digest(tmp)}
    (d / EXPORT_DIGESTS).write_text(json.dumps({"sha256": digests}, indent=1, sort_keys=True) + "\n",
                                    encoding="utf-8")
    os.replace(tmp, d / EXPORT_MOTIONS)
    return con.execute(statement("motions.sql", "count")).fetchall()[0][0]


def features_sql(directory) -> str:
    """SQL text of a query over exported features in place: ``(motion_id, frame, bits)``.

    Usable as a subquery or view, e.g.
    ``CREATE VIEW archive AS <features_sql(DIR)>``: DuckDB reads the Parquet
    files without loading them.
    """
    d = Path(directory)
    if not (d / "features").is_dir():
        raise ParameterError(f"directory: {str(d)!r} has no features/ folder (written by export_features)")
    return (f"SELECT motion_id::INTEGER AS motion_id, frame, bits "
            f"FROM read_parquet({_quote(d / 'features' / '*' / '*.parquet')}, hive_partitioning = true)")


def _quote(path: Path) -> str:
    return "'" + str(path).replace("'", "''") + "'"


#: the DuckDB table each Parquet dataset of an archive mirrors (:func:`table_schemas`)
ARCHIVE_TABLES = ("motions", "features", "postings", "annotations")


def table_schemas() -> dict:
    """The Arrow schemas of the tables an archive on Parquet mirrors, read from DuckDB.

    Returns
    -------
    dict of str to pyarrow.Schema
        For each of :data:`ARCHIVE_TABLES`: the columns and types of the table
        (``postings``: ``mocap_index.postings``) as ``sql/schema.sql`` and
        ``sql/index.sql`` create it.
    """
    con = open_database(":memory:")
    try:
        return {t: con.sql(_sql(f"empty_{t}")).to_arrow_table().schema for t in ARCHIVE_TABLES}
    finally:
        con.close()


# -- reading an archive -----------------------------------------------------------------------


def write_manifest(directory, manifest: dict) -> None:
    """Write ``manifest.json`` (atomically: a temporary name, then a rename); the last file of an archive."""
    d = Path(directory)
    tmp = d / f".{MANIFEST}.tmp"
    tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True, default=str) + "\n", encoding="utf-8")
    os.replace(tmp, d / MANIFEST)


def read_manifest(directory):
    """The manifest of a finished ``ray_annotate`` archive, or None when there is none."""
    f = Path(directory) / MANIFEST
    if not f.is_file():
        return None
    try:
        manifest = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SchemaError(f"{f}: not a readable manifest ({exc})") from None
    # JSON of another shape (a list, parts that are no table of row counts) is no manifest of ours
    parts = manifest.get("parts", {}) if isinstance(manifest, dict) else None
    digests = manifest.get("digests", {}) if isinstance(manifest, dict) else None
    if not (isinstance(parts, dict) and all(isinstance(k, str) and type(v) is int for k, v in parts.items())
            and isinstance(digests, dict) and all(isinstance(v, str) for v in digests.values())
            and all(type(manifest.get(k, 0)) is int for k in ("motions", "segments"))):
        raise SchemaError(f"{f}: not a manifest of ray-annotate (an object whose motions, segments and parts "
                          f"count rows; found {type(manifest).__name__} {shorten(json.dumps(manifest)[:200])})")
    return manifest


def _parts(root: Path) -> list:
    """``(first, last, path)`` of the ``part-<first>-<last>.parquet`` files under a dataset folder."""
    out = []
    for f in sorted(root.rglob("part-*.parquet")) if root.is_dir() else ():
        m = _PART.match(f.name)
        if m:
            out.append((int(m[1]), int(m[2]), f))
    return out


@dataclass
class Archive:
    """An archive on disk: its motions and where each motion's rows are.

    Attributes
    ----------
    root : Path
    kind : {"export", "ray"}
    motions : pyarrow.Table
        The ``motions`` rows (archive motion ids).
    """

    root: Path
    kind: str
    motions: pa.Table
    _parts: dict = field(default_factory=dict, repr=False)  # dataset -> its Ray parts, listed once
    #: an export's feature parts whose bytes differ from digests.json (file -> why): their motions are refused
    changed: dict = field(default_factory=dict, repr=False)

    @classmethod
    def open(cls, directory, *, whole=False) -> "Archive":
        """Recognise an export or a finished Ray archive, and check a Ray archive against its manifest.

        Every part of a Ray archive must be one its manifest lists, with the
        rows it lists (the Parquet footers say: nothing is read); an archive of
        an older mocapdb, whose manifest lists no parts, must hold the features
        and annotations rows its motions and manifest count. ``whole``:
        every part must be readable too (an import refuses only the motions of
        an unreadable part).

        Raises
        ------
        ParameterError
            Neither layout, an export or Ray run that did not finish (named), or
            a part missing, extra or changed (the first three named, in one line).
        """
        d = Path(directory)
        if (d / "motions").is_dir():
            manifest = read_manifest(d)
            if manifest is None:
                raise ParameterError(
                    f"directory: {str(d)!r} is an unfinished ray-annotate archive (no {MANIFEST}, which the run "
                    "writes last): the run was stopped before the end, and the motions of its unfinished "
                    "batches are missing; run ray-annotate again (--overwrite)")
            found = archive_parts(d)
            problems = _part_problems(manifest, found)
            if not problems and "digests" in manifest:   # the same parts with the same rows: their bytes
                problems = _digest_problems(d, manifest["digests"], MANIFEST)
            if whole:
                problems += [f"{rel}: not a readable Parquet file" for rel, rows in found.items() if rows < 0]
            _refuse(d, problems)
            motions = _read_motions(d / "motions")
            if manifest.get("motions") != motions.num_rows:
                raise ParameterError(f"directory: {str(d)!r} holds {motions.num_rows} motions, but its {MANIFEST} "
                                     f"lists {manifest.get('motions')}: parts of motions/ are missing or foreign")
            if "parts" not in manifest:   # an archive of an older mocapdb: its totals
                rows = {ds: sum(n for rel, n in found.items() if rel.startswith(f"{ds}/") and n > 0) for ds in DATASETS}
                want = {"features": int(pa.compute.sum(motions.column("n_frames")).as_py() or 0),
                        "annotations": manifest.get("segments")}
                _refuse(d, [f"{ds}/ holds {rows[ds]} rows, {MANIFEST} says {n}" for ds, n in want.items()
                            if n is not None and rows[ds] != n])
            return cls(d, "ray", motions)
        if (d / EXPORT_MOTIONS).is_file():
            changed = {}
            if (d / EXPORT_DIGESTS).is_file():   # an export of an older mocapdb has none: rows checked only
                listed = _read_digests(d / EXPORT_DIGESTS)
                found = {f.relative_to(d).as_posix() for f in (d / "features").rglob("*.parquet")} \
                    if (d / "features").is_dir() else set()
                # the motions table and foreign parts concern every motion: the export is refused whole
                _refuse(d, _digest_problems(d, {k: v for k, v in listed.items() if k == EXPORT_MOTIONS},
                                            EXPORT_DIGESTS)
                        + [f"{rel} is not one of its parts (a copy, or a part of another export)"
                           for rel in sorted(found - set(listed)) if not Path(rel).name.startswith(".")],
                        EXPORT_DIGESTS, "export again (--overwrite)")
                # a changed feature part costs its motion, as a missing or unreadable one does
                changed = {d / rel: _changed(rel, EXPORT_DIGESTS) for rel in _changed_parts(
                    d, {k: v for k, v in listed.items() if k != EXPORT_MOTIONS})}
            return cls(d, "export", _read_motions(d / EXPORT_MOTIONS), changed=changed)
        if (d / "features").is_dir():
            raise ParameterError(f"directory: {str(d)!r} has features/ but no {EXPORT_MOTIONS}, which "
                                 "export-features writes last: the export did not finish; export again (--overwrite)")
        raise ParameterError(f"directory: {str(d)!r} has no {EXPORT_MOTIONS} or motions/ (written by "
                             "export_features or ray_annotate)")

    def files(self, dataset, ids) -> dict:
        """``{file: (first id, last id)}`` of a dataset's files that may hold rows of motions ``ids`` (ascending)."""
        lo, hi = int(ids[0]), int(ids[-1])
        if self.kind == "ray":
            found = {f: (a, b) for a, b, f in self._ray_parts(dataset) if a <= hi and b >= lo}
            # a part holds a batch's motions, which may interleave with ids of other batches
            return {f: r for f, r in found.items() if np.any((ids >= r[0]) & (ids <= r[1]))}
        if dataset != "features":
            return {}
        out = {}
        for mid in ids.tolist():
            folder = self.root / "features" / f"motion_id={mid}"
            for f in sorted(folder.glob("*.parquet")) if folder.is_dir() else ():
                out[f] = (mid, mid)
        return out

    def _ray_parts(self, dataset):
        if dataset not in self._parts:
            self._parts[dataset] = _parts(self.root / dataset)
        return self._parts[dataset]


#: the file of an export naming each part's content digest (written before motions.parquet)
EXPORT_DIGESTS = "digests.json"


def file_digest(path) -> str:
    """The SHA-256 of a file's bytes (hex), read a MiB at a time."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def part_digests(directory, rels) -> dict:
    """``{relative path: SHA-256}`` of parts of an archive (written at export, checked on import and attach:
    a part whose rows were rewritten keeps its row count, not its bytes)."""
    d = Path(directory)
    return {rel: file_digest(d / rel) for rel in sorted(rels)}


def _changed_parts(d: Path, listed: dict) -> list:
    """The parts of ``listed`` (``{rel: digest}``) that are there with other bytes."""
    return [rel for rel, digest in listed.items() if (d / rel).is_file() and file_digest(d / rel) != digest]


def _changed(rel, source) -> str:
    return f"{rel} is not the file written (its bytes differ from the SHA-256 in {source}: changed since)"


def _digest_problems(d: Path, listed: dict, source: str) -> list:
    """Parts of ``listed`` (``{rel: digest}`` from ``source``) that are missing or have other bytes."""
    return ([f"{rel} is missing" for rel in listed if not (d / rel).is_file()]
            + [_changed(rel, source) for rel in _changed_parts(d, listed)])


#: the datasets of a Ray archive: the tables and the files that failed
DATASETS = (*ARCHIVE_TABLES, "errors")


def archive_parts(directory) -> dict:
    """``{relative path: rows}`` of every Parquet part of a Ray archive's datasets (rows from the file's
    footer, -1 for a file that is no readable Parquet); temporary files (a leading dot) left out."""
    d = Path(directory)
    out = {}
    for dataset in DATASETS:
        for f in sorted((d / dataset).rglob("*.parquet")) if (d / dataset).is_dir() else ():
            if not f.name.startswith("."):
                try:
                    rows = pq.read_metadata(f).num_rows
                except (OSError, pa.ArrowException):
                    rows = -1
                out[f.relative_to(d).as_posix()] = rows
    return out


def _part_problems(manifest: dict, found: dict) -> list:
    """What differs between the parts a manifest lists and those ``found`` (:func:`archive_parts`)."""
    listed = manifest.get("parts")
    if listed is None:
        return []
    out = [f"{rel} ({rows} rows) is missing" for rel, rows in listed.items() if rel not in found]
    out += [f"{rel} holds {found[rel]} rows, {MANIFEST} says {rows}" for rel, rows in listed.items()
            if found.get(rel, -1) >= 0 and found[rel] != rows]
    return out + [f"{rel} is not one of its parts (a copy, or a part of another run)" for rel in found
                  if rel not in listed]


def _refuse(d: Path, problems: list, listing=MANIFEST, again="run ray-annotate again (--overwrite)") -> None:
    """One line naming an archive's first problems."""
    if problems:
        more = f"; {len(problems) - 3} more" if len(problems) > 3 else ""
        raise ParameterError(f"directory: {str(d)!r} does not match its {listing}: " + "; ".join(problems[:3])
                             + more + f"; {again} or restore the archive")


def _read_digests(f: Path) -> dict:
    """An export's ``{part: SHA-256}`` (:data:`EXPORT_DIGESTS`)."""
    try:
        listed = json.loads(f.read_text(encoding="utf-8")).get("sha256")
    except (OSError, ValueError, AttributeError) as exc:
        raise SchemaError(f"{f}: not a readable list of digests ({exc})") from None
    if not (isinstance(listed, dict) and all(isinstance(k, str) and isinstance(v, str) for k, v in listed.items())):
        raise SchemaError(f"{f}: not a list of digests (an object \"sha256\": {{part: digest}})")
    return listed


def _read_motions(path: Path) -> pa.Table:
    try:
        table = pq.read_table(path, partitioning=None) if path.is_dir() else pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise SchemaError(f"{path}: cannot read the archive's motions ({exc})") from None
    missing = [c for c in ("motion_id", "name", "n_frames", "sha256") if c not in table.column_names]
    if missing:   # no part at all reads as a table without columns
        raise SchemaError(f"{path}: no motions table in it (columns {', '.join(missing)} missing)")
    return table.sort_by("motion_id")


def check_frames_per_motion(con, archive: "Archive") -> None:
    """A Ray archive's features parts must hold each motion's frames 1 … n_frames, once each (attach's check:
    the views read the parts in place; an import checks a batch at a time as it reads it).

    Raises
    ------
    ParameterError
        Naming the first motions whose rows are missing, partial or doubled, in one line.
    """
    files = [str(archive.root / rel) for rel in archive_parts(archive.root) if rel.startswith("features/")]
    counts = con.execute(_sql("archive_frame_counts"), {"files": files}).fetchnumpy() if files else {}
    got = {int(m): (int(n), int(a), int(b)) for m, n, a, b in zip(*(counts.get(c, ()) for c in
                                                                    ("motion_id", "n_rows", "first", "last")))}
    problems = []
    for mid, name, n in zip(*(archive.motions.column(c).to_pylist() for c in ("motion_id", "name", "n_frames"))):
        rows, first, last = got.pop(int(mid), (0, 1, 0))
        if (rows, first, last) != (n, 1, n) and n:
            problems.append(incomplete_reason(mid, name, rows, n, what="motion", remedy="features missing or doubled"))
    problems += [f"features of motion {mid}, which motions/ does not list" for mid in sorted(got)]
    _refuse(archive.root, problems)


def _read_rows(con, name, files, lo, hi):
    """Rows of an archive dataset in ``files`` for motions ``lo`` … ``hi``, and the files that did not read.

    Returns
    -------
    rows : pyarrow.Table, or None (no file read)
    bad : dict of Path to str
        A file DuckDB could not read (truncated, not Parquet) and its error: the
        rest is read without it, and the motions it would hold are refused.
    """
    def read(some):
        return con.sql(_sql(name), params={"files": [str(f) for f in some], "lo": lo, "hi": hi}).to_arrow_table()

    paths = sorted(files)
    if not paths:
        return None, {}
    try:
        return read(paths), {}
    except duckdb.Error:
        pass
    good, bad = [], {}
    for f in paths:  # which file is it? (each on its own)
        try:
            read([f])
            good.append(f)
        except duckdb.Error as exc:
            bad[f] = str(exc).splitlines()[0]
    return (read(good) if good else None), bad


@dataclass
class ImportReport:
    """What an :func:`import_features` call did, motion by motion (names are the archive's)."""

    imported: dict = field(default_factory=dict)   # archive motion id -> motion id in the database
    skipped: list = field(default_factory=list)    # (name, reason): already in the database
    repaired: list = field(default_factory=list)   # (name, reason): stored with incomplete features, replaced
    failed: list = field(default_factory=list)     # (name, reason): incomplete in the archive, not imported
    run_id: int | None = None                      # the run's rows in ingest_log

    def summary(self) -> str:
        out = f"{len(self.imported)} motion(s) imported"
        if self.repaired:
            out += f" ({len(self.repaired)} repaired)"
        return out + f", {len(self.skipped)} already present, {len(self.failed)} refused"


def import_features(con, directory, *, max_frames=BATCH_FRAMES) -> ImportReport:
    """Load an export, or an archive written by ``ray_annotate``, into the database.

    Motions not yet present (by sha256 of the file and skeleton) get new ids;
    their features are imported (and indexed, when the keyframe index exists)
    and, from a ``ray_annotate`` archive, their annotations. A motion already
    present whose stored features are incomplete (an import of a partial
    archive by an older mocapdb) is replaced.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    directory : str or Path
    max_frames : int, keyword-only
        Frames per batch: a batch of motions is read, checked and stored at a
        time, in its own transaction (memory does not grow with the archive).

    Returns
    -------
    ImportReport
        ``failed`` names every motion of the archive whose features are not
        exactly its frames 1 … n_frames (missing, partial or in an unreadable
        file, whose error is given): those are not imported, the others are,
        and importing the repaired archive again adds them.

    Raises
    ------
    ParameterError
        Not an archive, or an unfinished one (an export or a ``ray_annotate``
        run that was stopped).

    Notes
    -----
    Every motion of the archive gets its row in ``ingest_log`` under its
    source file (:mod:`mocapdb.storage.ingest_log`; an imported one in its
    batch's transaction), and so does every file of a ``ray_annotate``
    archive's ``errors`` dataset (failed); an archive refused whole gets one
    row under its folder.
    """
    log = IngestLog(con, "import-features")
    report = ImportReport(run_id=log.run_id)
    try:
        _import(con, directory, max_frames, report, log)
    except BaseException as exc:
        with contextlib.suppress(Exception):   # the import's own error, not the log's, is what to report
            if isinstance(exc, MocapdbError):
                log.add(directory, "failed", str(exc))
            log.flush()
        raise
    log.flush()
    return report


def _archive_errors(archive) -> list:
    """``(file, reason)`` of a ``ray_annotate`` archive's ``errors`` dataset (the files it could not read)."""
    out = []
    for _, _, f in _parts(archive.root / "errors") if archive.kind == "ray" else ():
        try:
            table = pq.read_table(f)
        except (OSError, pa.ArrowException) as exc:
            out.append((str(f), f"{f}: cannot read this part of the archive's errors ({exc})"))
            continue
        out.extend(zip(table.column("file").to_pylist(), table.column("reason").to_pylist()))
    return out


def _import(con, directory, max_frames, report, log) -> None:
    archive = Archive.open(directory)
    motions = archive.motions
    # names become file names (view --all, ELAN export): refuse what no ingest could give
    check_motion_names(motions.column("name").to_pylist(), source=Path(directory))
    for file, reason in _archive_errors(archive):
        log.add(file, "failed", f"ray-annotate: {reason}")
    stored = {(a, b): mid for mid, a, b in con.execute(statement("motions.sql", "stored_keys")).fetchall()}
    keys = list(zip(motions.column("sha256").to_pylist(), motions.column("skeleton_sha256").to_pylist()))
    names = motions.column("name").to_pylist()
    sources = motions.column("source_path").to_pylist()
    present = [stored[k] for k in keys if k in stored]
    broken = {mid: reason for mid, _, reason in incomplete_motions(con, present)}
    todo, replaces = [], {}
    for k, (key, name) in enumerate(zip(keys, names)):
        if key in stored and stored[key] not in broken:
            report.skipped.append((name, f"already in the database as motion {stored[key]}"))
            log.add(sources[k], "skipped", f"archive motion {name} is already in the database as motion "
                                           f"{stored[key]} ({directory})")
            continue
        if key in stored:
            replaces[k] = stored[key]
            report.repaired.append((name, broken[stored[key]]))
        todo.append(k)
    log.flush()
    todo = np.asarray(todo, dtype=np.int64)
    old_ids = motions.column("motion_id").to_numpy().astype(np.int64)
    lengths = motions.column("n_frames").to_numpy().astype(np.int64)
    for a, b in frame_batches(lengths[todo], max_frames):
        _import_batch(con, archive, todo[a:b], old_ids, lengths, names, replaces, report, log)
        log.flush()


def _import_batch(con, archive, rows_k, old_ids, lengths, names, replaces, report, log) -> None:
    """Read, check and store one batch of an archive's motions (positions ``rows_k`` of its motions table)."""
    ids = old_ids[rows_k]
    lo, hi = int(ids.min()), int(ids.max())
    order = np.argsort(ids, kind="stable")
    ids, rows_k = ids[order], rows_k[order]
    files = archive.files("features", ids)
    got, bad = _read_rows(con, "archive_features", files, lo, hi)
    cols = [np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.uint64)] if got is None else \
        [got.column(c).to_numpy() for c in ("motion_id", "frame", "bits")]
    wanted = np.isin(cols[0], ids)
    bits, complete, n_rows = check_frames(ids, lengths[rows_k], *(c[wanted] for c in cols))
    unreadable = {}
    for f, (first, last) in files.items():
        if f in bad:
            for mid in ids[(ids >= first) & (ids <= last)].tolist():
                unreadable.setdefault(mid, ("features", f"{f}: {bad[f]}"))
    ann_files = archive.files("annotations", ids)
    ann, ann_bad = _read_rows(con, "archive_annotations", ann_files, lo, hi)
    for f, (first, last) in ann_files.items():
        if f in ann_bad:
            for mid in ids[(ids >= first) & (ids <= last)].tolist():
                unreadable.setdefault(mid, ("annotations", f"{f}: {ann_bad[f]}"))
    changed = {mid: why for f, (first, last) in files.items() if f in archive.changed
               for mid in ids[(ids >= first) & (ids <= last)].tolist() for why in [archive.changed[f]]}
    ok = complete & ~np.isin(ids, list(unreadable)) & ~np.isin(ids, list(changed))
    for k, mid in enumerate(ids.tolist()):
        if not ok[k]:
            name = names[rows_k[k]]
            # an unreadable part is named by its dataset and cause (a truncated annotations part is not the
            # features'); a readable one with other bytes, by its digest
            why = (f"archive motion {mid} ({name}): {unreadable[mid][0]} unreadable: {unreadable[mid][1]}"
                   if mid in unreadable
                   else f"archive motion {mid} ({name}): features changed since the export, not imported: "
                   f"{changed[mid]}" if mid in changed
                   else incomplete_reason(mid, name, n_rows[k], lengths[rows_k[k]], what="archive motion",
                                          remedy="not imported"))
            report.failed.append((name, why))
            log.add(archive.motions.column("source_path")[int(rows_k[k])].as_py(), "failed", why)
    if not ok.any():
        return
    starts = np.concatenate(([0], np.cumsum(n_rows)))
    words = [bits[starts[k]:starts[k + 1]] for k in np.flatnonzero(ok)]
    keep_k = rows_k[ok]
    new = archive.motions.take(pa.array(keep_k)).append_column(
        "ord", pa.array(np.arange(len(keep_k), dtype=np.int32)))
    with transaction(con):
        remove_motions(con, [replaces[k] for k in keep_k.tolist() if k in replaces])
        with registered(con, mocap_new_motions=new):
            by_key = {(s, sk): mid for mid, s, sk in con.execute(_sql("import_motions")).fetchall()}
        new_ids = [by_key[k] for k in zip(new.column("sha256").to_pylist(), new.column("skeleton_sha256").to_pylist())]
        insert_features(con, new_ids, words)
        if ann is not None:
            id_map = pa.table({"old": pa.array(ids[ok], pa.int32()), "new": pa.array(new_ids, pa.int32())})
            with registered(con, mocap_id_map=id_map, mocap_archive_annotations=ann):
                con.execute(_sql("import_annotations"))
        log.insert_stored([(new.column("source_path")[i].as_py(), mid, _log_reason(archive, k, replaces),
                            _reader_notes(new.column("reader_options")[i].as_py()))
                           for i, (k, mid) in enumerate(zip(keep_k.tolist(), new_ids))])
    report.imported.update(zip(ids[ok].tolist(), new_ids))


def _log_reason(archive, k, replaces) -> str:
    """The ``ingest_log`` reason of an imported motion: where it came from, and what it replaced."""
    name = archive.motions.column("name")[k].as_py()
    mid = archive.motions.column("motion_id")[k].as_py()
    return (f"imported archive motion {mid} ({name}) from {archive.root}"
            + (f", repairing motion {replaces[k]}" if k in replaces else ""))


def _reader_notes(reader_options) -> list:
    """The reader's notes stored in a motion's ``reader_options`` (JSON, key ``notes``)."""
    try:
        notes = json.loads(reader_options).get("notes", []) if reader_options else []
    except (ValueError, AttributeError):
        return []
    return [str(n) for n in notes] if isinstance(notes, list) else []


__all__ = ["export_features", "import_features", "features_sql", "table_schemas", "ARCHIVE_TABLES", "ImportReport",
           "Archive", "MANIFEST", "EXPORT_MOTIONS", "EXPORT_DIGESTS", "file_digest", "part_digests", "write_manifest",
           "read_manifest", "archive_parts", "check_frames_per_motion", "DATASETS"]
