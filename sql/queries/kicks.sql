-- Every kick in the archive with one query: the default model's designed kick
-- keyframe (the raised leg stretched, mocapdb/shipped_models/classes/kick.toml) for
-- the left leg and, mirrored, the right, with the matched frame ranges.
SELECT m.name, k.leg, k.start_frame, k.end_frame,
       round((k.end_frame - k.start_frame + 1) / m.fps, 2) AS seconds
FROM (SELECT 'left' AS leg, * FROM keyframe_search('kickLFront1Reps')
      UNION ALL
      SELECT 'right' AS leg, * FROM keyframe_search('kickRFront1Reps')) k
JOIN motions m USING (motion_id)
ORDER BY m.name, k.start_frame;
