-- Statements of mocapdb.storage.ingest_log (the ingest_log table of sql/schema.sql).

-- name: next_run
SELECT nextval('ingest_run_seq');

-- name: insert
INSERT INTO ingest_log (run_id, command, path, member, outcome, reason, notes, motion_id)
SELECT run_id, command, path, member, outcome, reason, notes, motion_id FROM mocap_new_log ORDER BY ord;

-- name: run
-- the rows of one call, by file
SELECT path, member, outcome, reason, notes, motion_id, logged_at, run_id, command
FROM ingest_log WHERE run_id = $run_id ORDER BY path, member NULLS FIRST, rowid;
