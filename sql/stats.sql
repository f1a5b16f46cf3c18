-- Statements of mocapdb.storage.stats: what an archive holds (`mocapdb stats`, /stats of `mocapdb serve`).

-- name: formats
-- hours and motions per source format and rate
SELECT format, source_fps, count(*) AS motions, sum(n_frames / fps) / 3600 AS hours
FROM motions GROUP BY format, source_fps ORDER BY hours DESC, format, source_fps;

-- name: labels
-- annotated hours per label of a model (segments of one label never overlap)
SELECT label, count(*) AS segments, count(DISTINCT motion_id) AS motions, sum(end_s - start_s) / 3600 AS hours
FROM annotations WHERE model = $model GROUP BY label ORDER BY hours DESC, label;

-- name: models
-- the models with stored annotations
SELECT model, count(*) AS segments FROM annotations GROUP BY model ORDER BY model;

-- name: has_ingest_log
-- whether the database keeps an ingest log (newer mocapdb versions do)
SELECT count(*) > 0 FROM information_schema.tables WHERE table_name = 'ingest_log' AND table_schema = 'main';

-- name: refused
-- files whose latest ingest refused them: failed, or not a motion file (a file refused once and
-- stored later is no longer refused)
SELECT path, member, outcome, reason, logged_at
FROM (SELECT path, member, outcome, reason, logged_at,
             row_number() OVER (PARTITION BY path, coalesce(member, '') ORDER BY logged_at DESC) AS latest
      FROM ingest_log)
WHERE latest = 1 AND outcome IN ('failed', 'not a motion file')
ORDER BY outcome, path, member;
