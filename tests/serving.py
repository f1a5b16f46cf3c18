"""``mocapdb serve`` in a process of its own, for the serve tests: started on a free port, stopped after;
and the database both serve test modules read (session fixtures: made and served once)."""
import hashlib
import json
import subprocess
import sys
import urllib.error
import urllib.request

import pytest

import mocapdb

from conftest import run


class Served:
    """``mocapdb --db DB serve --port 0`` running; ``url`` is where it listens."""

    def __init__(self, db, *args):
        self.proc = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), "serve", "--port",
                                      "0", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        if "Serving" not in line:
            self.proc.kill()
            raise AssertionError(f"mocapdb serve did not start: {line}{self.proc.stderr.read()[-2000:]}")
        self.url = line.split(" at ", 1)[1].split()[0]
        self.pid = self.proc.pid

    def get(self, path, headers=None):
        """(status, body bytes, headers) of a GET."""
        req = urllib.request.Request(self.url.rstrip("/") + path, headers=headers or {})
        try:
            with urllib.request.urlopen(req, timeout=120) as r:
                return r.status, r.read(), r.headers
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read(), exc.headers

    def json(self, path):
        """(status, decoded JSON) of a GET."""
        status, body, _ = self.get(path)
        return status, json.loads(body)

    def stop(self):
        """Stop the server; what it wrote to stderr is then ``err``."""
        self.proc.terminate()
        try:
            self.proc.wait(15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.err = self.proc.stderr.read()
        self.proc.stdout.close()
        self.proc.stderr.close()


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


#: an ingest log of the shape newer ingests keep (path, member, outcome, reason, notes, motion_id, logged_at)
INGEST_LOG = """
DROP TABLE IF EXISTS ingest_log;
CREATE TABLE ingest_log (path VARCHAR, member VARCHAR, outcome VARCHAR, reason VARCHAR, notes VARCHAR,
                         motion_id INTEGER, logged_at TIMESTAMP);
INSERT INTO ingest_log VALUES
    ('/d/broken.bvh', NULL, 'failed', 'broken.bvh:12: expected 57 channels, got 54', NULL, NULL, '2026-01-01 10:00'),
    ('/d/notes.txt', NULL, 'not a motion file', 'not a motion file (.txt)', NULL, NULL, '2026-01-01 10:00'),
    ('/d/cmu.zip', 'x/13_29.amc', 'failed', 'no skeleton for 13_29.amc', NULL, NULL, '2026-01-01 10:00'),
    ('/d/fixed.bvh', NULL, 'failed', 'fixed.bvh:3: bad header', NULL, NULL, '2026-01-01 10:00'),
    ('/d/fixed.bvh', NULL, 'ingested', NULL, NULL, 3, '2026-01-02 10:00'),
    ('/d/86_09.amc', NULL, 'ingested', NULL, NULL, 1, '2026-01-01 10:00');
"""


@pytest.fixture(scope="session")
def sample_db(tmp_path_factory):
    """The shipped sample, ingested and annotated with the default model (stored), with an ingest log
    that refused three files (made by hand: the same rows whatever the ingest logs itself)."""
    db = tmp_path_factory.mktemp("serve") / "sample.duckdb"
    run(db, "ingest", "--sample", "--silent")
    run(db, "annotate", "--silent")
    with mocapdb.connect(db) as con:
        con.execute(INGEST_LOG)
    return db


@pytest.fixture(scope="session")
def server(sample_db):
    """The sample served; the database file's digest before it started is ``server.digest``."""
    before = digest(sample_db)
    s = Served(sample_db)
    s.digest = before
    yield s
    s.stop()
