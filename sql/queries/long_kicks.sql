-- All kick segments longer than one second, from every motion.
SELECT m.name, s.label, s.start_frame, s.end_frame, s.end_s - s.start_s AS seconds, s.cost
FROM motions m, LATERAL (SELECT unnest(annotate(m.motion_id), recursive := true)) s
WHERE s.label = 'kick' AND s.end_s - s.start_s > 1.0
ORDER BY m.name, s.start_frame;
