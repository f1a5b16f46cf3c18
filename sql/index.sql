-- The keyframe index (KEYFRAMES.md §1): plain tables in their own schema, like
-- DuckDB's fts. `state` always exists; `postings` exists while the index is
-- built. Every ingest, delete and import changes postings and bumps
-- state.version in the same transaction, so a connection that keeps the index
-- in memory knows when to reload it.

-- name: create_schema
CREATE SCHEMA IF NOT EXISTS %index_schema%;
CREATE TABLE IF NOT EXISTS %index_schema%.state (
    version  BIGINT          -- NULL: no index built; else bumped on every change
);
INSERT INTO %index_schema%.state SELECT NULL WHERE NOT EXISTS (SELECT 1 FROM %index_schema%.state);

-- name: create_postings
-- Runs of constant word per motion, once per index part: the toolbox's
-- per-set indexes (upper, lower, mix: the word restricted to the set's bits,
-- shifted to bit 0) and full (the 40-bit word). A posting list is
-- SELECT motion_id, seg … WHERE feature_set = ? AND word = ? ORDER BY motion_id, seg.
CREATE OR REPLACE TABLE %index_schema%.postings (
    motion_id    INTEGER NOT NULL,
    feature_set  VARCHAR NOT NULL,     -- upper, lower, mix, full
    seg          INTEGER NOT NULL,     -- run number within (motion, feature_set), from 1
    word         UBIGINT NOT NULL,     -- the run's word (restricted to the set, shifted)
    start_frame  INTEGER NOT NULL,     -- 1-based 30 Hz frame, as features.frame
    n_frames     INTEGER NOT NULL
);

-- name: drop_postings
DROP TABLE IF EXISTS %index_schema%.postings;
UPDATE %index_schema%.state SET version = NULL;

-- name: bump_version
UPDATE %index_schema%.state SET version = coalesce(version, 0) + 1;

-- name: version
SELECT version FROM %index_schema%.state;

-- name: insert_postings
INSERT INTO %index_schema%.postings SELECT * FROM mocap_new_postings;

-- name: delete_postings
DELETE FROM %index_schema%.postings WHERE motion_id IN (SELECT unnest($ids));

-- name: features_of_motions
SELECT motion_id, bits FROM features WHERE motion_id BETWEEN $first AND $last ORDER BY motion_id, frame;

-- name: load
SELECT p.motion_id,
       (list_position($all_parts, p.feature_set) - 1)::TINYINT AS part,
       p.seg - 1 AS seg, p.word, p.start_frame - 1 AS start_frame, p.n_frames
FROM %index_schema%.postings p
WHERE list_contains($parts, p.feature_set);

-- name: load_motions
-- the postings of some motions (ids ascending, lo and hi the first and last): a batch of an
-- archive-wide pass; the range lets DuckDB skip the row groups of other motions
SELECT p.motion_id,
       (list_position($all_parts, p.feature_set) - 1)::TINYINT AS part,
       p.seg - 1 AS seg, p.word, p.start_frame - 1 AS start_frame, p.n_frames
FROM %index_schema%.postings p
WHERE p.motion_id BETWEEN $lo AND $hi AND p.motion_id IN (SELECT unnest($ids)) AND list_contains($parts, p.feature_set);

-- name: motion_lengths
SELECT motion_id, n_frames FROM motions ORDER BY motion_id;

-- name: count_postings
SELECT count(*) FROM %index_schema%.postings;
