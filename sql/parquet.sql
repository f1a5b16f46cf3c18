-- Statements of mocapdb.storage.parquet (features to and from Parquet).

-- name: export_features
-- a file per motion: DIR/features/motion_id=N/*.parquet (hive partitioning)
COPY (SELECT motion_id, frame, bits FROM features ORDER BY motion_id, frame)
TO $path (FORMAT parquet, PARTITION_BY (motion_id), OVERWRITE_OR_IGNORE);

-- name: export_motions
COPY (SELECT * FROM motions ORDER BY motion_id) TO $path (FORMAT parquet);

-- name: archive_features
-- an archive's features rows of motions lo…hi from the given files: an export's motion_id is its
-- folder's (hive partitioning), a Ray archive's a column beside the motion_bucket folder
SELECT motion_id::BIGINT AS motion_id, frame::BIGINT AS frame, bits
FROM read_parquet($files, hive_partitioning = true, union_by_name = true)
WHERE motion_id::BIGINT BETWEEN $lo AND $hi;

-- name: archive_annotations
-- archives written before the confidence (issue 25) lack its column: NULL there
SELECT motion_id, model, label, start_frame, end_frame, cost, start_s, end_s, tau, keyframes, annotated_at, confidence
FROM (SELECT * FROM read_parquet($files, hive_partitioning = true, union_by_name = true)
      UNION ALL BY NAME SELECT NULL::DOUBLE AS confidence WHERE false)
WHERE motion_id BETWEEN $lo AND $hi;

-- name: import_motions
INSERT INTO motions BY NAME
SELECT * EXCLUDE (motion_id, ord) FROM mocap_new_motions ORDER BY ord
RETURNING motion_id, sha256, skeleton_sha256;

-- name: import_annotations
INSERT INTO annotations (motion_id, model, label, start_frame, end_frame, cost, start_s, end_s, tau, keyframes,
                         annotated_at, confidence)
SELECT m.new, a.model, a.label, a.start_frame, a.end_frame, a.cost, a.start_s, a.end_s, a.tau, a.keyframes,
       a.annotated_at, a.confidence
FROM mocap_archive_annotations a JOIN mocap_id_map m ON a.motion_id = m.old
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
