"""The driver of :func:`ray_annotate`: list the files, run them in batches on Ray
actors, check what they wrote.

* The file list (sources in the order given, folders sorted as ``ingest``
  walks them) gives motion ids: file ``k`` is motion ``k`` — deterministic,
  so a batch run again computes the same rows.
* A Ray Data pipeline sends batches of ``batch_files`` files to one
  :class:`~mocapdb.distributed.worker.MotionWorker` actor per CPU, which
  fingerprints, reads, computes features, postings and annotations and writes
  them as Parquet parts named after the batch's motion ids
  (:mod:`mocapdb.distributed.layout`).
* Ray restarts an actor that died and runs its batch again; the batch rewrites
  the same parts. At the end the driver keeps exactly the parts the batches
  reported, so every motion's rows are in the archive once; and it drops the
  rows of files with the same bytes as an earlier file (by sha256 of the file
  and its skeleton, as ``ingest``: stored once), rewriting those parts.
"""
from __future__ import annotations

import contextlib
import glob
import logging
import math
import os
import re
import socket
import warnings
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from mocapdb.distributed.layout import (ERRORS_SCHEMA, finish_output, part_name, part_path, prepare_output,
                                        write_part)
from mocapdb.distributed.worker import MotionWorker
from mocapdb.errors import MocapdbError, ParameterError, check_nonnegative
from mocapdb.readers import MOTION_SUFFIXES, ReaderOptions, companion_kind, motion_files
from mocapdb.storage.ingest import IngestReport
from mocapdb.storage.model_store import DEFAULT_MODEL, load_model
from mocapdb.storage.parquet import archive_parts, part_digests, table_schemas, write_manifest
from mocapdb.storage.schema import open_database

log = logging.getLogger("mocapdb")

#: how to get Ray
RAY_EXTRA = "pip install 'mocapdb[ray]'"
#: object store of a local Ray started here: the pipeline streams batches of a
#: few MB, and the machine's memory belongs to the workers
LOCAL_OBJECT_STORE = 256 * 2**20
#: times a batch is run again after its actor died; a file that kills its
#: process every time then fails the run instead of looping forever
TASK_RETRIES = 3
#: CPUs of each actor (one actor per CPU: files are independent)
ACTOR_CPUS = 1
#: files per batch (one batch = one task = one part per dataset)
BATCH_FILES = 64
#: motions per bucket of the partitioned datasets
BUCKET_MOTIONS = 1000

_GLOB = re.compile(r"[*?\[]")


class MissingExtraError(MocapdbError, ImportError):
    """An optional dependency is not installed; the message says which extra brings it."""


def require_ray():
    """The ``ray`` module, with Ray Data.

    Raises
    ------
    MissingExtraError
        If Ray is not installed (``pip install 'mocapdb[ray]'``).
    """
    try:
        import ray
        import ray.data  # noqa: F401  (the pipeline runs on Ray Data)
    except ImportError:
        raise MissingExtraError(f"ray_annotate needs Ray, which is not installed: {RAY_EXTRA}") from None
    return ray


@dataclass
class RayReport(IngestReport):
    """What a :func:`ray_annotate` run did: :class:`~mocapdb.storage.ingest.IngestReport`
    (``failed`` = the rows of the ``errors`` dataset) plus the segments written."""

    segments: int = 0
    out: str = ""

    def summary(self) -> str:
        out = (f"{len(self.ingested)} motions, {self.segments} segments written to {self.out} "
               f"({len(self.skipped)} skipped, {len(self.failed)} failed")
        return out + (f", {len(self.unsupported)} not motion files)" if self.unsupported else ")")


def expand_sources(sources, *, unsupported=None, refused=None, hidden=None, unreadable=None) -> list[Path]:
    """Files, folders (recursively) and glob patterns → the motion files, as absolute paths.

    Folders are walked as by ``ingest`` (:func:`mocapdb.readers.motion_files`);
    a pattern (``*``, ``?``, ``[…]``, ``**`` for any depth) adds its matching
    folders and motion files. A file listed twice counts once. ``unsupported``,
    ``refused`` (zip members never read: names that leave their archive,
    earlier copies of a member named twice), ``hidden`` and ``unreadable``
    receive ``(path, reason)`` as with ``motion_files``, so a run accounts for
    every file ``ingest`` would.

    Raises
    ------
    ParameterError
        If a path does not exist, a pattern matches nothing, or no motion file is found.
    """
    paths = []
    for s in sources:
        if not Path(s).exists() and _GLOB.search(str(s)):
            hits = [Path(h) for h in sorted(glob.glob(str(s), recursive=True))]
            hits = [h for h in hits if h.is_dir() or (h.suffix.lower() in MOTION_SUFFIXES and companion_kind(h) is None)]
            if not hits:
                raise ParameterError(f"sources: the pattern {str(s)!r} matches no motion file or folder")
            paths.extend(hits)
        else:
            paths.append(Path(s))
    # absolute, symlinks kept: the paths `ingest` stores for the same files
    files = list(dict.fromkeys(Path(os.path.abspath(p)) for p in motion_files(paths, unsupported=unsupported,
                                                                                         refused=refused, hidden=hidden,
                                                                                         unreadable=unreadable)))
    if not files:
        raise ParameterError(f"sources: no motion files ({', '.join(MOTION_SUFFIXES)}) in {[str(s) for s in sources]}")
    return files


