-- Settings of a mocapdb database instance (mocapdb.storage.schema.open_database).

-- name: memory_limit
-- GLOBAL: the limit is the database instance's, shared by its connections
SET GLOBAL memory_limit = $memory_limit;
