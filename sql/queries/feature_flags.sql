-- Ad-hoc analytics over the named features: share of frames with both knees
-- bent and with the right hand above the head, per motion.
SELECT m.name,
       round(avg((knee_right_bent AND knee_left_bent)::INTEGER), 3) AS both_knees_bent,
       round(avg(hand_right_raised_rel_spine::INTEGER), 3) AS right_hand_raised
FROM feature_flags f JOIN motions m USING (motion_id)
GROUP BY m.name
ORDER BY both_knees_bent DESC;
