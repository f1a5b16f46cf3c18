-- The named-argument forms of the native extension's scalar functions, on every mocapdb.connect
-- connection whose database loaded it (docs/EXTENSION.md). A scalar function of DuckDB's C API
-- takes positional arguments only; these temporary macros shadow the native names on the
-- connection and call the native functions by their qualified names (the extension registers
-- them in the system catalog). keyframe_search and keyframe_search_words are native table
-- functions with their named arguments: no macro. similar_to is a native scalar function returning a
-- list; the table macros of the same name (similar_rows.sql) give its rows.

-- Δ of a class template against a motion (see macros.sql).
CREATE OR REPLACE TEMP MACRO mt_distance(motion, cls, model := 'default') AS
    system.main.mt_distance(motion, cls, model);

-- Labelled segments of a motion (see macros.sql). A NULL tau uses each class's τ; a NULL keyframes
-- preselects when the model has keyframe queries.
CREATE OR REPLACE TEMP MACRO annotate(motion, model := 'default', tau := NULL, keyframes := NULL) AS
    system.main.annotate(motion, model, tau, keyframes);

-- Query by example: the ranked list of the native similar_to (its rows and the similar_to overloads are
-- similar_rows.sql's). The motion's type is checked here too, to name the value in the message (the
-- native function refuses every type but integers and text: no cast turns '86_09' into 8609 or 3.7 into 4).
CREATE OR REPLACE TEMP MACRO mocap_similar_rows(motion, first_frame, last_frame, k) AS TABLE
SELECT * FROM mocap_similar_view(system.main.similar_to(
    CASE WHEN motion IS NULL OR typeof(motion) IN ('TINYINT', 'SMALLINT', 'INTEGER', 'BIGINT', 'HUGEINT',
              'UTINYINT', 'USMALLINT', 'UINTEGER', 'UBIGINT', 'UHUGEINT', 'VARCHAR') THEN motion
         ELSE error('similar_to: motion must be a motion id (an integer) or a name, got '
                    || motion::VARCHAR || ' (' || typeof(motion) || ')') END,
    first_frame::INTEGER, last_frame::INTEGER, k::INTEGER));
