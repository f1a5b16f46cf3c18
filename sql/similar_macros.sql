-- similar_to over the Python UDF mocap_similar, installed with macros.sql on the mocapdb.connect
-- connections without the native extension (MOCAPDB_NATIVE=0, no C compiler at install); its rows and
-- overloads are similar_rows.sql's (see macros.sql for why macros and UDFs read their own rows).

-- The ranked list of the query (similar_rows.sql). The UDF reads the archive from the keyframe index the
-- connection keeps, a batch of motions at a time (its runs rebuild any stretch): only the motion id and
-- the range travel in.
CREATE OR REPLACE TEMP MACRO mocap_similar_rows(motion, first_frame, last_frame, k) AS TABLE
SELECT * FROM mocap_similar_view(mocap_similar(
    -- the motion as given and its type: an integer is an id, text a name ('86_09'::INTEGER is 8609,
    -- 3.7::INTEGER is 4: never cast)
    motion::VARCHAR, typeof(motion), first_frame::INTEGER, last_frame::INTEGER, k::INTEGER,
    (SELECT mocap_s.version FROM %index_schema%.state mocap_s)));
