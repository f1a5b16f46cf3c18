-- Statements of mocapdb.storage.motions and mocapdb.storage.ingest.

-- name: by_id
SELECT motion_id FROM motions WHERE motion_id = $id;

-- name: by_name
SELECT motion_id FROM motions WHERE name = $name ORDER BY motion_id;

-- name: meta
SELECT motion_id, name, fps, n_frames, source_fps, n_source_frames FROM motions
WHERE $ids IS NULL OR motion_id IN (SELECT unnest($ids)) ORDER BY motion_id;

-- name: words_of
-- the features of some motions (ids ascending, lo and hi the first and last): the range lets
-- DuckDB skip the row groups of other motions (features are stored in motion order)
SELECT motion_id, frame, bits FROM features WHERE motion_id BETWEEN $lo AND $hi AND motion_id IN (SELECT unnest($ids));

-- name: feature_counts
-- a stored motion is complete when its feature rows are its frames 1…n once each: n rows from 1
-- to n summing to n(n+1)/2 (a few numbers per motion, no state that grows with its length)
SELECT m.motion_id, m.name, m.n_frames, coalesce(f.n, 0) AS n_rows,
       coalesce(f.n = m.n_frames AND f.lo = 1 AND f.hi = m.n_frames
                AND f.s = m.n_frames::BIGINT * (m.n_frames::BIGINT + 1) // 2, m.n_frames = 0) AS complete
FROM motions m
LEFT JOIN (SELECT motion_id, count(*) AS n, min(frame) AS lo, max(frame) AS hi, sum(frame::BIGINT) AS s
           FROM features WHERE motion_id IN (SELECT unnest($ids)) GROUP BY motion_id) f USING (motion_id)
WHERE m.motion_id IN (SELECT unnest($ids))
ORDER BY m.motion_id;

-- name: source
SELECT source_path, skeleton_path, reader_options, sha256, skeleton_sha256 FROM motions WHERE motion_id = $id;

-- name: by_file_name
-- a document named by its file (86_09.amc) where the stem names several motions
SELECT motion_id FROM motions WHERE regexp_extract(source_path, '[^/\\]+$') = $name ORDER BY motion_id;

-- name: name_counts
SELECT name, count(*) AS n FROM motions GROUP BY name;

-- name: stored_keys
SELECT motion_id, sha256, skeleton_sha256 FROM motions;

-- name: insert_motions
INSERT INTO motions (name, source_path, format, sha256, skeleton_sha256, source_fps, fps,
                     n_source_frames, n_frames, skeleton, skeleton_path, reader_options)
SELECT name, source_path, format, sha256, skeleton_sha256, source_fps, fps, n_source_frames, n_frames,
       skeleton, skeleton_path, reader_options
FROM mocap_new_motions ORDER BY ord
RETURNING motion_id, sha256, skeleton_sha256;

-- name: insert_features
INSERT INTO features SELECT motion_id, frame, bits FROM mocap_new_features;

-- name: delete_features
DELETE FROM features WHERE motion_id IN (SELECT unnest($ids));

-- name: delete_annotations
DELETE FROM annotations WHERE motion_id IN (SELECT unnest($ids));

-- name: delete_motions
DELETE FROM motions WHERE motion_id IN (SELECT unnest($ids)) RETURNING motion_id;

-- name: count
SELECT count(*) FROM motions;

-- name: schema_exists
SELECT count(*) > 0 FROM duckdb_tables() WHERE schema_name = 'main' AND table_name = 'motions';

-- name: sources_for_relocate
SELECT motion_id, name, source_path, sha256, skeleton_path, skeleton_sha256 FROM motions ORDER BY motion_id;

-- name: relocate
UPDATE motions SET source_path = r.source_path, skeleton_path = r.skeleton_path
FROM mocap_relocated r WHERE motions.motion_id = r.motion_id;

-- name: for_delete
-- what delete says about a motion it removes
SELECT motion_id, name, format, source_path FROM motions WHERE motion_id IN (SELECT unnest($ids)) ORDER BY motion_id;

-- name: named
SELECT motion_id, name, format, source_path FROM motions WHERE name = $name ORDER BY motion_id;

-- name: selected
-- the motions a command selects by filter (export-joints): a label among the stored segments of a
-- model and a WHERE condition over motions' columns (spliced in by mocapdb.storage.motions.select_motions,
-- the user's own SQL on their own database, as `mocapdb sql` runs it; the commands open it read-only)
SELECT motion_id FROM motions
WHERE ($label IS NULL OR motion_id IN (SELECT motion_id FROM annotations WHERE model = $model AND label = $label))
  AND ({where})
ORDER BY motion_id;

-- name: stored_labels
SELECT DISTINCT label FROM annotations WHERE model = $model ORDER BY label;
