"""The Parquet layout of an archive written on a Ray cluster, and writing it safely.

::

    OUT/motions/part-<first>-<last>.parquet                   the motions table
    OUT/features/motion_bucket=<k>/part-<first>-<last>.parquet the features table
    OUT/postings/motion_bucket=<k>/part-<first>-<last>.parquet mocap_index.postings
    OUT/annotations/motion_bucket=<k>/part-<first>-<last>.parquet the annotations table
    OUT/errors/part-<first>-<last>.parquet                    file, reason
    OUT/manifest.json                                         written last: the run finished

Every part holds the rows of one batch of files, ``<first>``–``<last>`` being
the batch's motion ids (zero-padded), so its name depends only on its rows: a
batch computed again after a worker died overwrites its own parts. A part is
written under a temporary name and renamed, so a reader never sees half a
file. Bucket ``k`` holds motions ``k·B + 1 … (k + 1)·B`` (``B`` =
``bucket_motions``): DuckDB prunes buckets on ``motion_bucket`` (hive
partitioning) and parts on their ``motion_id`` statistics. The driver writes
``manifest.json`` (:data:`mocapdb.storage.parquet.MANIFEST`) once every batch
is written and checked: an archive without it is unfinished (a run that was
stopped), and ``import-features`` refuses it.
"""
from __future__ import annotations

import os
import shutil
import uuid
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mocapdb.errors import ParameterError
from mocapdb.storage.parquet import MANIFEST

#: the datasets of an archive, in the order a batch writes them
DATASETS = ("features", "postings", "annotations", "errors", "motions")
#: datasets split into motion-id buckets (hive partitioning)
PARTITIONED = ("features", "postings", "annotations")
#: name of the hive partition column
BUCKET_COLUMN = "motion_bucket"
#: files that could not be read, and why (a dataset of its own, no DuckDB table)
ERRORS_SCHEMA = pa.schema([("file", pa.string()), ("reason", pa.string())])


def bucket_of(motion_ids, bucket_motions: int) -> np.ndarray:
    """The bucket of each motion id (ids are 1-based)."""
    return (np.asarray(motion_ids, dtype=np.int64) - 1) // int(bucket_motions)


def part_name(first: int, last: int) -> str:
    """File name of the part holding motions ``first`` … ``last``."""
    return f"part-{int(first):09d}-{int(last):09d}.parquet"


def part_path(dataset: str, name: str, bucket=None) -> str:
    """Path of a part relative to the archive folder (``/``-separated)."""
    if dataset in PARTITIONED:
        return f"{dataset}/{BUCKET_COLUMN}={int(bucket)}/{name}"
    return f"{dataset}/{name}"


def write_part(out, relative: str, table: pa.Table) -> None:
    """Write a part atomically: a temporary file beside it, then a rename.

    A retried batch writes the same name; the rename replaces the earlier
    attempt's file as a whole. Temporary names start with a dot, which
    DuckDB's ``*.parquet`` globs and Arrow datasets skip.
    """
    path = Path(out) / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)


def prepare_output(out, *, overwrite: bool = False) -> Path:
    """Create the archive folder; it must be empty or absent unless ``overwrite``.

    With ``overwrite`` the datasets of an earlier archive are removed (and
    nothing else in the folder).
    """
    d = Path(out)
    if d.exists() and not d.is_dir():
        raise ParameterError(f"out: {str(d)!r} is a file; give a folder")
    if d.exists() and any(d.iterdir()):
        if not overwrite:
            what = ("holds an unfinished archive (no manifest.json: its run was stopped before the end)"
                    if (d / "motions").is_dir() and not (d / MANIFEST).exists() else "is not empty")
            raise ParameterError(f"out: {str(d)!r} {what}; pass overwrite=True (--overwrite) to replace "
                                 "the archive in it")
        # the manifest first: a run stopped while replacing the archive leaves an unfinished one
        (d / MANIFEST).unlink(missing_ok=True)
        for name in DATASETS:
            shutil.rmtree(d / name, ignore_errors=True)
    d.mkdir(parents=True, exist_ok=True)
    return d.resolve()


def finish_output(out, parts, schemas: dict) -> None:
    """Make the folder hold exactly the reported parts, and every dataset at least one file.

    Parameters
    ----------
    out : Path
    parts : iterable of str
        Relative paths of the parts the successful batches reported.
    schemas : dict of str to pyarrow.Schema
        The schema of each dataset.

    Notes
    -----
    A worker that died left at most temporary files and parts that its
    retried batch rewrote under the same names; anything not reported (a
    temporary file, a part of an attempt that never finished) is removed, so
    every motion's rows are in exactly one part. A dataset without rows gets
    one empty part, so that queries over it find a file.
    """
    out = Path(out)
    keep = {Path(p) for p in parts}
    for dataset in DATASETS:
        root = out / dataset
        found = False
        for f in sorted(root.rglob("*")) if root.is_dir() else ():
            if f.is_file():
                if f.relative_to(out) in keep:
                    found = True
                else:
                    f.unlink()
        if not found:
            write_part(out, part_path(dataset, "part-empty.parquet", 0), schemas[dataset].empty_table())


__all__ = ["DATASETS", "PARTITIONED", "BUCKET_COLUMN", "ERRORS_SCHEMA", "bucket_of", "part_name",
           "part_path", "write_part", "prepare_output", "finish_output"]
