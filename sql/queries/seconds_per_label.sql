-- Seconds of each label per motion (segments of different labels may overlap,
-- as in the paper: each label's segments are counted on their own).
SELECT m.name, s.label, round(sum(s.end_s - s.start_s), 2) AS seconds, count(*) AS segments
FROM motions m, LATERAL (SELECT unnest(annotate(m.motion_id), recursive := true)) s
GROUP BY m.name, s.label
ORDER BY m.name, seconds DESC;
