-- Keyframe search macros, installed on every mocapdb.connect when the keyframe
-- index (schema mocap_index) exists; sql/keyframe_macros_missing.sql otherwise.
-- Parameter names and mocap_ aliases as in macros.sql.

-- Keyframe search with an inline query: keyframes as 40-bit (mask, value)
-- words (a frame matches iff bits & mask = value), gap bounds between
-- consecutive keyframes in 30 Hz frames (a NULL d_max is unbounded).
-- Rows (motion_id, start_frame, end_frame), 1-based inclusive 30 Hz frames.
-- The fuzzy match runs here, on the 40-bit postings; the chain search in Python.
CREATE OR REPLACE TEMP MACRO keyframe_search_words(masks, vals, gap_min, gap_max,
                                                   extend_left := 0, extend_right := 0) AS TABLE
SELECT mocap_h.motion_id, mocap_h.start_frame, mocap_h.end_frame
FROM (SELECT unnest(mocap_keyframe_search(
        len(masks), gap_min, gap_max,
        (SELECT list({k: mocap_q.k, motion_id: mocap_p.motion_id, start_frame: mocap_p.start_frame,
                      n_frames: mocap_p.n_frames})
         FROM mocap_index.postings mocap_p
         JOIN (SELECT unnest(range(len(masks))) AS k, unnest(masks)::UBIGINT AS mask,
                      unnest(vals)::UBIGINT AS value) mocap_q
           ON (mocap_p.word & mocap_q.mask) = mocap_q.value
         WHERE mocap_p.feature_set = 'full'),
        (SELECT list({motion_id: mocap_m.motion_id, n_frames: mocap_m.n_frames}) FROM motions mocap_m),
        extend_left, extend_right), recursive := true)) mocap_h;

-- Keyframe search with a class's stored query. extend := true widens every hit
-- by the annotation margins 2·(pos₁ − 1) and 2·(L − pos_K) (TEMPLATES.md §10).
CREATE OR REPLACE TEMP MACRO keyframe_search(cls, model := 'default', extend := false) AS TABLE
SELECT mocap_r.* FROM (
    SELECT mocap_u.c.keyframes AS kf FROM model_payload mocap_p, unnest(mocap_p.classes) AS mocap_u(c)
    WHERE mocap_p.model_name = model AND mocap_u.c.class = cls AND mocap_u.c.keyframes IS NOT NULL
) mocap_k, keyframe_search_words(
    mocap_k.kf.mask, mocap_k.kf.value, mocap_k.kf.d_min,
    list_transform(mocap_k.kf.d_max, lambda x: CASE WHEN x < 0 THEN NULL ELSE x END),
    extend_left := CASE WHEN extend THEN 2 * (mocap_k.kf.positions[1] - 1) ELSE 0 END,
    extend_right := CASE WHEN extend THEN 2 * (mocap_k.kf.template_length - mocap_k.kf.positions[-1]) ELSE 0 END
) mocap_r;
