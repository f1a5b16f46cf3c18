"""The stored words of every recording of ``../shared/data``, as digests, and how to make them.

``python tests/feature_digests.py --repo DIR`` ingests every shared recording with the checkout
``DIR`` (cmu/13 and cmu/14 with cmu/02/02.asf, as they ship without a skeleton) and writes
``tests/feature_digests.json``: per file (relative to the data folder) the SHA-256 of its 30 Hz words
as stored (uint64, frame order) and its frame counts, or ``"failed"``. The file in the repository was
made by d3b3f07, the code before issue 35's ingest (worker processes, the skeleton lookup, feature 41
by blocks): ``tests/test_ingest_workers.py`` checks that today's ingest stores the same words for
every file. Make it again, with the reason in the commit, only when the features change on purpose.
Three entries are cd10d4b's, all others d3b3f07's: ACCAD's two crawls and the crouch that ends lying,
refused by d3b3f07's human test, are read since (a human who never stands); the remaining 537 files
made again by cd10d4b gave d3b3f07's digests.
"""
import argparse
import hashlib
import json
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
DIGESTS = HERE / "feature_digests.json"


def ingest_digests(mocapdb, data: Path, db: Path) -> dict:
    """``{relative path: {"sha256", "n_frames", "n_source_frames"} or "failed"}`` of an ingest of ``data``."""
    con = mocapdb.connect(db)
    try:
        first = mocapdb.ingest(con, [data])
        cmu02 = data / "cmu" / "02" / "02.asf"
        second = mocapdb.ingest(con, [data / "cmu" / "13", data / "cmu" / "14"], asf=cmu02)
        out = {}
        for p, _ in first.failed + second.failed:
            out[Path(p).relative_to(data).as_posix()] = "failed"
        rows = con.execute("""
            SELECT m.source_path, m.n_frames, m.n_source_frames, list(f.bits ORDER BY f.frame)
            FROM motions m JOIN features f USING (motion_id) GROUP BY ALL""").fetchall()
        for path, n30, native, bits in rows:
            words = bytes().join(int(b).to_bytes(8, "little") for b in bits)
            out[Path(path).relative_to(data).as_posix()] = {"sha256": hashlib.sha256(words).hexdigest(),
                                                            "n_frames": n30, "n_source_frames": native}
        return dict(sorted(out.items()))
    finally:
        con.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repo", type=Path, required=True, help="the checkout whose ingest makes the digests")
    ap.add_argument("--data", type=Path, default=HERE.parents[0].parent / "shared" / "data")
    args = ap.parse_args()
    sys.path.insert(0, str(args.repo.resolve()))
    import mocapdb

    with tempfile.TemporaryDirectory() as tmp:
        digests = ingest_digests(mocapdb, args.data.resolve(), Path(tmp) / "d.duckdb")
    DIGESTS.write_text(json.dumps({"made_by": args.repo.name, "files": digests}, indent=1) + "\n")
    print(f"{len(digests)} files, {sum(v == 'failed' for v in digests.values())} failed -> {DIGESTS}")


if __name__ == "__main__":
    main()
