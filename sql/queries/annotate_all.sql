-- Annotate every motion with the default model: one row per labelled segment
-- (30 Hz frames, 1-based inclusive; seconds from the start of the motion).
SELECT m.motion_id, m.name, unnest(annotate(m.motion_id), recursive := true)
FROM motions m;
