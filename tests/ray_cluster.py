"""A Ray cluster of several nodes on this machine, started with ``ray start`` (tests and benchmarks).

Each node (``ray start --head``, then ``ray start --address``) gets a
temporary folder of its own, so that its processes can be told from any
other Ray on the machine; the cluster is stopped by the ids of those
processes and their children, never with ``ray stop`` (which stops every
Ray of the machine).
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _ray():
    return str(Path(sys.executable).with_name("ray"))


class LocalCluster:
    """``with LocalCluster(nodes=2, port=…) as c: … c.address …``.

    Parameters
    ----------
    nodes : int
        The head and ``nodes - 1`` more nodes.
    cpus : int
        CPUs of each node.
    port : int
        The head's GCS port.
    env : dict, optional
        Environment of every node (e.g. ``RAY_AUTH_MODE=token`` and the token;
        ``PYTHONPATH`` so that its workers import the code under test).
    """

    def __init__(self, *, nodes=1, cpus=1, port=6391, env=None):
        self.nodes, self.cpus, self.port = nodes, cpus, port
        self.env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", **(env or {}))
        # short: Ray's socket paths below it must stay within the 107 characters of a Unix socket
        self.root = Path(tempfile.mkdtemp(prefix="rc", dir="/tmp"))

    @property
    def address(self) -> str:
        return f"127.0.0.1:{self.port}"

    def _start(self, args, k):
        subprocess.run([_ray(), "start", *args, "--num-cpus", str(self.cpus), "--temp-dir", str(self.root / f"n{k}"),
                        "--node-ip-address", "127.0.0.1", "--disable-usage-stats"], env=self.env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=300)

    def __enter__(self):
        try:
            self._start(["--head", "--port", str(self.port), "--include-dashboard=false"], 0)
            for k in range(1, self.nodes):
                self._start(["--address", self.address], k)
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc):
        self.stop()

    def pids(self) -> list:
        """The cluster's processes: those started with its folders, and their descendants."""
        procs = {}
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
                    ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
                except (OSError, ValueError, IndexError):
                    continue
                procs[int(d.name)] = (ppid, cmd)
        mine = {pid for pid, (_, cmd) in procs.items() if str(self.root) in cmd}
        grew = True
        while grew:
            more = {pid for pid, (ppid, _) in procs.items() if ppid in mine} - mine
            mine |= more
            grew = bool(more)
        return sorted(mine - {os.getpid()})

    def stop(self) -> None:
        for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 1.0)):
            pids = self.pids()
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + wait
            while pids and self.pids() and time.monotonic() < deadline:
                time.sleep(0.1)
        shutil.rmtree(self.root, ignore_errors=True)
