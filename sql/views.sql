-- The 40 features as named BOOLEAN columns (generated from mocapdb.features.FEATURE_NAMES).
CREATE OR REPLACE VIEW feature_flags AS
SELECT
    motion_id,
    frame,
    (bits & 1::UBIGINT) <> 0 AS hand_right_to_front_rel_torso,
    (bits & 2::UBIGINT) <> 0 AS hand_left_to_front_rel_torso,
    (bits & 4::UBIGINT) <> 0 AS hand_right_raised_rel_spine,
    (bits & 8::UBIGINT) <> 0 AS hand_left_raised_rel_spine,
    (bits & 16::UBIGINT) <> 0 AS hand_right_to_top_rel_spine,
    (bits & 32::UBIGINT) <> 0 AS hand_left_to_top_rel_spine,
    (bits & 64::UBIGINT) <> 0 AS elbow_right_bent,
    (bits & 128::UBIGINT) <> 0 AS elbow_left_bent,
    (bits & 256::UBIGINT) <> 0 AS hands_apart_rel_shoulders,
    (bits & 512::UBIGINT) <> 0 AS hands_move_together,
    (bits & 1024::UBIGINT) <> 0 AS hand_right_move_apart_rel_root,
    (bits & 2048::UBIGINT) <> 0 AS hand_left_move_apart_rel_root,
    (bits & 4096::UBIGINT) <> 0 AS hand_right_high_vel,
    (bits & 8192::UBIGINT) <> 0 AS hand_left_high_vel,
    (bits & 16384::UBIGINT) <> 0 AS foot_right_back_rel_leg_left,
    (bits & 32768::UBIGINT) <> 0 AS foot_left_back_rel_leg_right,
    (bits & 65536::UBIGINT) <> 0 AS foot_right_raised_rel_y_body_min,
    (bits & 131072::UBIGINT) <> 0 AS foot_left_raised_rel_y_body_min,
    (bits & 262144::UBIGINT) <> 0 AS feet_apart_rel_hips,
    (bits & 524288::UBIGINT) <> 0 AS knee_right_bent,
    (bits & 1048576::UBIGINT) <> 0 AS knee_left_bent,
    (bits & 2097152::UBIGINT) <> 0 AS foot_crossover,
    (bits & 4194304::UBIGINT) <> 0 AS feet_move_together_rel_hips,
    (bits & 8388608::UBIGINT) <> 0 AS feet_move_apart_rel_hips,
    (bits & 16777216::UBIGINT) <> 0 AS foot_right_high_vel,
    (bits & 33554432::UBIGINT) <> 0 AS foot_left_high_vel,
    (bits & 67108864::UBIGINT) <> 0 AS humerus_right_abduct_rel_spine,
    (bits & 134217728::UBIGINT) <> 0 AS humerus_left_abduct_rel_spine,
    (bits & 268435456::UBIGINT) <> 0 AS femur_right_abduct_rel_spine,
    (bits & 536870912::UBIGINT) <> 0 AS femur_left_abduct_rel_spine,
    (bits & 1073741824::UBIGINT) <> 0 AS root_behind_feet_left_right_neck,
    (bits & 2147483648::UBIGINT) <> 0 AS spine_horizontal_rel_y,
    (bits & 4294967296::UBIGINT) <> 0 AS hand_right_low_rel_y_body_min,
    (bits & 8589934592::UBIGINT) <> 0 AS hand_left_low_rel_y_body_min,
    (bits & 17179869184::UBIGINT) <> 0 AS shoulders_rotated_right_rel_hip,
    (bits & 34359738368::UBIGINT) <> 0 AS shoulders_rotated_left_rel_hip,
    (bits & 68719476736::UBIGINT) <> 0 AS body_extent_rel_y,
    (bits & 137438953472::UBIGINT) <> 0 AS body_extent_extremities_rel_x_z,
    (bits & 274877906944::UBIGINT) <> 0 AS root_high_vel,
    (bits & 549755813888::UBIGINT) <> 0 AS root_high_ang_vel
FROM features;

-- Model names and fingerprints, for the SQL functions: a macro parameter named
-- `model` cannot read a column named `model` (DuckDB rejects the clash).
CREATE OR REPLACE VIEW model_fingerprints AS
SELECT m.model AS model_name, m.fingerprint FROM models m;

-- Near-duplicate takes (issue 33): pairs of motions of as many 30 Hz frames whose feature words agree on
-- at least 99 % of them — the same take at another scale or unit (the features do not depend on either),
-- or exported again. Set-based: a pair is a candidate when its words agree at 16 frames spread over the
-- take (at least 14 of them: a 1 % disagreement rarely falls there twice), then every frame of the
-- candidates is compared, their words as lists. Motions of one length only are paired.
CREATE OR REPLACE VIEW duplicates AS
WITH sketch AS (
    SELECT m.motion_id, m.n_frames, list(f.bits ORDER BY r.k) AS words
    FROM motions m CROSS JOIN range(16) r(k)
    JOIN features f ON f.motion_id = m.motion_id AND f.frame = 1 + (r.k * (m.n_frames - 1)) // 15
    WHERE m.n_frames >= 16
    GROUP BY m.motion_id, m.n_frames
),
candidates AS (
    SELECT a.motion_id AS a, b.motion_id AS b, a.n_frames
    FROM sketch a JOIN sketch b ON a.n_frames = b.n_frames AND a.motion_id < b.motion_id
    WHERE len(a.words) = 16 AND len(b.words) = 16
      AND list_sum(list_transform(range(1, 17), lambda i: (a.words[i] = b.words[i])::INTEGER)) >= 14
),
words AS (
    SELECT motion_id, list(bits ORDER BY frame) AS w FROM features
    WHERE motion_id IN (SELECT a FROM candidates UNION SELECT b FROM candidates)
    GROUP BY motion_id
),
agreement AS (
    -- keyed by motion only (a join on frames would let the planner pair every motion's frame k first)
    SELECT c.a, c.b, c.n_frames,
           list_sum(list_transform(range(1, c.n_frames + 1), lambda i: (wa.w[i] = wb.w[i])::INTEGER)) AS same
    FROM candidates c JOIN words wa ON wa.motion_id = c.a JOIN words wb ON wb.motion_id = c.b
    WHERE len(wa.w) = c.n_frames AND len(wb.w) = c.n_frames
)
SELECT g.a AS motion_id, ma.name, g.b AS duplicate_id, mb.name AS duplicate_name, g.n_frames,
       g.same / g.n_frames AS agreement, ma.source_path, mb.source_path AS duplicate_source_path
FROM agreement g JOIN motions ma ON ma.motion_id = g.a JOIN motions mb ON mb.motion_id = g.b
WHERE g.same >= 0.99 * g.n_frames
ORDER BY g.a, g.b;