@contextlib.contextmanager
def ray_session(ray, *, address=None, num_cpus=None):
    """Use the Ray this process is connected to, or connect to ``address``, or start a local Ray.

    A local Ray gets ``num_cpus`` CPUs (default: all cores), no dashboard and a
    small object store; usage statistics stay off unless the environment
    says otherwise. A session started here is shut down at the end.

    Yields
    ------
    int
        The CPUs of the cluster.
    """
    started = not ray.is_initialized()
    if started:
        quiet = {"logging_level": logging.WARNING, "log_to_driver": False}
        if address is not None:
            _check_reachable(address)
            try:
                ray.init(address=address, **quiet)
            except (ConnectionError, ray.exceptions.AuthenticationError) as exc:
                raise MocapdbError(_cannot_connect(address, exc)) from None
        else:
            # Ray would otherwise try to send usage statistics (no network here, or not wanted)
            os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
            ray.init(num_cpus=int(num_cpus or os.cpu_count() or 1), include_dashboard=False,
                     object_store_memory=LOCAL_OBJECT_STORE, **quiet)
    try:
        yield max(1, int(ray.cluster_resources().get("CPU", 1)))
    finally:
        if started:
            ray.shutdown()


#: what a client of a cluster with token authentication needs (Ray ≥ 2.52; docs/CLUSTER.md "Archives larger than one machine")
TOKEN_AUTH = ("a cluster started with token authentication (RAY_AUTH_MODE=token) needs it here too: "
              "RAY_AUTH_MODE=token and its token in RAY_AUTH_TOKEN_PATH=FILE (or RAY_AUTH_TOKEN, or ~/.ray/auth_token)")


#: seconds to wait for a cluster's address to answer before Ray is asked to connect (Ray itself retries
#: an address nobody answers at for minutes)
CONNECT_TIMEOUT = 5.0


def _check_reachable(address) -> None:
    """Refuse at once a ``host:port`` (or ``ray://host:port``) that no host answers at: a name that does
    not resolve, a port nothing listens on, or no answer within :data:`CONNECT_TIMEOUT` seconds. Other
    forms (``auto``, ``local``) are Ray's to resolve.

    Raises
    ------
    MocapdbError
    """
    text = str(address)
    hostport = text.split("://", 1)[1] if "://" in text else text
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit():
        return
    host = host.strip("[]")   # an IPv6 address in brackets
    try:
        with socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT):
            pass
    except socket.gaierror as exc:
        raise MocapdbError(f"cannot connect to the Ray cluster at {address}: no such host {host!r} "
                           f"({exc.strerror or exc})") from None
    except (OSError, ValueError, OverflowError) as exc:
        why = "no answer within {:g} s".format(CONNECT_TIMEOUT) if isinstance(exc, TimeoutError) else \
            (getattr(exc, "strerror", None) or str(exc))
        raise MocapdbError(f"cannot connect to the Ray cluster at {address}: {why} (is the cluster's head "
                           "running, and the address its GCS address, e.g. HOST:6379?)") from None


def _cannot_connect(address, exc) -> str:
    """Why ``ray.init(address=…)`` failed, with what token authentication needs when it is not set up."""
    text = f"cannot connect to the Ray cluster at {address}"
    if os.environ.get("RAY_AUTH_MODE", "").lower() != "token":
        text += f"; {TOKEN_AUTH}"
    return text + f" (Ray: {str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__})"


@contextlib.contextmanager
def _quiet_data(ray):
    """Ray Data without its progress bars and INFO lines (the library never prints)."""
    ctx = ray.data.DataContext.get_current()
    bars, logger = ctx.enable_progress_bars, logging.getLogger("ray.data")
    level = logger.level
    ctx.enable_progress_bars = False
    logger.setLevel(logging.WARNING)
    try:
        yield
    finally:
        ctx.enable_progress_bars = bars
        logger.setLevel(level)


def _model(name, database):
    """The model ``name`` from ``database`` (read-only), or a shipped model."""
    if database is not None and not Path(database).is_file():
        raise ParameterError(f"database: {str(database)!r} does not exist (it is read for the model {name!r}; "
                             "leave --db out to use a shipped model)")
    con = open_database(database, read_only=True) if database is not None else open_database(":memory:")
    try:
        return load_model(con, name)
    finally:
        con.close()


