"""An ingest worker process: ``python -m mocapdb.storage.ingest_worker`` (started by :mod:`mocapdb.storage.ingest_pool`).

A module of its own so that running it does not re-import the pool's module under a second name.
"""
from mocapdb.storage.ingest_pool import serve

if __name__ == "__main__":
    serve()
