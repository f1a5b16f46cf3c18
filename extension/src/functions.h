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
int mdb_register_annotate(duckdb_connection con, mdb_state *st);
int mdb_register_similar(duckdb_connection con, mdb_state *st);

/* Intervals of matching frames of one keyframe (word & mask == value) in one motion's runs
 * r[a..b), appended to iv; 0, or -1 when out of memory. */
int mdb_keyframe_intervals(const mdb_runs *r, size_t a, size_t b, uint64_t mask, uint64_t value, mdb_spans *iv);

#endif
