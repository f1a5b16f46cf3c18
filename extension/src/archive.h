/* Reading an archive written by `mocapdb ingest` through the extension's own
 * connection: the motions' lengths and a batch of motions' keyframe-index runs. */
#ifndef MOCAPDB_ARCHIVE_H
#define MOCAPDB_ARCHIVE_H

#include <pthread.h>
#include <stdint.h>

#include "chain.h"
#include "distance.h"
#include "duckdb_extension.h"

/* What a loaded extension keeps per database: a connection of its own (opened at
 * LOAD; the C API hands the database out only then) and the lock that serialises
 * its use (a DuckDB connection runs one query at a time). */
struct mdb_batch;

typedef struct {
	duckdb_connection con;
	pthread_mutex_t lock;
	struct mdb_batch *cache; /* index batches read, newest first (see mdb_acquire_runs) */
	size_t cache_bytes;
} mdb_state;

/* The stored motions, ascending ids, with their 30 Hz frame counts. */
typedef struct {
	int32_t *id;
	int64_t *n_frames;
	size_t n;
} mdb_motions;

/* The 40-bit-word runs of a batch of motions, in (motion, run) order. */
typedef struct {
	int32_t *motion;
	uint64_t *word;
	int64_t *start; /* 0-based first frame */
	int64_t *len;
	size_t n;
	size_t cap;
} mdb_runs;

/* A batch of motions' runs as read at one index version, shared by the queries using it. */
typedef struct mdb_batch {
	int64_t version;
	int32_t lo, hi;
	mdb_runs runs;
	int refs;     /* queries holding it */
	int detached; /* no longer in the cache: freed by its last release */
	struct mdb_batch *next;
} mdb_batch;

/* Error text of the archive functions (set when they return non-zero). */
typedef struct {
	char text[512];
} mdb_error;

void mdb_motions_free(mdb_motions *m);
/* The runs of motions lo .. hi (ids, inclusive) of the 'full' part of the index, in (motion,
 * run) order: from the cache while the index version is the same (a bounded number of bytes,
 * so memory stays flat in archive size), else read. NULL after an error. Give it back with
 * mdb_release_runs. */
mdb_batch *mdb_acquire_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_error *err);
void mdb_release_runs(mdb_state *st, mdb_batch *b);
void mdb_runs_free(mdb_runs *r);

/* A class's quantized template of a model, prepared for mdb_mt_distance. An unknown model or
 * class is an error naming it and what the database has. */
int mdb_read_template(mdb_state *st, const char *model, const char *cls, mdb_template *out, mdb_error *err);
/* A class's stored keyframe query (keyframes, keyframe_queries), widened by the annotation margins
 * 2·(pos_1 - 1) and 2·(L - pos_K) when extend. An unknown model or class, or a class without a
 * query, is an error naming it. */
int mdb_read_keyframe_query(mdb_state *st, const char *model, const char *cls, int extend, mdb_query *out,
                            mdb_error *err);
/* The stored motions with ids lo .. hi, ascending, with their frame counts. */
int mdb_read_motion_range(mdb_state *st, int32_t lo, int32_t hi, mdb_motions *out, mdb_error *err);
/* The packed 30 Hz words of the motions want[0 .. n_want) (ascending ids within lo .. hi, each of
 * n_frames[i] frames) into words + off[i]. A motion whose features are not its frames 1 .. n is an
 * error naming it. */
int mdb_read_words(mdb_state *st, int32_t lo, int32_t hi, const int32_t *want, const int64_t *n_frames,
                   const size_t *off, size_t n_want, uint64_t *words, mdb_error *err);

#endif
