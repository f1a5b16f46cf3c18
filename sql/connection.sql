-- Statements of mocapdb.extension.connection (one registration of the SQL functions per database instance).

-- name: instance
-- the token of the registration whose UDFs this database instance has (a
-- Catalog Error when it has none: a fresh instance)
SELECT mocap_instance();

-- name: release
-- the native extension lets go of the database (its own connection and caches): the file closes
-- with its last connection (docs/EXTENSION.md)
SELECT mocapdb_release();

-- name: load
-- the native extension (its path; unsigned: the connection allows that, storage/schema.OPEN_CONFIG)
LOAD '%extension%';
