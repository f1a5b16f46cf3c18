/* Δ of a quantized motion template against one document's packed words (TEMPLATES.md §9):
 * subsequence DTW with the annotation steps (1,1) w 1, (1,2) w 1, (2,1) w 2 and the toolbox's
 * predecessor rule. Pure C over arrays, the twin of mocapdb.templates.distance. */
#ifndef MOCAPDB_DISTANCE_H
#define MOCAPDB_DISTANCE_H

#include <stddef.h>
#include <stdint.h>

/* A template as stored (one (mask, value, weight) per column), expanded by rounded weight
 * with its cost table (K rows of MDB_N_COST) built by mdb_template_prepare. */
#define MDB_N_COST 42

typedef struct {
	size_t K;
	uint64_t *mask, *value;
	double *table; /* K x MDB_N_COST: cost of column i at c mismatching features, 1/K folded in */
	/* NULL, or K x 5 x 256 feature-weighted costs (similar_plan.c): column i's cost of a word is the
	 * sum of its five bytes' entries, in byte order (weighted_cost_tables); table is then unused */
	const double *btable;
} mdb_template;

/* Expand columns 0..n-1 and tabulate their costs; 0, -1 when out of memory, -2 when a weight
 * is not finite and positive or the expansion passes max_columns. */
int mdb_template_prepare(const uint64_t *mask, const uint64_t *value, const double *weight, size_t n,
                         size_t max_columns, mdb_template *out);
void mdb_template_free(mdb_template *t);

/* The ring of columns mdb_mt_distance_in works in: grown as templates need, reused across calls
 * (one per thread); zeros to start with. */
typedef struct {
	double *buf;
	int64_t *sbuf;
	size_t stride; /* rows of a column it holds */
	size_t dirty;  /* rows of a column (from row 0) the last call may have left finite */
} mdb_dp_scratch;

void mdb_dp_scratch_free(mdb_dp_scratch *s);

/* Δ(j) for j = 0..n-1 into delta (+inf where no path ends) and, when starts is not NULL, the first
 * frame of the path ending at j into starts (-1 where none; the predecessor choice of Δ, as
 * mocapdb.templates.distance with return_starts); 0, or -1 when out of memory. A finite bound
 * gives only Δ(j) <= bound (and its start), the same doubles, +inf (and -1) for the others, and
 * skips the cells no path of cost <= bound reaches (what annotation needs: hits are Δ <= τ);
 * INFINITY: every Δ(j). */
int mdb_mt_distance_in(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts,
                       double bound, mdb_dp_scratch *scratch);
/* The same with a scratch of its own. */
int mdb_mt_distance(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts);

#endif
