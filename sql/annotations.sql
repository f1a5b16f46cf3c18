-- Statements of mocapdb.storage.annotations (materialised annotation results).

-- name: delete
DELETE FROM annotations WHERE model = $model AND motion_id IN (SELECT unnest($ids));

-- name: insert
INSERT INTO annotations (motion_id, model, label, start_frame, end_frame, cost, start_s, end_s, tau, keyframes,
                         confidence)
SELECT motion_id, $model, label, start_frame, end_frame, cost, start_s, end_s, $tau, $keyframes, confidence
FROM mocap_new_annotations;

-- name: sources
SELECT motion_id, name, source_path, source_fps, n_source_frames FROM motions
WHERE $ids IS NULL OR motion_id IN (SELECT unnest($ids)) ORDER BY motion_id;
