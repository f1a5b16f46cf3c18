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
