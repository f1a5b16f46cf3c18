"""What runs on the Ray workers: the actor that turns a batch of files into the rows
of the archive.

It calls the single-machine code — :func:`mocapdb.storage.ingest_read.prepare_file`,
:func:`~mocapdb.storage.ingest_read.compute_motion` and
:func:`~mocapdb.storage.ingest.motions_table` for reading and features,
:func:`mocapdb.storage.postings.postings_table` for the index,
:func:`mocapdb.annotation.annotate` (with
:func:`~mocapdb.annotation.preselection_for`) and
:func:`~mocapdb.annotation.segment_table` for the segments — so the rows are
those that ``ingest`` and ``annotate`` store in DuckDB. Ray itself is only
touched to fetch the model from the object store.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pyarrow as pa

from mocapdb._numba import limit_threads
from mocapdb.annotation import SEGMENT_DTYPE, Model, annotate, preselection_for, segment_table
from mocapdb.distributed.layout import (DATASETS, ERRORS_SCHEMA, PARTITIONED, bucket_of, part_name, part_path,
                                        write_part)
from mocapdb.errors import MocapdbError
from mocapdb.readers.sources import as_path
from mocapdb.storage.ingest import motions_table
from mocapdb.storage.ingest_read import compute_motion, prepare_file, read_once
from mocapdb.storage.postings import postings_table

#: what :class:`MotionWorker` returns: one row per file of the batch
SUMMARY_SCHEMA = pa.schema([("motion_id", pa.int32()), ("file", pa.string()), ("sha256", pa.string()),
                            ("skeleton_sha256", pa.string()), ("n_source_frames", pa.int64()),
                            ("n_frames", pa.int64()), ("n_segments", pa.int64()), ("error", pa.string()),
                            ("parts", pa.list_(pa.string()))])


class Computed(NamedTuple):
    """A file read and computed in a batch: what the datasets need of it."""

    row: pa.Table          # its motions row (mocapdb.storage.ingest.motions_table)
    words: np.ndarray      # (n_frames,) uint64, the 30 Hz feature words
    path: str


def _reason(exc: Exception, path: str) -> str:
    """A one-line reason naming the file (reader errors already do)."""
    if isinstance(exc, OSError):
        return f"{path}: {exc.strerror or exc}"
    text = str(exc)
    return text if text.startswith(path) else f"{path}: {text}"


class MotionWorker:
    """Ray Data actor: a batch of files → ``motions``, ``features``, ``postings``,
    ``annotations`` and ``errors`` parts of the archive.

    One actor per CPU lives for the whole run, so the numba kernels compile
    (or load from the cache) once per process, and the model arrives once:
    the driver puts it in the object store and each actor fetches it here.

    Parameters
    ----------
    model : mocapdb.annotation.Model or ray.ObjectRef
    model_name : str
        Stored in ``annotations.model``.
    tau : float or None
        As ``mocapdb.api.annotate`` (None: each class's τ).
    keyframes : bool or None
        Keyframe preselection, on an in-memory index of the batch's motions
        (None: when the model has keyframe queries).
    out : str
        The archive folder (shared by every node).
    schemas : dict of str to pyarrow.Schema
        The schema of each dataset (:func:`mocapdb.storage.parquet.table_schemas`).
    stamp : datetime.datetime
        ``motions.ingested_at`` and ``annotations.annotated_at`` of the run (one
        value, so a retried batch writes identical rows).
    bucket_motions : int
        Motions per bucket of the partitioned datasets.
    options : ReaderOptions, optional
        How files are read, as :func:`mocapdb.storage.ingest_read.prepare_file`
        (:class:`mocapdb.readers.ReaderOptions`; the driver's value, as ``ingest`` has it).
    threads : int
        Threads of the parallel kernels: the actor's CPUs (the actors already
        use every CPU of the cluster).
    """

    def __init__(self, *, model, model_name, tau, keyframes, out, schemas, stamp, bucket_motions, options=None,
                 threads=1):
        if not isinstance(model, Model):
            import ray  # the model was put in the object store once by the driver

            model = ray.get(model)
        self.model = model
        self.threads = int(threads)
        self.model_name = model_name
        self.tau = tau
        self.keyframes = keyframes
        self.out = out
        self.schemas = schemas
        self.stamp = stamp
        self.bucket_motions = int(bucket_motions)
        self.options = options

    def __call__(self, batch: pa.Table) -> pa.Table:
        """Compute and write one batch (columns ``motion_id``, ``path``); returns
        :data:`SUMMARY_SCHEMA` rows, each with the parts the batch wrote."""
        limit_threads(self.threads)  # per thread, and Ray calls from another thread than __init__'s
        ids = np.asarray(batch.column("motion_id").to_numpy(), dtype=np.int64)
        paths = batch.column("path").to_pylist()
        done, errors = self.compute(ids, paths)
        tables = self.tables(done)
        tables["annotations"], failed = self.annotate(tables["motions"], list(done.values()))
        errors.update(failed)
        tables["errors"] = pa.table({"file": [errors[i][0] for i in sorted(errors)],
                                     "reason": [errors[i][1] for i in sorted(errors)]}, schema=ERRORS_SCHEMA)
        parts = self.write(ids, tables)
        return self.summary(ids, paths, tables["motions"], errors, tables["annotations"], parts)

    # -- the steps ------------------------------------------------------------------

    def compute(self, ids, paths):
        """Fingerprint, read and compute every file, as ingest does.

        Returns
        -------
        done : dict
            motion id → :class:`Computed` (its ``motions`` row and words), in batch order.
        errors : dict
            motion id → (file, reason) of the files that did not read.
        """
        done, errors = {}, {}
        for mid, path in zip(ids.tolist(), paths):
            try:
                file = as_path(path)
                with read_once(file):        # hashed and parsed from one read, as ingest's pool does
                    prep = prepare_file(file, self.options)
                    compute_motion(prep)
                if prep.error is not None:
                    raise MocapdbError(prep.error)
                # the row (ingest's checks included) and the words; the joints go now
                done[mid] = Computed(motions_table([prep]), prep.words, str(prep.path))
            except (MocapdbError, OSError) as exc:
                errors[mid] = (path, _reason(exc, path))
        return done, errors

    def tables(self, done: dict) -> dict:
        """``motions``, ``features`` and ``postings`` rows of the computed files, in the datasets' schemas."""
        ids = np.fromiter(done, dtype=np.int32, count=len(done))
        files = list(done.values())
        motions = pa.concat_tables([f.row for f in files]) if files else motions_table([])
        motions = motions.add_column(0, "motion_id", pa.array(ids, pa.int32()))
        motions = motions.append_column("ingested_at", pa.array([self.stamp] * len(ids), pa.timestamp("us")))
        counts = np.array([f.words.shape[0] for f in files], dtype=np.int64)
        features = pa.table({
            "motion_id": pa.array(np.repeat(ids, counts), pa.int32()),
            "frame": pa.array(np.concatenate([np.arange(1, c + 1, dtype=np.int32) for c in counts] or
                                             [np.zeros(0, np.int32)]), pa.int32()),
            "bits": pa.array(np.concatenate([f.words for f in files] or [np.zeros(0, np.uint64)]), pa.uint64()),
        })
        postings = postings_table({int(i): f.words for i, f in zip(ids, files)})
        return {name: self.conform(name, t) for name, t in
                (("motions", motions), ("features", features), ("postings", postings))}

    def conform(self, dataset: str, table: pa.Table) -> pa.Table:
        """``table`` with exactly the columns and types of the dataset."""
        schema = self.schemas[dataset]
        return table.select(schema.names).cast(schema)

    def annotate(self, motions: pa.Table, ordered: list):
        """``annotations`` rows of the batch's motions, and ``{motion_id: (file, reason)}``
        of motions whose annotation failed (their features are kept, as after ``ingest``)."""
        ids = motions.column("motion_id").to_numpy()
        names = motions.column("name").to_pylist()
        fps = motions.column("fps").to_numpy()
        try:
            return self._annotate(ids, names, fps, [p.words for p in ordered]), {}
        except MocapdbError:
            # one motion's failure (e.g. too many hits) must not cost the batch: one at a time
            tables, failed = [self._annotate(ids[:0], [], fps[:0], [])], {}
            for k, p in enumerate(ordered):
                try:
                    tables.append(self._annotate(ids[k:k + 1], names[k:k + 1], fps[k:k + 1], [p.words]))
                except MocapdbError as exc:
                    failed[int(ids[k])] = (str(p.path), f"{p.path}: annotation failed: {exc}")
            return pa.concat_tables(tables), failed

    def _annotate(self, ids, names, fps, words) -> pa.Table:
        if words:
            lengths = np.array([len(w) for w in words], dtype=np.int64)
            flat = np.concatenate(words).astype(np.uint64, copy=False)
            pre = preselection_for(flat, lengths, self.model, self.keyframes)
            segs = annotate(flat, self.model, doc_lengths=lengths, preselection=pre, tau=self.tau,
                            keep_hits=False).segments
        else:
            segs = np.zeros(0, SEGMENT_DTYPE)
        table = segment_table(segs, motion_ids=ids, names=names, fps=fps)
        n = table.num_rows
        # what mocapdb.api.annotate stores beside the segments (sql/annotations.sql)
        table = (table.append_column("model", pa.array([self.model_name] * n, pa.string()))
                 .append_column("tau", pa.array([self.tau] * n, pa.float64()))
                 .append_column("keyframes", pa.array([self.keyframes] * n, pa.bool_()))
                 .append_column("annotated_at", pa.array([self.stamp] * n, pa.timestamp("us"))))
        return self.conform("annotations", table)

    def write(self, ids, tables: dict) -> list[str]:
        """Write the batch's non-empty parts; returns their paths relative to the archive."""
        parts = []
        for dataset in DATASETS:
            table = tables[dataset]
            if table.num_rows == 0:
                continue
            if dataset in PARTITIONED:
                rows_bucket = bucket_of(table.column("motion_id").to_numpy(), self.bucket_motions)
                batch_bucket = bucket_of(ids, self.bucket_motions)
                for b in np.unique(rows_bucket):
                    mine = ids[batch_bucket == b]
                    rel = part_path(dataset, part_name(mine.min(), mine.max()), b)
                    self.write_part(rel, table.filter(pa.array(rows_bucket == b)))
                    parts.append(rel)
            else:
                rel = part_path(dataset, part_name(ids.min(), ids.max()))
                self.write_part(rel, table)
                parts.append(rel)
        return parts

    def write_part(self, relative: str, table: pa.Table) -> None:
        """Write one part (atomically; the same name on a retry)."""
        write_part(self.out, relative, table)

    def summary(self, ids, paths, motions, errors, annotations, parts) -> pa.Table:
        """One row per file of the batch (:data:`SUMMARY_SCHEMA`)."""
        segs = dict(zip(*np.unique(annotations.column("motion_id").to_numpy(), return_counts=True)))
        rows = {r["motion_id"]: r for r in
                motions.select(["motion_id", "sha256", "skeleton_sha256", "n_source_frames", "n_frames"]).to_pylist()}
        out = []
        for mid, path in zip(ids.tolist(), paths):
            r = rows.get(mid, {})
            out.append({"motion_id": mid, "file": path, "sha256": r.get("sha256"),
                        "skeleton_sha256": r.get("skeleton_sha256"), "n_source_frames": r.get("n_source_frames"),
                        "n_frames": r.get("n_frames"), "n_segments": int(segs.get(mid, 0)),
                        "error": errors.get(mid, (None, None))[1], "parts": parts})
        return pa.Table.from_pylist(out, schema=SUMMARY_SCHEMA)


__all__ = ["MotionWorker", "Computed", "SUMMARY_SCHEMA"]
