/* What a query by example reads from the archive through the extension's connection (similar.c,
 * similar_search.c): the motion named, the query stretch's words, the ranked motions and their
 * lengths, the archive sample, whether the keyframe index is built. Every read is one query. */
#ifndef MOCAPDB_SIMILAR_READ_H
#define MOCAPDB_SIMILAR_READ_H

#include <stdint.h>

#include "archive.h"

#define MDB_SIM_WHAT "similar_to"
/* an integer motion argument beyond int64: no motion has it */
#define MDB_SIM_BEYOND INT64_MIN

/* motion ids (ascending) with their frame counts */
typedef struct {
	int32_t *id;
	int64_t *len;
	size_t n, cap;
} mdb_sim_motions;

/* packed 30 Hz words */
typedef struct {
	uint64_t *w;
	size_t n, cap;
} mdb_sim_words;

void mdb_sim_motions_free(mdb_sim_motions *l);
/* The "out of memory" error of similar_to; -1. */
int mdb_sim_oom(mdb_error *err);
/* The motions whose feature rows are their frames 1 … n, ascending (mocapdb.storage.retrieval's
 * _whole_motions: only they are ranked). */
int mdb_sim_read_motions(mdb_state *st, mdb_sim_motions *out, mdb_error *err);
/* The archive sample: every motion's frames whose 1-based number is a multiple of step. */
int mdb_sim_read_sample(mdb_state *st, int32_t step, mdb_sim_words *out, mdb_error *err);
/* 0 when the keyframe index is built, else -1 with the error saying how to build it. */
int mdb_sim_check_index(mdb_state *st, mdb_error *err);
/* one_motion: the id of the one motion a name names (all digits: the id itself). */
int mdb_sim_resolve_name(mdb_state *st, const char *name, int64_t *id, mdb_error *err);
/* query_stretch and check_range: motion id's range (1-based first_frame .. last_frame; absent: its
 * first or last frame) as 0-based *first .. *last, its words read into w (w->w + *first on). */
int mdb_sim_query_stretch(mdb_state *st, int64_t id, int has_first, int32_t first_frame, int has_last,
                          int32_t last_frame, int64_t *first, int64_t *last, mdb_sim_words *w, mdb_error *err);

#endif
