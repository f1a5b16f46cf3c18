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

/* most members of a struct type of mdb_struct_list_type */
#define MDB_MAX_STRUCT_MEMBERS 16
/* LIST(STRUCT(names[i] ids[i], …)) of n members (types.c); the caller destroys it. */
duckdb_logical_type mdb_struct_list_type(const char **names, const duckdb_type *ids, size_t n);

/* Intervals of matching frames of one keyframe (word & mask == value) in one motion's runs
 * r[a..b), appended to iv; 0, or -1 when out of memory. */
int mdb_keyframe_intervals(const mdb_runs *r, size_t a, size_t b, uint64_t mask, uint64_t value, mdb_spans *iv);

#endif
