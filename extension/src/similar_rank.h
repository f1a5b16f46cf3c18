/* Ranking a query by example on archive words (mocapdb.retrieval.search.rank_slices and
 * search_segments, mocapdb.retrieval.hits): Δ of the weighted template on word slices, coarse to
 * fine, and the non-overlapping hits below τ, cheapest first. Pure C over arrays, no DuckDB. */
#ifndef MOCAPDB_SIMILAR_RANK_H
#define MOCAPDB_SIMILAR_RANK_H

#include <stddef.h>
#include <stdint.h>

#include "distance.h"
#include "similar_plan.h"

/* one hit: doc (a slice, a segment's document, a motion), frames 0-based inclusive */
typedef struct {
	int64_t doc, start, end;
	double cost;
} mdb_sim_hit;

typedef struct {
	mdb_sim_hit *at;
	size_t n, cap;
} mdb_sim_hits;

void mdb_sim_hits_free(mdb_sim_hits *h);
/* Append one hit; 0, or -1 when out of memory. */
int mdb_sim_hits_push(mdb_sim_hits *h, mdb_sim_hit x);
/* Sort by (cost, doc, start) and keep the first limit (best_hits). */
void mdb_sim_hits_best(mdb_sim_hits *h, int64_t limit);

/* A planned query: the template, its coarse version (every step-th column; step 1: none), τ. */
typedef struct {
	const mdb_sim_template *t, *sparse;
	size_t step;
	double tau;
} mdb_sim_ranker;

/* rank_slices: the best non-overlapping hits on the slices [ta[q], tb[q]) of words (ascending,
 * disjoint), none touching a frame marked in taken (NULL: none), at most limit, appended to out
 * sorted by (cost, slice, start) with doc = the slice, start/end word indices. 0, or -1 when out of
 * memory. */
int mdb_sim_rank_slices(const mdb_sim_ranker *r, const uint64_t *words, size_t n_words, const int64_t *ta,
                        const int64_t *tb, size_t n, const uint8_t *taken, int64_t limit, mdb_sim_hits *out);

/* The words of segments: out[Σ (stop − start)] for segments doc/start/stop[0 .. n); 0 or -1 (err set). */
typedef int (*mdb_sim_fetch)(void *ctx, const int64_t *doc, const int64_t *start, const int64_t *stop, size_t n,
                             uint64_t *out);

/* search_segments: rank on segments (doc, [start, stop)) a window of MDB_SIM_RANK_BATCH frames at a
 * time, none overlapping the stretch (ex_doc, ex_first .. ex_last) (ex_doc < 0: none); the best
 * limit into out (doc = the segment's document, frames within it), by (cost, doc, start). 0, -1
 * when out of memory, -2 when fetch failed. */
int mdb_sim_search_segments(const mdb_sim_ranker *r, mdb_sim_fetch fetch, void *ctx, const int64_t *doc,
                            const int64_t *start, const int64_t *stop, size_t n, int64_t ex_doc, int64_t ex_first,
                            int64_t ex_last, int64_t limit, mdb_sim_hits *out);

#endif
