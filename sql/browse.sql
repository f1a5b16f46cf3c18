-- Statements of mocapdb.storage.browse: the archive as `mocapdb serve` shows it (read only).

-- name: motion_page
-- one page of the archive: the filters (`q` a substring of the name or of the source path, so a session's
-- folder is a filter too), one of a fixed set of orders (a parameter, as a column name
-- cannot be one), LIMIT/OFFSET; `total` counts every motion the filters keep (the window runs before
-- LIMIT). The label filter is a semi-join on the label's segments of the model.
SELECT motion_id, name, format, source_fps, fps, n_frames, n_frames / fps AS seconds, source_path,
       regexp_extract(source_path, '^(.*)[/\\]', 1) AS folder, count(*) OVER () AS total
FROM motions
WHERE ($format IS NULL OR format = $format)
  AND ($q IS NULL OR contains(lower(name), lower($q)) OR contains(lower(source_path), lower($q)))
  AND ($min_s IS NULL OR n_frames / fps >= $min_s)
  AND ($max_s IS NULL OR n_frames / fps <= $max_s)
  AND ($label IS NULL OR motion_id IN (SELECT motion_id FROM annotations WHERE model = $model AND label = $label))
ORDER BY CASE WHEN $sort = 'name' THEN name END,
         CASE WHEN $sort = '-name' THEN name END DESC,
         CASE WHEN $sort = 'seconds' THEN n_frames / fps END,
         CASE WHEN $sort = '-seconds' THEN n_frames / fps END DESC,
         CASE WHEN $sort = 'format' THEN format END,
         CASE WHEN $sort = '-format' THEN format END DESC,
         CASE WHEN $sort = 'rate' THEN source_fps END,
         CASE WHEN $sort = '-rate' THEN source_fps END DESC,
         CASE WHEN $sort = '-id' THEN motion_id END DESC,
         motion_id
LIMIT $limit OFFSET $offset;

-- name: motion_count
-- the motions the filters keep (asked only when a page comes back empty, so `total` is unknown)
SELECT count(*) FROM motions
WHERE ($format IS NULL OR format = $format)
  AND ($q IS NULL OR contains(lower(name), lower($q)) OR contains(lower(source_path), lower($q)))
  AND ($min_s IS NULL OR n_frames / fps >= $min_s)
  AND ($max_s IS NULL OR n_frames / fps <= $max_s)
  AND ($label IS NULL OR motion_id IN (SELECT motion_id FROM annotations WHERE model = $model AND label = $label));

-- name: page_segments
-- the stored segments of a page's motions only (the label strips), in time order
SELECT motion_id, label, start_frame, end_frame FROM annotations
WHERE model = $model AND motion_id IN (SELECT unnest($ids))
ORDER BY motion_id, start_frame, label;

-- name: motion_row
SELECT motion_id, name, format, source_fps, fps, n_frames, n_frames / fps AS seconds, source_path,
       regexp_extract(source_path, '^(.*)[/\\]', 1) AS folder, n_source_frames, skeleton, reader_options, ingested_at
FROM motions WHERE motion_id = $id;

-- name: label_segments
-- every stored segment of a label across the archive, a page at a time
SELECT a.motion_id, m.name, a.start_frame, a.end_frame, a.start_s, a.end_s, a.cost, a.confidence,
       count(*) OVER () AS total
FROM annotations a JOIN motions m USING (motion_id)
WHERE a.model = $model AND a.label = $label
ORDER BY a.end_s - a.start_s DESC, a.motion_id, a.start_frame
LIMIT $limit OFFSET $offset;

-- name: model_labels
-- a model's labels in its label order (the viewer's colours follow it)
SELECT label FROM classes WHERE model = $model GROUP BY label ORDER BY min(label_id), label;

-- name: motion_segments
-- one motion's stored segments (of a model), in time order
SELECT label, start_frame, end_frame, start_s, end_s, cost, confidence FROM annotations
WHERE model = $model AND motion_id = $id ORDER BY start_frame, label;

-- name: stored_labels
-- the labels a model's stored segments hold (a label filter's choices besides the model's own labels)
SELECT DISTINCT label FROM annotations WHERE model = $model ORDER BY label;
