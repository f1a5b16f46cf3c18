-- The SQL functions as Python UDFs, the fallback where the native extension is
-- missing (docs/EXTENSION.md; native_macros.sql where it is loaded): temporary
-- macros installed on every mocapdb.connect, because they call Python UDFs,
-- which exist only on connections where Python registered them. Each passes the motion id, the model's fingerprint and the
-- index version in; the UDF reads the motions' words (and postings) itself, a
-- batch of motions at a time, and keeps models parsed per connection,
-- re-reading one only when its fingerprint changed. (A `list(bits ORDER BY
-- frame)` subquery here would be decorrelated by DuckDB into one aggregate of
-- every motion's words: memory that grows with the archive.) The UDFs read
-- committed data: a motion inserted in a transaction not yet committed is
-- unknown to them (NULL). Parameter names differ from every column
-- the bodies read (DuckDB rejects the clash); table aliases are prefixed
-- mocap_ so that an argument such as m.motion_id cannot be captured by an
-- alias of the body (macros expand textually).

-- Δ of a class template against a motion: one DOUBLE per 30 Hz frame, inf
-- where no template match can end. NULL for a NULL or unknown motion.
CREATE OR REPLACE TEMP MACRO mt_distance(motion, cls, model := 'default') AS
    mocap_mt_distance(
        motion::INTEGER,
        model,
        (SELECT mocap_v.fingerprint FROM model_fingerprints mocap_v WHERE mocap_v.model_name = model),
        cls);

-- Labelled segments of a motion: LIST(STRUCT(label, start_frame, end_frame,
-- cost, start_s, end_s)), frames 1-based at 30 Hz. A NULL tau uses each
-- class's τ; a NULL keyframes preselects when the model has keyframe queries.
CREATE OR REPLACE TEMP MACRO annotate(motion, model := 'default', tau := NULL, keyframes := NULL) AS
    mocap_annotate(
        motion::INTEGER,
        model,
        (SELECT mocap_v.fingerprint FROM model_fingerprints mocap_v WHERE mocap_v.model_name = model),
        tau::DOUBLE, keyframes::BOOLEAN,
        (SELECT mocap_s.version FROM %index_schema%.state mocap_s));

-- Segments of every motion that contain a class's keyframe chain: rows
-- (motion_id, start_frame, end_frame), 1-based inclusive 30 Hz frames.
-- extend := true widens every hit by the annotation margins 2·(pos₁ − 1) and
-- 2·(L − pos_K) (TEMPLATES.md §10).
CREATE OR REPLACE TEMP MACRO keyframe_search(cls, model := 'default', extend := false) AS TABLE
SELECT unnest(mocap_keyframe_search(
    model,
    (SELECT mocap_v.fingerprint FROM model_fingerprints mocap_v WHERE mocap_v.model_name = model),
    cls, extend::BOOLEAN,
    (SELECT mocap_s.version FROM %index_schema%.state mocap_s)), recursive := true);

-- The same for an inline query: keyframes as 40-bit (mask, value) words (a
-- frame matches iff bits & mask = value), gap bounds between consecutive
-- keyframes in 30 Hz frames (a NULL d_max is unbounded). Limits: see docs/USER_GUIDE.md (SQL).
CREATE OR REPLACE TEMP MACRO keyframe_search_words(masks, vals, gap_min, gap_max,
                                                   extend_left := 0, extend_right := 0) AS TABLE
SELECT unnest(mocap_keyframe_search_words(
    masks::UBIGINT[], vals::UBIGINT[], gap_min::BIGINT[], gap_max::BIGINT[],
    extend_left::BIGINT, extend_right::BIGINT,
    (SELECT mocap_s.version FROM %index_schema%.state mocap_s)), recursive := true);
