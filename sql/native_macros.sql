-- The named-argument forms of the native extension's scalar functions, on every mocapdb.connect
-- connection whose database loaded it (docs/EXTENSION.md). A scalar function of DuckDB's C API
-- takes positional arguments only; these temporary macros shadow the native names on the
-- connection and call the native functions by their qualified names (the extension registers
-- them in the system catalog). keyframe_search and keyframe_search_words are native table
-- functions with their named arguments: no macro. similar_to is a native scalar function returning a
-- list; the table macros of the same name below give its rows.

-- Δ of a class template against a motion (see macros.sql).
CREATE OR REPLACE TEMP MACRO mt_distance(motion, cls, model := 'default') AS
    system.main.mt_distance(motion, cls, model);

-- Labelled segments of a motion (see macros.sql). A NULL tau uses each class's τ; a NULL keyframes
-- preselects when the model has keyframe queries.
CREATE OR REPLACE TEMP MACRO annotate(motion, model := 'default', tau := NULL, keyframes := NULL) AS
    system.main.annotate(motion, model, tau, keyframes);

-- Query by example (see similar_macros.sql, the Python UDF's form): the native similar_to(motion,
-- first_frame, last_frame, k) returns the ranked list; these table macros give its rows with the names
-- and seconds. The motion's type is checked here too, to name the value in the message (the native
-- function refuses every type but integers and text: no cast turns '86_09' into 8609 or 3.7 into 4).
CREATE OR REPLACE TEMP MACRO mocap_similar_rows(motion, first_frame, last_frame, k) AS TABLE
SELECT mocap_m.name AS document, mocap_r.motion_id, mocap_r.start_frame, mocap_r.end_frame,
       (mocap_r.start_frame - 1) / mocap_m.fps AS start_s, mocap_r.end_frame / mocap_m.fps AS end_s, mocap_r.cost
FROM (SELECT unnest(system.main.similar_to(
          CASE WHEN motion IS NULL OR typeof(motion) IN ('TINYINT', 'SMALLINT', 'INTEGER', 'BIGINT', 'HUGEINT',
                    'UTINYINT', 'USMALLINT', 'UINTEGER', 'UBIGINT', 'UHUGEINT', 'VARCHAR') THEN motion
               ELSE error('similar_to: motion must be a motion id (an integer) or a name, got '
                          || motion::VARCHAR || ' (' || typeof(motion) || ')') END,
          first_frame::INTEGER, last_frame::INTEGER, k::INTEGER), recursive := true)) mocap_r
JOIN motions mocap_m ON mocap_m.motion_id = mocap_r.motion_id
ORDER BY mocap_r.rank;

-- similar_to(motion [, start_frame, end_frame] [, k := 10]): the user-facing overloads; motion is an id or a
-- name, a NULL range the whole motion
CREATE OR REPLACE TEMP MACRO similar_to(motion, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, NULL, NULL, k)),
  (motion, first_frame, last_frame, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, first_frame, last_frame, k));
