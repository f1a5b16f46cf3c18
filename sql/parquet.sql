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
