-- Statements of mocapdb.storage.parquet (features to and from Parquet).

-- name: import_motions
INSERT INTO motions BY NAME
SELECT * EXCLUDE (motion_id, ord) FROM mocap_new_motions ORDER BY ord
RETURNING motion_id;

-- name: import_features
INSERT INTO features
SELECT m.new, f.frame, f.bits
FROM read_parquet($features, hive_partitioning = true) f JOIN mocap_id_map m ON f.motion_id::INTEGER = m.old
ORDER BY m.new, f.frame;

-- name: words_of_motions
SELECT motion_id, bits FROM features WHERE motion_id IN (SELECT unnest($ids)) ORDER BY motion_id, frame;

-- name: import_annotations
INSERT INTO annotations (motion_id, model, label, start_frame, end_frame, cost, start_s, end_s, tau, keyframes,
                         annotated_at)
SELECT m.new, a.model, a.label, a.start_frame, a.end_frame, a.cost, a.start_s, a.end_s, a.tau, a.keyframes,
       a.annotated_at
FROM read_parquet($annotations, hive_partitioning = true) a JOIN mocap_id_map m ON a.motion_id = m.old
ORDER BY m.new, a.start_frame, a.label;

-- The tables an archive on Parquet mirrors (mocapdb.storage.parquet.table_schemas).

-- name: empty_motions
SELECT * FROM motions LIMIT 0;

-- name: empty_features
SELECT * FROM features LIMIT 0;

-- name: empty_postings
SELECT * FROM %index_schema%.postings LIMIT 0;

-- name: empty_annotations
SELECT * FROM annotations LIMIT 0;
