-- How a plain DuckDB user finds the SQL functions (run on every read-write
-- open, after schema.sql and views.sql, which recreate the views).
--
-- The SQL functions are native in the extension (mocapdb.connect loads it; LOAD it in any other
-- DuckDB client; Python UDFs where it is missing); every table says where it comes from
-- (SELECT table_name, comment FROM duckdb_tables()).

COMMENT ON TABLE motions IS 'mocapdb: one row per recording. The SQL functions annotate(), mt_distance(), keyframe_search(), keyframe_search_words() are on connections from mocapdb.connect() (Python) and in the native extension (LOAD the file `mocapdb extension-path` prints).';
COMMENT ON TABLE features IS 'mocapdb: the 40 relational features of every 30 Hz frame, packed (bit k-1 = feature k). annotate() and the other SQL functions: open the file with mocapdb.connect(), `mocapdb --db FILE sql`, or LOAD the native extension.';
COMMENT ON VIEW feature_flags IS 'mocapdb: the 40 features as named BOOLEAN columns.';
COMMENT ON VIEW duplicates IS 'mocapdb: near-duplicate takes: pairs of motions of as many frames whose feature words agree on at least 99 % of them (the same take at another scale or unit, or exported again).';
COMMENT ON TABLE models IS 'mocapdb: class models (the shipped default and toolbox, and trained ones). annotate(motion_id, model := ...) on mocapdb.connect() connections; annotate(motion_id, model) with the native extension.';
COMMENT ON TABLE classes IS 'mocapdb: the fine classes of each model with label, δ, τ and minimum length.';
COMMENT ON TABLE templates IS 'mocapdb: motion template columns of each class, quantized as (mask, value) words.';
COMMENT ON TABLE keyframe_queries IS 'mocapdb: one keyframe query per class and model.';
COMMENT ON TABLE keyframes IS 'mocapdb: the keyframes of each keyframe query, with gap bounds in 30 Hz frames.';
COMMENT ON TABLE confidence_maps IS 'mocapdb: per label of a model, the step function from a segment''s score (its raw score, and its length by length_weight: multiplying the raw score where length_product, else added) to its calibrated confidence (share right on held-out recordings).';
COMMENT ON TABLE ga_statistics IS 'mocapdb: per-generation statistics of the genetic algorithm that learned keyframe queries.';
COMMENT ON TABLE annotations IS 'mocapdb: stored results of `mocapdb annotate`; fresh ones from annotate(motion_id) on a connection from mocapdb.connect() or `mocapdb --db FILE sql`.';
COMMENT ON TABLE ingest_log IS 'mocapdb: one row per file an ingest or import-features looked at: path, archive member, outcome (ingested, skipped, failed, not a motion file), reason, the reader''s notes, motion_id, time; run_id groups a call.';