def _check(tau, num_cpus, batch_files, bucket_motions):
    check_nonnegative(tau, "tau", none="each class's τ")
    if num_cpus is not None and not (isinstance(num_cpus, int) and num_cpus >= 1):
        raise ParameterError(f"num_cpus must be a positive integer (--num-cpus), got {num_cpus!r}")
    for name, v in (("batch_files", batch_files), ("bucket_motions", bucket_motions)):
        if not (isinstance(v, int) and v >= 1):
            raise ParameterError(f"{name} must be a positive integer (--{name.replace('_', '-')}), got {v!r}")


def ray_annotate(sources, out, *, address=None, model=DEFAULT_MODEL, tau=None, keyframes=None, database=None,
                 options=None, num_cpus=None, batch_files=BATCH_FILES, bucket_motions=BUCKET_MOTIONS,
                 overwrite=False, worker=MotionWorker) -> RayReport:
    """Read, compute features, index and annotate recordings on a Ray cluster; write Parquet.

    The single-machine pipeline (``ingest`` then ``annotate``) on Ray Data: the
    same readers, kernels and model, the same rows, written as the Parquet
    datasets ``motions``, ``features``, ``postings``, ``annotations`` (the
    columns of the DuckDB tables) and ``errors`` (file, reason) under ``out``
    (layout: :mod:`mocapdb.distributed.layout`).

    Parameters
    ----------
    sources : iterable of str or Path
        Files, folders (recursively) or glob patterns, on a filesystem every
        node sees at the same path.
    out : str or Path
        Archive folder (shared by every node); empty or absent unless ``overwrite``.
    address : str, optional, keyword-only
        Ray cluster to run on (``ray.init(address=…)``, e.g. ``"auto"`` or
        ``"ray://head:10001"``). Default: the Ray this process is connected
        to, else a local Ray started for the run.
    model : str, keyword-only, default "default"
        A shipped model, or one stored in ``database``.
    tau : float, optional, keyword-only
        Hit threshold for every class (default: each class's τ).
    keyframes : bool, optional, keyword-only
        Keyframe preselection (default: when the model has keyframe queries),
        as ``mocapdb.api.annotate``.
    database : str or Path, optional, keyword-only
        A mocap database to read the model from (opened read-only).
    options : ReaderOptions, optional, keyword-only
        How files are read (:class:`mocapdb.readers.ReaderOptions`), as by
        ``ingest``: the same value reaches every worker, so a file reads as
        ``ingest`` reads it (joint and marker maps, marker rules included).
    num_cpus : int, optional, keyword-only
        CPUs of a local Ray (default: all cores).
    batch_files : int, keyword-only, default 64
        Files per batch: the unit of work, of retry and of the Parquet parts.
    bucket_motions : int, keyword-only, default 1000
        Motions per ``motion_bucket`` partition.
    overwrite : bool, keyword-only
        Replace an archive already in ``out``.
    worker : class, keyword-only
        The actor class (default :class:`~mocapdb.distributed.worker.MotionWorker`;
        a subclass can add outputs).

    Returns
    -------
    RayReport
        Motions written (with ids), files skipped (same bytes as an earlier
        one) and failed (the ``errors`` dataset), segments written.

    Raises
    ------
    MissingExtraError
        Ray is not installed.
    ParameterError
        Bad parameters, or sources that name no motion file.
    """
    _check(tau, num_cpus, batch_files, bucket_motions)
    ray = require_ray()
    report = RayReport()
    # what the walk refuses is failed (a row of the errors dataset, as ingest logs it), a hidden file skipped
    walk_refused = []
    files = expand_sources(sources, unsupported=report.unsupported, refused=walk_refused, hidden=report.skipped,
                           unreadable=report.unreadable)
    options = options or ReaderOptions()   # its paths are absolute: workers have their own working directory
    the_model = _model(model, database)
    schemas = {**table_schemas(), "errors": ERRORS_SCHEMA}
    out = prepare_output(out, overwrite=overwrite)
    stamp = datetime.now().replace(microsecond=0)  # one ingested_at / annotated_at for the run
    report.out = str(out)
    init = {"model_name": model, "tau": tau, "keyframes": keyframes, "out": str(out), "schemas": schemas,
            "stamp": stamp, "bucket_motions": bucket_motions, "options": options, "threads": ACTOR_CPUS}
    with ray_session(ray, address=address, num_cpus=num_cpus) as cpus, _quiet_data(ray):
        log.info("ray_annotate: %d files on %d CPUs", len(files), cpus)
        rows = _compute(ray, worker, {"model": ray.put(the_model), **init}, files, cpus, batch_files)
    rows.sort(key=lambda r: r["motion_id"])
    _check_once(rows)
    parts = sorted({p for r in rows for p in r["parts"]})
    if walk_refused:  # a part of their own, motions 0-0: they have no motion id (ids start at 1)
        parts.append(part_path("errors", part_name(0, 0)))
        write_part(out, parts[-1], pa.table({"file": [str(f) for f, _ in walk_refused],
                                             "reason": [r for _, r in walk_refused]}, schema=ERRORS_SCHEMA))
        report.failed.extend(walk_refused)
    _drop_duplicates(out, rows, parts, schemas, report)
    for r in rows:
        if r["n_frames"] is not None:
            report.ingested.append((r["file"], r["motion_id"], r["n_frames"]))
            report.source_frames += r["n_source_frames"]
            report.segments += r["n_segments"]
        if r["error"] is not None:
            report.failed.append((r["file"], r["error"]))
    finish_output(out, parts, schemas)
    # last: the archive is finished (import-features refuses an archive without it)
    write_manifest(out, {"format": "mocapdb ray-annotate archive", "mocapdb": _version(), "started_at": stamp,
                         "finished_at": datetime.now().replace(microsecond=0), "model": model, "tau": tau,
                         "keyframes": keyframes, "files": len(files), "motions": len(report.ingested),
                         "failed": len(report.failed), "skipped": len(report.skipped),
                         "source_frames": report.source_frames, "segments": report.segments,
                         "batch_files": batch_files, "bucket_motions": bucket_motions,
                         # every part, its rows and its bytes' SHA-256: attach and import check the archive
                         # against them (rows rewritten in place keep their count, not their digest)
                         "parts": (found := archive_parts(out)), "digests": part_digests(out, found)})
    log.info("ray_annotate: %s", report.summary())
    return report


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mocapdb")
    except PackageNotFoundError:  # a source checkout
        return "unknown"


