-- All motions that contain a squat-like keyframe chain (the default model's
-- squat1Reps keyframe query), with the matched frame ranges.
SELECT m.name, k.start_frame, k.end_frame, round((k.end_frame - k.start_frame + 1) / m.fps, 2) AS seconds
FROM keyframe_search('squat1Reps') k JOIN motions m USING (motion_id)
ORDER BY m.name, k.start_frame;
