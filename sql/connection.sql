-- Statements of mocapdb.extension.connection (one registration of the SQL functions per database instance).

-- name: instance
-- the token of the registration whose UDFs this database instance has (a
-- Catalog Error when it has none: a fresh instance)
SELECT mocap_instance();