def _compute(ray, worker, init, files, cpus, batch_files) -> list:
    """The batches on one actor per CPU; returns the summary rows
    (:data:`~mocapdb.distributed.worker.SUMMARY_SCHEMA`)."""
    items = [{"motion_id": k + 1, "path": str(path)} for k, path in enumerate(files)]
    n_blocks = math.ceil(len(items) / batch_files)
    ds = ray.data.from_items(items, override_num_blocks=n_blocks)
    with warnings.catch_warnings():
        # Ray 2.60 deprecates **ray_remote_args but offers no other way to bound retries
        warnings.filterwarnings("ignore", message=".*ray_remote_args.*")
        ds = ds.map_batches(
            worker, fn_constructor_kwargs=init, batch_size=None, batch_format="pyarrow", num_cpus=ACTOR_CPUS,
            compute=ray.data.ActorPoolStrategy(size=max(1, min(cpus // ACTOR_CPUS, n_blocks))),
            max_restarts=-1, max_task_retries=TASK_RETRIES)
    return ds.take_all()


def _check_once(rows) -> None:
    """Every motion reported by exactly one batch (a batch counted twice: never expected)."""
    ids = [r["motion_id"] for r in rows]
    if len(set(ids)) != len(ids):
        twice = sorted({i for i in ids if ids.count(i) > 1})
        raise MocapdbError(f"internal error: motions {twice} were reported by two Ray batches")


def _drop_duplicates(out, rows, parts, schemas, report) -> None:
    """Remove the rows of files whose bytes (and skeleton's) equal an earlier file's.

    The earliest file keeps its motion, as with ``ingest``; the others are
    reported as skipped and their rows are filtered out of their batches' parts.
    """
    first, dropped = {}, {}
    for r in rows:
        if r["n_frames"] is None:
            continue
        key = (r["sha256"], r["skeleton_sha256"])
        if key in first:
            report.skipped.append((r["file"], f"same bytes as {first[key]} of this run"))
            dropped[r["motion_id"]] = r
        else:
            first[key] = r["file"]
    if not dropped:
        return
    gone = pa.array(sorted(dropped), pa.int32())
    for rel in sorted({p for r in dropped.values() for p in r["parts"]}):
        dataset = rel.split("/", 1)[0]
        if "motion_id" not in schemas[dataset].names:
            continue
        table = pq.read_table(out / rel, schema=schemas[dataset])
        write_part(out, rel, table.filter(pc.invert(pc.is_in(table.column("motion_id"), gone))))
    for r in dropped.values():
        r["n_frames"] = None  # not written: neither ingested nor failed


__all__ = ["ray_annotate", "expand_sources", "require_ray", "ray_session", "RayReport", "MissingExtraError",
           "RAY_EXTRA", "BATCH_FILES", "BUCKET_MOTIONS", "TASK_RETRIES", "LOCAL_OBJECT_STORE"]
