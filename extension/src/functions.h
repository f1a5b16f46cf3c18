/* The SQL functions of the native extension, registered at LOAD. */
#ifndef MOCAPDB_FUNCTIONS_H
#define MOCAPDB_FUNCTIONS_H

#include "archive.h"

/* largest finite gap bound and margin of an inline keyframe query, as mocapdb.extension.udfs.MAX_GAP */
#define MDB_MAX_GAP (30 * 3600)
/* as mocapdb.storage.motions.BATCH_FRAMES: frames of motions read per batch */
#define MDB_BATCH_FRAMES 1000000

int mdb_register_keyframe_words(duckdb_connection con, mdb_state *st);
int mdb_register_keyframe_search(duckdb_connection con, mdb_state *st);
int mdb_register_mt_distance(duckdb_connection con, mdb_state *st);

#endif
