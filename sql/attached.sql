-- Statements of mocapdb.storage.attached: a database whose motions, features,
-- annotations and keyframe index are views over a ray-annotate archive's
-- Parquet. A view cannot take parameters, so the archive's path is written
-- into the views' text (%archive%: quotes doubled, see mocapdb.storage.sqltext).

-- name: is_attached
SELECT count(*) > 0 FROM duckdb_tables() WHERE schema_name = 'main' AND table_name = 'mocap_archive';

-- name: archive_root
SELECT root FROM mocap_archive;

-- name: own_rows
SELECT (SELECT count(*) FROM motions) + (SELECT count(*) FROM annotations);

-- name: drop_tables
-- the empty tables of a new database give way to the views
DROP TABLE features;
DROP TABLE annotations;
DROP TABLE motions;
DROP TABLE %index_schema%.postings;
DROP TABLE %index_schema%.state;

-- name: views
-- the datasets as ray-annotate writes them (mocapdb.distributed.layout); temporary
-- files start with a dot and are not matched; motion_bucket is the folder, not a column
CREATE OR REPLACE VIEW motions AS
SELECT * FROM read_parquet('%archive%/motions/*.parquet');
CREATE OR REPLACE VIEW features AS
SELECT motion_id, frame, bits FROM read_parquet('%archive%/features/*/*.parquet', hive_partitioning = true);
CREATE OR REPLACE VIEW annotations AS
SELECT * EXCLUDE (motion_bucket) FROM read_parquet('%archive%/annotations/*/*.parquet', hive_partitioning = true);
CREATE OR REPLACE VIEW %index_schema%.postings AS
SELECT * EXCLUDE (motion_bucket) FROM read_parquet('%archive%/postings/*/*.parquet', hive_partitioning = true);
-- the index version: a new run of the archive (a new manifest) is a new version
CREATE OR REPLACE VIEW %index_schema%.state AS
SELECT (hash(content) >> 1)::BIGINT AS version FROM read_text('%archive%/manifest.json');
CREATE OR REPLACE TABLE mocap_archive AS SELECT '%archive%' AS root, current_timestamp AS attached_at;

-- name: settings
-- keep the Parquet footers read: a batch of motions reads the statistics of every part
SET GLOBAL parquet_metadata_cache = true;
