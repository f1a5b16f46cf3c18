-- similar_to's rows, over either similar function: the table macros every mocapdb.connect connection
-- gets around the definition of mocap_similar_rows(motion, first_frame, last_frame, k) — the Python
-- UDF's (similar_macros.sql) or the native function's (native_macros.sql), over the ranked list
-- LIST(STRUCT(rank, motion_id, start_frame, end_frame, cost)). DuckDB binds a table macro's functions
-- when it is created: the view comes before mocap_similar_rows, the overloads after.

-- name: view
-- Query by example: the stretches of every motion most like frames first_frame..last_frame (1-based
-- inclusive at 30 Hz; the whole motion without them, NULL) of a motion, k of them: rows (document,
-- motion_id, start_frame, end_frame, start_s, end_s, cost) ranked by cost, none overlapping another or
-- the query, from the ranked list hits.
CREATE OR REPLACE TEMP MACRO mocap_similar_view(hits) AS TABLE
SELECT mocap_m.name AS document, mocap_r.motion_id, mocap_r.start_frame, mocap_r.end_frame,
       (mocap_r.start_frame - 1) / mocap_m.fps AS start_s, mocap_r.end_frame / mocap_m.fps AS end_s, mocap_r.cost
FROM (SELECT unnest(hits, recursive := true)) mocap_r
JOIN motions mocap_m ON mocap_m.motion_id = mocap_r.motion_id
ORDER BY mocap_r.rank;

-- name: overloads
-- similar_to(motion [, start_frame, end_frame] [, k := 10]): the user-facing overloads; motion is an id or a
-- name, a NULL range the whole motion
CREATE OR REPLACE TEMP MACRO similar_to(motion, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, NULL, NULL, k)),
  (motion, first_frame, last_frame, k := 10) AS TABLE (
    SELECT * FROM mocap_similar_rows(motion, first_frame, last_frame, k));
