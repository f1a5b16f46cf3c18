-- Statements of mocapdb.storage.models (class models side by side, keyed by name).

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
