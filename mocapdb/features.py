"""The 40 boolean relational features of Müller & Röder (2006) + root angular velocity.

Everything in this module follows FEATURES.md (matrix order §0, primitives §4,
hysteresis §5, per-feature definitions §6).
"""

#: snake_case names in matrix order; bit k-1 of a packed word is feature k
FEATURE_NAMES = (
    "hand_right_to_front_rel_torso", "hand_left_to_front_rel_torso",
    "hand_right_raised_rel_spine", "hand_left_raised_rel_spine",
    "hand_right_to_top_rel_spine", "hand_left_to_top_rel_spine",
    "elbow_right_bent", "elbow_left_bent",
    "hands_apart_rel_shoulders", "hands_move_together",
    "hand_right_move_apart_rel_root", "hand_left_move_apart_rel_root",
    "hand_right_high_vel", "hand_left_high_vel",
    "foot_right_back_rel_leg_left", "foot_left_back_rel_leg_right",
    "foot_right_raised_rel_y_body_min", "foot_left_raised_rel_y_body_min",
    "feet_apart_rel_hips", "knee_right_bent", "knee_left_bent",
    "foot_crossover", "feet_move_together_rel_hips", "feet_move_apart_rel_hips",
    "foot_right_high_vel", "foot_left_high_vel",
    "humerus_right_abduct_rel_spine", "humerus_left_abduct_rel_spine",
    "femur_right_abduct_rel_spine", "femur_left_abduct_rel_spine",
    "root_behind_feet_left_right_neck", "spine_horizontal_rel_y",
    "hand_right_low_rel_y_body_min", "hand_left_low_rel_y_body_min",
    "shoulders_rotated_right_rel_hip", "shoulders_rotated_left_rel_hip",
    "body_extent_rel_y", "body_extent_extremities_rel_x_z",
    "root_high_vel", "root_high_ang_vel",
)
N_FEATURES = 40

#: the toolbox's three feature sets (index per set): name -> (first bit, n bits)
FEATURE_SETS = {"upper": (0, 14), "lower": (14, 12), "mix": (26, 14)}

#: left/right mirror (FEATURES.md §7): mirrored row i = original row MIRROR_FEATURES[i]
MIRROR_FEATURES = tuple(i - 1 for i in (
    2, 1, 4, 3, 6, 5, 8, 7, 9, 10, 12, 11, 14, 13, 16, 15, 18, 17, 19, 21, 20,
    22, 23, 24, 26, 25, 28, 27, 30, 29, 31, 32, 34, 33, 36, 35, 37, 38, 39, 40))

#: the toolbox keeps every 4th native frame (120 Hz -> 30 Hz), whatever the rate
DOWNSAMPLING_FACTOR = 4
