"""Crash consistency: kill a mocapdb command at a random moment, reopen the database, check its invariants.

Each trial copies a prepared database, runs one command as a real process
(``python -m mocapdb.cli``, the same as a user's), sends SIGKILL to it and to
every process it started (Ray's too) after a seeded random delay, and then
opens the database again with :func:`mocapdb.connect` and checks
:func:`invariants`. The delay counts from the moment the command began to
write (see :data:`WINDOWS`), so that kills land in its work rather than in
Python's start-up. ``ray-annotate`` writes an archive, not the database:
after its kill the partial archive is imported into a copy of the database
(as a user would), and that database is checked.

Used by ``tests/test_crash.py`` (a few trials per command) and
``benchmarks/bench_crash.py`` (``--trials N``, figures: trials / consistent).
"""
from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import mocapdb

#: the commands killed, and the window (seconds) the kill falls in after the command began to
#: write (its database's write-ahead log, or ray-annotate's archive folder, appeared); a kill
#: after the end is a completed run, checked too
WINDOWS = {"ingest": 5.0, "annotate": 5.0, "import-features": 4.0, "ray-annotate": 30.0}

INVARIANTS = {
    "feature rows equal n_frames, frames 1…n": """
        SELECT m.motion_id FROM motions m LEFT JOIN (
            SELECT motion_id, count(*) AS n, count(DISTINCT frame) AS d, min(frame) AS lo, max(frame) AS hi
            FROM features GROUP BY motion_id) f USING (motion_id)
        WHERE f.n IS NULL OR f.n <> m.n_frames OR f.d <> m.n_frames OR f.lo <> 1 OR f.hi <> m.n_frames""",
    "no features of a missing motion": """
        SELECT DISTINCT motion_id FROM features WHERE motion_id NOT IN (SELECT motion_id FROM motions)""",
    "postings cover every motion (each feature set, frames 1…n)": """
        SELECT m.motion_id FROM motions m CROSS JOIN (VALUES ('upper'), ('lower'), ('mix'), ('full')) s(feature_set)
        LEFT JOIN (SELECT motion_id, feature_set, sum(n_frames) AS n, min(start_frame) AS lo
                   FROM mocap_index.postings GROUP BY ALL) p USING (motion_id, feature_set)
        WHERE (SELECT version FROM mocap_index.state) IS NOT NULL
          AND (p.n IS NULL OR p.n <> m.n_frames OR p.lo <> 1)""",
    "no postings of a missing motion": """
        SELECT DISTINCT motion_id FROM mocap_index.postings WHERE motion_id NOT IN (SELECT motion_id FROM motions)""",
    "no dangling annotation rows": """
        SELECT DISTINCT motion_id FROM annotations
        WHERE motion_id NOT IN (SELECT motion_id FROM motions) OR model NOT IN (SELECT model FROM models)""",
    "no dangling model rows": """
        SELECT model FROM classes WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM templates WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM keyframe_queries WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM keyframes WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM ga_statistics WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM confidence_maps WHERE model NOT IN (SELECT model FROM models)
        UNION SELECT model FROM templates t WHERE NOT EXISTS (
            SELECT 1 FROM classes c WHERE c.model = t.model AND c.class = t.class)""",
}


def invariants(path) -> list[str]:
    """The invariants the database at ``path`` breaks (empty: consistent), each with up to 5 offenders.

    Opening it is part of the check (DuckDB replays its write-ahead log), and
    so is answering ``annotate()`` on its first motion.
    """
    with mocapdb.connect(path) as con:
        broken = []
        postings = con.execute("SELECT count(*) FROM duckdb_tables() WHERE schema_name = 'mocap_index' "
                               "AND table_name = 'postings'").fetchall()[0][0]
        for name, sql in INVARIANTS.items():
            if "postings" in sql and not postings:
                continue
            rows = con.execute(sql).fetchall()
            if rows:
                broken.append(f"{name}: {[r[0] for r in rows[:5]]}")
        first = con.execute("SELECT min(motion_id) FROM motions").fetchall()[0][0]
        if first is not None:
            try:
                con.execute("SELECT annotate(?)", [first]).fetchall()
            except Exception as exc:  # noqa: BLE001 - any failure is a broken database
                broken.append(f"annotate() on the first motion: {str(exc).splitlines()[0][:300]}")
        return broken


def _descendants(pid) -> list[int]:
    """Every process started (directly or not) by ``pid``, from /proc."""
    children = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def kill_tree(proc) -> None:
    """SIGKILL a process, its process group and every descendant (Ray's raylet and workers too)."""
    victims = _descendants(proc.pid)
    for pid in [proc.pid, *victims]:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


@dataclass
class Trial:
    """One kill: the command, the delay, whether it had finished, and the invariants broken."""

    command: str
    delay: float
    completed: bool
    broken: list

    @property
    def consistent(self) -> bool:
        return not self.broken


