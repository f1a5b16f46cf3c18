"""Content digests of exported parts, checked on import (issue 33, the security probe).

`import-features` of an export whose Parquet part had its feature words flipped (the same rows) imported
them silently, and the answers then differed from the source database; an extra `motion_id=99` partition
was ignored without a note. Each part's SHA-256 is written at export (`digests.json`) and checked. On the
recordings shipped with mocapdb; the Ray archive's digests (its manifest) are in tests/test_ray.py.
"""
import json
import shutil

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from conftest import run


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    d = tmp_path_factory.mktemp("digests")
    db = d / "s.duckdb"
    run(db, "ingest", "--sample", "--silent")
    run(db, "export-features", d / "export")
    return d / "export"


def _copy(export, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(export, copy)
    return copy


def test_every_part_has_its_digest_and_an_untouched_export_imports(export, tmp_path):
    listed = json.loads((export / "digests.json").read_text())["sha256"]
    parts = sorted(f.relative_to(export).as_posix() for f in export.rglob("*.parquet"))
    assert sorted(listed) == parts and len(parts) == 4 and all(len(v) == 64 for v in listed.values())
    assert "3 motion(s) imported" in run(tmp_path / "i.duckdb", "import-features", export).output


def test_feature_words_flipped_in_place_cost_their_motion(export, tmp_path):
    """As a missing or unreadable part does (tests/test_partial_archives.py), a changed one costs its motion,
    named with the reason; the others go in."""
    copy = _copy(export, tmp_path)
    part = sorted((copy / "features").rglob("*.parquet"))[1]
    t = pq.read_table(part)
    k = t.schema.get_field_index("bits")
    flipped = t.set_column(k, "bits", pc.bit_wise_xor(t.column("bits"), pa.scalar(5, t.schema.field("bits").type)))
    pq.write_table(flipped, part)
    assert pq.read_metadata(part).num_rows == t.num_rows   # the row count a check of rows would see
    db = tmp_path / "i.duckdb"
    r = run(db, "import-features", copy, code=1)
    rel = part.relative_to(copy).as_posix()
    mid = int(part.parent.name.split("=")[1])
    name = pq.read_table(copy / "motions.parquet").to_pylist()[mid - 1]["name"]
    assert (f"refused  archive motion {mid} ({name}): features changed since the export, not imported: {rel} is "
            "not the file written (its bytes differ from the SHA-256 in digests.json: changed since)") in r.output
    assert "2 motion(s) imported, 0 already present, 1 refused" in r.output
    assert run(db, "sql", "SELECT name FROM motions ORDER BY name", "--format", "csv").output.count("\n") == 3


def test_a_foreign_partition_or_a_changed_motions_file_is_refused(export, tmp_path):
    copy = _copy(export, tmp_path)
    extra = copy / "features" / "motion_id=99"
    extra.mkdir()
    shutil.copy(sorted((copy / "features").rglob("*.parquet"))[0], extra / "data_0.parquet")
    r = run(tmp_path / "i.duckdb", "import-features", copy, code=1)
    assert "features/motion_id=99/data_0.parquet is not one of its parts" in r.output
    copy2 = tmp_path / "copy2"
    shutil.copytree(export, copy2)
    t = pq.read_table(copy2 / "motions.parquet")
    pq.write_table(t.set_column(t.schema.get_field_index("name"), "name", pa.array(["x", "y", "z"])),
                   copy2 / "motions.parquet")
    r = run(tmp_path / "i2.duckdb", "import-features", copy2, code=1)
    assert "motions.parquet is not the file written" in r.output
    # an export of an older mocapdb (no digests): rows checked as before
    (copy2 / "digests.json").unlink()
    assert "3 motion(s) imported" in run(tmp_path / "i3.duckdb", "import-features", copy2).output
