/* A query by example over the archive (mocapdb.storage.retrieval.search_archive): the plan from the
 * query stretch and the archive sample (similar_plan.c), the ranked motions a batch at a time, their
 * words from the keyframe index's full runs, preselected with the query's keyframes when the archive
 * exceeds the cell budget, ranked (similar_rank.c). */
#ifndef MOCAPDB_SIMILAR_SEARCH_H
#define MOCAPDB_SIMILAR_SEARCH_H

#include "archive.h"
#include "similar_rank.h"

/* The best limit hits of the query stretch q_words[0 .. K) (frames q_first … of motion q_id, which no
 * hit overlaps) into found, doc = motion id, by (cost, motion, start); 0, or -1 with err set. */
int mdb_sim_search_archive(mdb_state *st, int64_t q_id, int64_t q_first, const uint64_t *q_words, size_t K,
                           int64_t limit, mdb_sim_hits *found, mdb_error *err);

#endif
