-- Stand-ins for the keyframe search macros on a database without the keyframe
-- index: they fail with a message that says how to build it.
CREATE OR REPLACE TEMP MACRO keyframe_search_words(masks, vals, gap_min, gap_max,
                                                   extend_left := 0, extend_right := 0) AS TABLE
SELECT error('this database has no keyframe index (schema mocap_index); build it with `mocapdb index` '
             || 'or mocapdb.postings.create_index(con)')::INTEGER AS motion_id,
       NULL::INTEGER AS start_frame, NULL::INTEGER AS end_frame;

CREATE OR REPLACE TEMP MACRO keyframe_search(cls, model := 'default', extend := false) AS TABLE
SELECT * FROM keyframe_search_words([], [], [], []);
