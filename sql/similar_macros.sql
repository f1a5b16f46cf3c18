-- similar_to: temporary macros over the Python UDF mocap_similar, installed with macros.sql on the
-- mocapdb.connect connections without the native extension (MOCAPDB_NATIVE=0, no C compiler at install);
-- native_macros.sql has their twins over the native similar_to (see macros.sql for why macros and UDFs
-- read their own rows).

-- Query by example: the stretches of every motion most like frames
-- first_frame..last_frame (1-based inclusive at 30 Hz; the whole motion without
-- them, NULL) of a motion, k of them: rows (document, motion_id, start_frame,
-- end_frame, start_s, end_s, cost) ranked by cost, none overlapping another or
-- the query. The UDF reads the archive from the keyframe index the connection
-- keeps, a batch of motions at a time (its runs rebuild any stretch): only the
-- motion id and the range travel in.
CREATE OR REPLACE TEMP MACRO mocap_similar_rows(motion, first_frame, last_frame, k) AS TABLE
SELECT mocap_m.name AS document, mocap_r.motion_id, mocap_r.start_frame, mocap_r.end_frame,
       (mocap_r.start_frame - 1) / mocap_m.fps AS start_s, mocap_r.end_frame / mocap_m.fps AS end_s, mocap_r.cost
FROM (SELECT unnest(mocap_similar(
          -- the motion as given and its type: an integer is an id, text a name ('86_09'::INTEGER is 8609,
          -- 3.7::INTEGER is 4: never cast)
          motion::VARCHAR, typeof(motion), first_frame::INTEGER, last_frame::INTEGER, k::INTEGER,
          (SELECT mocap_s.version FROM %index_schema%.state mocap_s)), recursive := true)) mocap_r
JOIN motions mocap_m ON mocap_m.motion_id = mocap_r.motion_id
ORDER BY mocap_r.rank;

-- similar_to(motion [, start_frame, end_frame] [, k := 10]): the user-facing overloads; motion is an id or a
-- name, a NULL range the whole motion
CREATE OR REPLACE TEMP MACRO similar_to(motion, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, NULL, NULL, k)),
  (motion, first_frame, last_frame, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, first_frame, last_frame, k));
