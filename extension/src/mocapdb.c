/* Entry point of mocapdb.duckdb_extension (`LOAD mocapdb`), against DuckDB's stable C
 * extension API (the version set by -DDUCKDB_EXTENSION_API_VERSION_*; docs/EXTENSION.md).
 *
 * The C API gives an extension its database only while it loads. So LOAD opens one
 * connection that the functions keep for reading the archive (models, features,
 * postings) and registers the functions with the database (every connection sees them).
 * That connection holds the database: it stays open until the process ends. */
#define DUCKDB_EXTENSION_NAME mocapdb
#include <stdlib.h>

#include "archive.h"
#include "functions.h"

DUCKDB_EXTENSION_ENTRYPOINT_CUSTOM(duckdb_extension_info info, struct duckdb_extension_access *access) {
	duckdb_database *db = access->get_database(info);
	if (!db) {
		return false; /* DuckDB set the error */
	}
	mdb_state *st = calloc(1, sizeof *st);
	duckdb_connection reg = NULL;
	if (!st || pthread_mutex_init(&st->lock, NULL)) {
		free(st);
		access->set_error(info, "mocapdb: out of memory");
		return false;
	}
	if (duckdb_connect(*db, &st->con) == DuckDBError || duckdb_connect(*db, &reg) == DuckDBError) {
		access->set_error(info, "mocapdb: could not open a connection to the database");
		return false;
	}
	int failed = mdb_register_keyframe_words(reg, st) || mdb_register_keyframe_search(reg, st) ||
	             mdb_register_mt_distance(reg, st);
	duckdb_disconnect(&reg);
	if (failed) {
		access->set_error(info, "mocapdb: registering the SQL functions failed (are they loaded already?)");
		return false;
	}
	return true;
}
