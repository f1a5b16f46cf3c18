/* Entry point of mocapdb.duckdb_extension (`LOAD mocapdb`), against DuckDB's stable C
 * extension API (the version set by -DDUCKDB_EXTENSION_API_VERSION_*; docs/EXTENSION.md).
 *
 * The C API gives an extension its database only while it loads. So LOAD opens the two
 * connections that the functions keep for reading the archive (models; features and
 * postings) and registers the functions with the database (every connection sees them).
 * Those connections hold the database until `SELECT mocapdb_release()` (state.c). */
#define DUCKDB_EXTENSION_NAME mocapdb
#include <stdlib.h>

#include "archive.h"
#include "functions.h"

DUCKDB_EXTENSION_ENTRYPOINT_CUSTOM(duckdb_extension_info info, struct duckdb_extension_access *access) {
	duckdb_database *db = access->get_database(info);
	if (!db) {
		return false; /* DuckDB set the error */
	}
	mdb_state *st = mdb_state_new();
	duckdb_connection reg = NULL;
	const char *error = NULL;
	if (!st) {
		access->set_error(info, "mocapdb: out of memory");
		return false;
	}
	if (duckdb_connect(*db, &st->main.con) == DuckDBError || duckdb_connect(*db, &st->data.con) == DuckDBError ||
	    duckdb_connect(*db, &reg) == DuckDBError) {
		error = "mocapdb: could not open a connection to the database";
	} else if (mdb_register_keyframe_words(reg, st) || mdb_register_keyframe_search(reg, st) ||
	           mdb_register_mt_distance(reg, st) || mdb_register_annotate(reg, st) ||
	           mdb_register_similar(reg, st) ||
	           mdb_register_release(reg, st)) {
		error = "mocapdb: registering the SQL functions failed (are they loaded already?)";
	}
	if (reg) {
		duckdb_disconnect(&reg);
	}
	if (error) {
		/* the functions registered before the failure keep the state, released */
		mdb_state_release(st);
		access->set_error(info, error);
	}
	mdb_state_unref(st); /* LOAD's reference: the registered functions hold theirs */
	return error == NULL;
}
