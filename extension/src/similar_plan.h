/* The plan of a query by example (mocapdb.retrieval.search.plan_query for one stretch, all features):
 * the stretch's own words as the template, the information weights of its features from a sample
 * of the archive, its chance level and the hit threshold τ, the byte tables of the weighted local
 * cost, and the keyframe queries of the preselection (mocapdb.retrieval.keyframes). Pure C over
 * arrays, no DuckDB; every double as numpy computes it (numpy's pairwise sums, the same operations
 * in the same order), so that ranks, frames and costs are the Python UDF's bit for bit. */
#ifndef MOCAPDB_SIMILAR_PLAN_H
#define MOCAPDB_SIMILAR_PLAN_H

#include <stddef.h>
#include <stdint.h>

#include "chain.h"

#define MDB_SIM_FEATURES 40
/* bytes of a 40-bit word: a weighted cost is five table look-ups (weighted_cost_tables) */
#define MDB_SIM_BYTES 5
/* mocapdb.retrieval.search: TAU_FACTOR, MIN_QUERY_S, SAMPLE_FRAMES, CELL_BUDGET, FRAME_CELLS,
 * COARSE_FACTOR, COARSE_MIN_COLUMNS, COARSE_COLUMNS, BATCH_FRAMES */
#define MDB_SIM_TAU_FACTOR 0.75
#define MDB_SIM_MIN_QUERY_S 0.5
#define MDB_SIM_SAMPLE_FRAMES 16384
#define MDB_SIM_CELL_BUDGET 200000000LL
#define MDB_SIM_FRAME_CELLS 32
#define MDB_SIM_COARSE_FACTOR 4
#define MDB_SIM_COARSE_MIN_COLUMNS 8
#define MDB_SIM_COARSE_COLUMNS 24
#define MDB_SIM_RANK_BATCH ((int64_t)1 << 20)
/* mocapdb.retrieval.keyframes.KEYFRAME_LEVELS and its constants */
#define MDB_SIM_LEVELS 6
#define MDB_SIM_KF_MAX_FEATURES 4
#define MDB_SIM_KF_STABLE 0.15
#define MDB_SIM_KF_CANDIDATES 32

/* P(feature on) of the archive sample: (count + 1) / (n + 2) (feature_frequencies). */
void mdb_sim_frequencies(const int64_t *counts, int64_t n, double *p_on);

/* A weighted template: K columns of (mask, value) with their feature weights (K x 40, 0 at
 * wildcards) and the byte tables of its local cost (K x 5 x 256, weighted_cost_tables with
 * column weights 1). */
typedef struct {
	size_t K;
	uint64_t *mask, *value;
	double *fw;
	double *btable;
} mdb_sim_template;

void mdb_sim_template_free(mdb_sim_template *t);

/* The clip template of n words (every feature fixed, column weights 1) with its information
 * weights −log2 p(value) (information_weights); 0, or -1 when out of memory. */
int mdb_sim_clip_template(const uint64_t *words, size_t n, const double *p_on, mdb_sim_template *out);
/* Every step-th column of t (the coarse pass of rank_slices), with its own byte tables; 0 or -1. */
int mdb_sim_sparse_template(const mdb_sim_template *t, size_t step, mdb_sim_template *out);
/* The chance level of the template (chance_cost with its weights). */
double mdb_sim_chance(const mdb_sim_template *t, const double *p_on);

/* Frames (and columns) per step of the coarse pass (coarse_step) and the Δ cells of ranking n frames
 * (rank_cells). */
size_t mdb_sim_coarse_step(size_t K);
int64_t mdb_sim_rank_cells(int64_t n_frames, size_t K);

/* The keyframe queries of the template, one per level, distinct, lenient first (query_keyframes),
 * each with the annotation margins as ext_l / ext_r (annot_margins); sample: n words. Returns
 * their number (0: no preselection), or -1 when out of memory. */
int mdb_sim_keyframes(const mdb_sim_template *t, const uint64_t *sample, size_t n, mdb_query *out);

#endif
