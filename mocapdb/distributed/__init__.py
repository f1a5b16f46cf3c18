"""The pipeline on a Ray cluster, for archives that outgrow one machine (the ``ray`` extra).

:func:`ray_annotate` reads recordings of every supported format, computes
their features, postings and annotations on Ray Data actors with the same
readers, kernels and model as ``ingest`` + ``annotate``, and writes Parquet
datasets with the columns of the DuckDB tables
(:mod:`~mocapdb.distributed.layout`), which DuckDB queries in place and
``mocapdb import-features`` loads into a database.

Ray is imported only when a run starts, so the base install works without it.
"""
from mocapdb.distributed.layout import BUCKET_COLUMN, DATASETS, ERRORS_SCHEMA, PARTITIONED
from mocapdb.distributed.pipeline import (BATCH_FILES, BUCKET_MOTIONS, RAY_EXTRA, MissingExtraError, RayReport,
                                          expand_sources, ray_annotate, ray_session, require_ray)
from mocapdb.distributed.worker import MotionWorker

__all__ = ["ray_annotate", "expand_sources", "ray_session", "require_ray", "RayReport", "MissingExtraError",
           "MotionWorker", "DATASETS", "PARTITIONED", "BUCKET_COLUMN", "ERRORS_SCHEMA",
           "RAY_EXTRA", "BATCH_FILES", "BUCKET_MOTIONS"]
