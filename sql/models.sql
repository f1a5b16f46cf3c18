-- Statements of mocapdb.storage.model_store (class models side by side, keyed by name).

-- name: names
SELECT model FROM models ORDER BY model;

-- name: fingerprint
SELECT fingerprint FROM models WHERE model = $model;

-- name: metadata
SELECT description, source FROM models WHERE model = $model;

-- name: shipped_state
SELECT model, (fingerprint, shipped) FROM models;

-- name: keyframe_stats
SELECT class, source, fitness, precision, recall FROM keyframe_queries WHERE model = $model;

-- name: ga_statistics
SELECT class, run, generation, mean_precision, mean_recall, mean_fitness, best_fitness, mean_keyframes
FROM ga_statistics WHERE model = $model ORDER BY class, run, generation;

-- name: ga_curve
-- Per-generation averages over all runs and classes (paper Fig. 5).
SELECT generation, avg(mean_precision) AS mean_precision, avg(mean_recall) AS mean_recall,
       avg(mean_fitness) AS mean_fitness, avg(best_fitness) AS best_fitness,
       avg(mean_keyframes) AS mean_keyframes, count(DISTINCT (class, run)) AS n_runs
FROM ga_statistics WHERE model = $model GROUP BY generation ORDER BY generation;

-- A model's rows in each of its tables: read, removed, written (the table names are part
-- of the statements, so each table has its own).

-- name: rows_models
SELECT * FROM models WHERE model = $model;

-- name: delete_models
DELETE FROM models WHERE model = $model;

-- name: insert_models
INSERT INTO models BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_classes
SELECT * FROM classes WHERE model = $model;

-- name: delete_classes
DELETE FROM classes WHERE model = $model;

-- name: insert_classes
INSERT INTO classes BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_templates
SELECT * FROM templates WHERE model = $model;

-- name: delete_templates
DELETE FROM templates WHERE model = $model;

-- name: insert_templates
INSERT INTO templates BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_keyframe_queries
SELECT * FROM keyframe_queries WHERE model = $model;

-- name: delete_keyframe_queries
DELETE FROM keyframe_queries WHERE model = $model;

-- name: insert_keyframe_queries
INSERT INTO keyframe_queries BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_keyframes
SELECT * FROM keyframes WHERE model = $model;

-- name: delete_keyframes
DELETE FROM keyframes WHERE model = $model;

-- name: insert_keyframes
INSERT INTO keyframes BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_ga_statistics
SELECT * FROM ga_statistics WHERE model = $model;

-- name: delete_ga_statistics
DELETE FROM ga_statistics WHERE model = $model;

-- name: insert_ga_statistics
INSERT INTO ga_statistics BY NAME SELECT * FROM mocap_new_rows;

-- name: rows_confidence_maps
SELECT * FROM confidence_maps WHERE model = $model;

-- name: delete_confidence_maps
DELETE FROM confidence_maps WHERE model = $model;

-- name: insert_confidence_maps
INSERT INTO confidence_maps BY NAME SELECT * FROM mocap_new_rows;
