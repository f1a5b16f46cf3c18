-- The named-argument forms of the native extension's scalar functions, on every mocapdb.connect
-- connection whose database loaded it (docs/EXTENSION.md). A scalar function of DuckDB's C API
-- takes positional arguments only; these temporary macros shadow the native names on the
-- connection and call the native functions by their qualified names (the extension registers
-- them in the system catalog). keyframe_search and keyframe_search_words are native table
-- functions with their named arguments: no macro.

-- Δ of a class template against a motion (see macros.sql).
CREATE OR REPLACE TEMP MACRO mt_distance(motion, cls, model := 'default') AS
    system.main.mt_distance(motion, cls, model);

-- Labelled segments of a motion (see macros.sql). A NULL tau uses each class's τ; a NULL keyframes
-- preselects when the model has keyframe queries.
CREATE OR REPLACE TEMP MACRO annotate(motion, model := 'default', tau := NULL, keyframes := NULL) AS
    system.main.annotate(motion, model, tau, keyframes);
