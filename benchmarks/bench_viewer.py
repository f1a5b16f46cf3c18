"""The viewer page: size and load time for a 10-minute motion and for the longest motion of ../shared/data.

Run: ``python benchmarks/bench_viewer.py`` (needs Debian's ``chromium``, as the
tests). Prints figures for benchmarks/RESULTS.md (issue 12):

* the longest real motion (86_09, 4,794 frames at 120 Hz, 40 s) and a 10-minute
  motion (72,000 frames at 120 Hz): the 232 HDM05 clips of ../shared/data one
  after the other (7.9 min, read with HDM_bd.asf), then backwards from the
  end, written as one AMC file to a temporary folder;
* per motion: ``mocapdb.view`` wall time (annotation with Δ̄, re-reading the
  source, encoding), of which re-reading the source; page size, of which poses
  and Δ̄; load time in headless Chromium (the page's own ``performance.now()``
  when its data are decoded, the timeline built and the first pose drawn), and
  the browser's wall time for the whole dump;
* what storing poses instead would cost on a 100-hour archive (10.8 M frames
  at 30 Hz): float32 and int16 joints against the 8-byte feature words.
"""
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from bench_annotate import DATA, machine_header  # noqa: E402
from browser import _run  # noqa: E402
from timing import best_of  # noqa: E402

HOURS_100 = 100 * 3600 * 30  # frames at 30 Hz


def amc_frames(path):
    """(header lines, frames as lists of lines) of an AMC file."""
    lines = path.read_text(encoding="latin-1").splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.strip().isdigit())
    frames = []
    for ln in lines[first:]:
        if ln.strip().isdigit():
            frames.append([])
        else:
            frames[-1].append(ln)
    return lines[:first], frames


def long_amc(clips, out, n_frames):
    """One AMC of ``n_frames`` frames: the clips' frames in turn, then backwards from the end.

    Played backwards rather than repeated: a repeat would be found by deflate
    and make the page unrealistically small.
    """
    header, frames = amc_frames(clips[0])
    for c in clips[1:]:
        frames += amc_frames(c)[1]
    order = list(range(len(frames)))
    while len(order) < n_frames:
        order += list(range(len(frames) - 1, -1, -1))
    with out.open("w", encoding="latin-1", newline="\n") as fh:
        fh.write("\n".join(header) + "\n")
        for k, i in enumerate(order[:n_frames], start=1):
            fh.write(f"{k}\n" + "\n".join(frames[i]) + "\n")
    return out


def page_parts(text):
    data = json.loads(re.search(r'id="mocapdb-data">(.*?)</script>', text, re.S).group(1).replace("<\\/", "</"))
    return len(data["pose"]["data"]), len(data["delta"]["data"]), data["pose"]["dtype"]


def load_ms(page, repeat=3):
    """Best page load time (ms, the page's own clock) and best browser wall time (s) of ``repeat`` runs."""
    best, wall = float("inf"), float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        dom = _run(page.resolve().as_uri(), "--dump-dom").stdout
        wall = min(wall, time.perf_counter() - t)
        m = re.search(r'data-load-ms="([\d.]+)"', dom)
        if not m or "data-errors" in dom:
            raise RuntimeError(f"{page.name} did not load cleanly")
        best = min(best, float(m.group(1)))
    return best, wall


def main():
    import mocapdb
    from mocapdb.storage.motions import source_motion

    machine_header("viewer page: size and load time (issue 12)")
    subprocess.run(["chromium", "--version"], check=False)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        ten = long_amc(sorted((DATA / "hdm05_cut").glob("*/*.amc")), tmp / "hdm05_10min.amc", 72_000)
        con = mocapdb.connect(tmp / "v.duckdb")
        for path, asf in ((DATA / "cmu" / "86" / "86_09.amc", DATA / "cmu" / "86" / "86.asf"),
                          (ten, DATA / "hdm05_cut" / "HDM_bd.asf")):
            report = mocapdb.ingest(con, [path], asf=asf)
            assert not report.failed, report.failed
        print("| motion | source frames | 30 Hz frames | view s | of which re-read s | page KB | poses KB | "
              "Δ̄ KB | poses B/frame | load ms (page) | browser wall s |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        per_frame = []
        for name in ("86_09", "hdm05_10min"):
            mid, n_src, n = con.execute("SELECT motion_id, n_source_frames, n_frames FROM motions WHERE name = ?",
                                        [name]).fetchone()
            page = tmp / f"{name}.html"
            secs, _ = best_of(lambda: mocapdb.view(con, name, out=page), repeat=3)
            reread, _ = best_of(lambda: source_motion(con, mid), repeat=3)
            text = page.read_text(encoding="utf-8")
            poses, delta, dtype = page_parts(text)
            per_frame.append(poses / n)
            ms, wall = load_ms(page)
            print(f"| {name} | {n_src:,} | {n:,} | {secs:.2f} | {reread:.2f} | {len(text.encode()) / 1024:,.0f} | "
                  f"{poses / 1024:,.0f} | {delta / 1024:,.0f} | {poses / n:.1f} ({dtype}) | {ms:.0f} | {wall:.2f} |")
        con.close()
    b = max(per_frame)
    print()
    print(f"storing poses for a 100-hour archive ({HOURS_100:,} frames at 30 Hz, 24 joints x 3):")
    print(f"  float32 {HOURS_100 * 72 * 4 / 1e9:.2f} GB, int16 {HOURS_100 * 72 * 2 / 1e9:.2f} GB, "
          f"as the page encodes them (base64 of deflated int16 differences) {HOURS_100 * b / 1e9:.2f} GB; "
          f"feature words {HOURS_100 * 8 / 1e6:.0f} MB")


if __name__ == "__main__":
    main()
