"""Relational features (paper Sect. 2, FEATURES.md): 24 joints → 40 booleans per frame → packed 30 Hz words.

:mod:`~mocapdb.features.relational` computes the features at the native rate
(body units, smoothed velocities, lenient/strict tests, hysteresis);
:mod:`~mocapdb.features.pipeline` gives a take's words in one kernel call
(:func:`motion_features`);
:mod:`~mocapdb.features.words` holds everything on packed words (downsampling,
packing, runs, mirroring, time reversal).
"""
from mocapdb.features.relational import (FEATURE_THRESHOLDS, ROOT_ANG_VEL_THRESHOLDS_ALT, SMOOTHING_MS,
                                         heading_turned, hysteresis, relational_features, smoothing_window)
from mocapdb.features.pipeline import motion_features
from mocapdb.features.rates import (FEATURE_RATE, RATE_METHODS, TOOLBOX_RATE, feature_frame_count, feature_grid,
                                    grid_source_frames, resample_joints)
from mocapdb.features.words import (DERIVED_FEATURE_NAMES, MIRROR_BITS, N_BITS, WORD_FEATURE_NAMES,
                                    DOWNSAMPLING_FACTOR, FEATURE_NAMES, FEATURE_SETS, MIRROR_FEATURES, N_FEATURES,
                                    SET_BITS, as_doc_lengths, as_words, downsample, feature_runs, mirror_words,
                                    pack_words, segment_runs, unpack_words, reverse_fuzzy_words, DIRECTION_FEATURES,
                                    REVERSE_SWAP)

__all__ = [
    "FEATURE_NAMES", "N_FEATURES", "DERIVED_FEATURE_NAMES", "N_BITS", "WORD_FEATURE_NAMES", "MIRROR_BITS",
    "heading_turned", "FEATURE_SETS", "SET_BITS", "MIRROR_FEATURES", "DOWNSAMPLING_FACTOR",
    "FEATURE_THRESHOLDS", "SMOOTHING_MS", "ROOT_ANG_VEL_THRESHOLDS_ALT",
    "relational_features", "hysteresis", "smoothing_window", "motion_features",
    "downsample", "pack_words", "unpack_words", "feature_runs", "segment_runs", "mirror_words",
    "as_words", "as_doc_lengths", "FEATURE_RATE", "TOOLBOX_RATE", "RATE_METHODS", "feature_frame_count",
    "feature_grid", "grid_source_frames", "resample_joints", "reverse_fuzzy_words", "DIRECTION_FEATURES",
    "REVERSE_SWAP",
]