class CrashHarness:
    """Prepared inputs of the trials, under ``root``.

    * ``base.duckdb``: a database holding some motions (annotated, so its
      annotations and index are there to be kept consistent);
    * ``new_files``: files an ``ingest`` adds (several batches);
    * ``export``: a feature export of more motions, for ``import-features``.
    """

    def __init__(self, root, data, *, env=None):
        self.root = Path(root)
        self.data = Path(data)
        self.env = dict(os.environ if env is None else env)
        cut = self.data / "hdm05_cut"
        self.base = self.root / "base.duckdb"
        self.new_files = [cut / c for c in ("depositFloorR", "grabHighR", "squat1Reps", "lieDownFloor",
                                            "hopBothLegs1hops", "kickLFront1Reps")]
        self.ray_sources = [cut / "squat1Reps", cut / "kickLFront1Reps", self.data / "cmu" / "02"]
        self.export = self.root / "export"
        if not self.base.exists():
            self._prepare(cut)

    def _prepare(self, cut):
        self.root.mkdir(parents=True, exist_ok=True)
        full = self.root / "full.duckdb"
        with mocapdb.connect(full) as con:
            mocapdb.ingest(con, [*self.new_files, self.data / "cmu" / "86"])
            mocapdb.api.export_features(con, self.export)
        with mocapdb.connect(self.base) as con:
            mocapdb.ingest(con, [cut / "rotateArmsBothBackward1Reps", cut / "throwBasketball",
                                 self.data / "cmu" / "86"])
            mocapdb.annotate(con)

    def _cli(self, *args, cwd):
        with open(Path(cwd) / "stderr.txt", "wb") as err:  # a file: a pipe nobody reads could block the command
            return subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", *map(str, args)], cwd=cwd,
                                    env=self.env, stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)

    def _run_and_kill(self, proc, marker, delay, d):
        """Kill ``proc`` ``delay`` s after ``marker`` appeared; True when it had finished before (then it
        must have succeeded)."""
        deadline = time.monotonic() + 300
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        try:
            proc.wait(timeout=delay)
        except subprocess.TimeoutExpired:
            kill_tree(proc)
            return False
        if proc.returncode != 0:
            err = (d / "stderr.txt").read_text(errors="replace")
            raise AssertionError(f"the command failed without being killed (exit {proc.returncode}): {err[-2000:]}")
        return True

    def _start(self, command, d):
        """Start ``command`` on a fresh copy of the base database in folder ``d``: (process, database,
        the path whose appearance marks the start of its writing)."""
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir()
        db = d / "db.duckdb"
        shutil.copy(self.base, db)
        if command == "ingest":
            proc = self._cli("--db", db, "ingest", *self.new_files, "--silent", cwd=d)
        elif command == "annotate":
            proc = self._cli("--db", db, "annotate", "--silent", "--format", "csv", "--out", d / "seg.csv", cwd=d)
        elif command == "import-features":
            proc = self._cli("--db", db, "import-features", self.export, cwd=d)
        elif command == "ray-annotate":
            proc = self._cli("ray-annotate", *self.ray_sources, "--out", d / "archive", "--num-cpus", "2",
                             "--batch-files", "8", cwd=d)
        else:
            raise ValueError(f"unknown command {command!r}; one of {', '.join(WINDOWS)}")
        return proc, db, d / "archive" if command == "ray-annotate" else d / "db.duckdb.wal"

    def work_seconds(self, command) -> float:
        """How long ``command`` writes on this machine: from the start of its writing to its exit,
        in one run that is not killed (kills drawn within it land in its work however fast the
        machine is; :data:`WINDOWS` are fixed bounds for the test suite)."""
        d = self.root / f"{command}-calibrate"
        proc, _, marker = self._start(command, d)
        deadline = time.monotonic() + 300
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        began = time.monotonic()
        proc.wait(timeout=600)
        seconds = time.monotonic() - began
        shutil.rmtree(d, ignore_errors=True)
        return seconds

    def trial(self, command, rng, k, *, window=None) -> Trial:
        """Run ``command`` on a copy of the base database, kill it at a random moment of its first
        ``window`` seconds of writing (default :data:`WINDOWS`), check the database."""
        delay = rng.uniform(0.0, WINDOWS[command] if window is None else window)
        d = self.root / f"{command}-{k}"
        proc, db, marker = self._start(command, d)
        completed = self._run_and_kill(proc, marker, delay, d)
        if command == "ray-annotate":
            # what a user does next with the archive the killed run left: import it
            imp = subprocess.run([sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), "import-features",
                                  str(d / "archive")], cwd=d, env=self.env, capture_output=True, text=True,
                                 timeout=600)
            if imp.returncode not in (0, 1):
                raise AssertionError(f"import of the partial archive crashed: {imp.stderr[-2000:]}")
        broken = invariants(db)
        shutil.rmtree(d, ignore_errors=True)
        return Trial(command, round(delay, 2), completed, broken)

    def run(self, trials, *, seed=0, commands=tuple(WINDOWS), calibrate=False):
        """``trials`` kills per command, seeded; returns the list of :class:`Trial`. ``calibrate``:
        draw each command's kills within its :meth:`work_seconds` instead of :data:`WINDOWS`."""
        rng = random.Random(seed)
        out = []
        for command in commands:
            window = self.work_seconds(command) if calibrate else None
            for k in range(trials):
                out.append(self.trial(command, rng, k, window=window))
        return out


def summary(results) -> str:
    """Trials / consistent per command, one line each."""
    lines = []
    for command in dict.fromkeys(r.command for r in results):
        rs = [r for r in results if r.command == command]
        lines.append(f"{command:16s} trials {len(rs):3d}  killed {sum(not r.completed for r in rs):3d}  "
                     f"consistent {sum(r.consistent for r in rs):3d}")
    return "\n".join(lines)
