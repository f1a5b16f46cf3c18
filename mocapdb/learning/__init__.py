"""Learning (paper Sect. 3 training, Sect. 6 keyframes): models from labelled clips.

:mod:`~mocapdb.learning.class_templates` (one template per class),
:mod:`~mocapdb.learning.genetic`, :mod:`~mocapdb.learning.ga_operators` and
:mod:`~mocapdb.learning.keyframe_learning` (keyframe queries by the genetic
algorithm), :mod:`~mocapdb.learning.toolbox_queries` (the toolbox's own queries),
:mod:`~mocapdb.learning.confidence_maps` (calibrated confidence from held-out segments).
"""
from mocapdb.learning.class_templates import (clip_actor, clip_files, clips_from_folders, clips_from_segments, read_clip, train_model)
from mocapdb.learning.genetic import (GA_DEFAULTS, GAResult, GAStatistics, evolve_keyframes, f_beta, fitness_from_hits, fixed_entries, training_index)
from mocapdb.learning.ga_operators import (MUTATIONS, gap_bounds, mutate, random_query, recombine, stochastic_universal_sampling)
from mocapdb.learning.keyframe_learning import (LearnedQuery, average_statistics, consensus_pick, consensus_scores, learn_keyframe_queries, learn_keyframe_query)
from mocapdb.learning.confidence_maps import fit_confidence_maps
from mocapdb.learning.toolbox_queries import (has_toolbox_query, read_toolbox_query, toolbox_keyframe_queries)

__all__ = [
    "train_model", "clip_files", "clip_actor", "read_clip", "clips_from_folders", "clips_from_segments",
    "GAResult", "GAStatistics", "GA_DEFAULTS", "evolve_keyframes", "f_beta", "fitness_from_hits",
    "fixed_entries", "training_index", "MUTATIONS", "gap_bounds", "mutate", "random_query", "recombine",
    "stochastic_universal_sampling", "LearnedQuery", "average_statistics", "consensus_pick",
    "consensus_scores", "learn_keyframe_queries", "learn_keyframe_query", "read_toolbox_query",
    "toolbox_keyframe_queries", "has_toolbox_query", "fit_confidence_maps",
]
