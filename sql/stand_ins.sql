-- The persisted stand-in macros older versions of mocapdb wrote for the names of the native
-- functions (annotate(), mt_distance(), keyframe_search(), keyframe_search_words(): the extension
-- has them, docs/EXTENSION.md). A persisted macro would hide the native function, so they go on
-- every read-write open (mocapdb.storage.schema). Only those the file has are dropped: on an
-- instance that loaded the extension, a bare name the file lacks is the native function, which
-- DuckDB refuses to drop.

-- name: present
SELECT function_name FROM duckdb_functions()
WHERE database_name = current_database() AND schema_name = 'main' AND function_type IN ('macro', 'table_macro')
  AND function_name IN ('annotate', 'mt_distance', 'keyframe_search', 'keyframe_search_words')
ORDER BY function_name;

-- name: annotate
DROP MACRO IF EXISTS annotate;

-- name: mt_distance
DROP MACRO IF EXISTS mt_distance;

-- name: keyframe_search
DROP MACRO TABLE IF EXISTS keyframe_search;

-- name: keyframe_search_words
DROP MACRO TABLE IF EXISTS keyframe_search_words;
