/* The distance function Δ as mocapdb.templates.distance computes it, operation for operation,
 * so that the doubles are the same bit for bit (built with -ffp-contract=off: no fused
 * multiply-add where numba has none):
 *
 * - expansion (expandWeightedVectorSequence): column i repeated r_i = max(1, round(w_i)) times
 *   (halves away from zero), each with weight w_i / r_i;
 * - cost table: table[i][c] = (c / K) * ((w_i + 1) / (2 * max(1, popcount(mask_i)))), c the
 *   number of fixed features on which the word disagrees;
 * - DP: row 0 is a free start, D[0][j] = C[0][j]; row i takes the predecessor with the smallest
 *   accumulated cost among (i-1, j-1), (i-1, j-2), (i-2, j-1), in that order with strict "<"
 *   (the first wins ties), then adds its step weight (1, 1, 2) times C[i][j]; out of range is
 *   +inf, which never wins and stays +inf. Δ(j) = D[K-1][j]. */
#include "distance.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void mdb_template_free(mdb_template *t) {
	free(t->mask);
	free(t->value);
	free(t->table);
	memset(t, 0, sizeof *t);
}

/* Matlab's round: halves away from zero */
static double matlab_round(double x) {
	double a = fabs(x), fl = floor(a);
	return copysign(fl + (a - fl >= 0.5 ? 1.0 : 0.0), x);
}

int mdb_template_prepare(const uint64_t *mask, const uint64_t *value, const double *weight, size_t n,
                         size_t max_columns, mdb_template *out) {
	memset(out, 0, sizeof *out);
	size_t K = 0;
	for (size_t i = 0; i < n; i++) {
		if (!isfinite(weight[i]) || weight[i] <= 0 || weight[i] > (double)max_columns) {
			return -2;
		}
		double r = matlab_round(weight[i]);
		K += r < 1.0 ? 1 : (size_t)r;
		if (K > max_columns) {
			return -2;
		}
	}
	if (K == 0) {
		return -2;
	}
	out->mask = malloc(K * sizeof *out->mask);
	out->value = malloc(K * sizeof *out->value);
	out->table = malloc(K * MDB_N_COST * sizeof *out->table);
	double *w = malloc(K * sizeof *w);
	if (!out->mask || !out->value || !out->table || !w) {
		free(w);
		mdb_template_free(out);
		return -1;
	}
	size_t k = 0;
	for (size_t i = 0; i < n; i++) {
		double r = matlab_round(weight[i]);
		if (r < 1.0) {
			r = 1.0;
		}
		double wi = weight[i] / r;
		for (size_t rep = 0; rep < (size_t)r; rep++, k++) {
			out->mask[k] = mask[i];
			out->value[k] = value[i];
			w[k] = wi;
		}
	}
	out->K = K;
	for (size_t i = 0; i < K; i++) {
		int fixed = __builtin_popcountll(out->mask[i]);
		double factor = (w[i] + 1.0) / (2.0 * (double)(fixed > 1 ? fixed : 1));
		for (int c = 0; c < MDB_N_COST; c++) {
			out->table[i * MDB_N_COST + c] = ((double)c / (double)K) * factor;
		}
	}
	free(w);
	return 0;
}

/* The DP runs over MDB_LANES template rows at a time (gcc's vector extensions: each lane does
 * the scalar operations in the same order — the same comparisons, selects, the multiplication by
 * the step weight and the addition — so every double is the one the scalar row loop gives). Row i
 * of frame j reads only rows i-1 and i-2 of frames j-1 and j-2, so the rows of a frame are
 * independent. Each column of the ring holds PAD rows of +inf above row 0 (the predecessors that
 * do not exist) and room past row K-1 for a last vector: those rows cost 0 and hold values
 * nothing reads. */
#define MDB_LANES 4
#define PAD (MDB_LANES - 1) /* row 1's vector starts on a vector boundary */
typedef double vd __attribute__((vector_size(MDB_LANES * sizeof(double))));
typedef int64_t vi __attribute__((vector_size(MDB_LANES * sizeof(int64_t))));

/* the lanes of a where m is set, those of b elsewhere (m: all bits or none, as comparisons give) */
#define SELECT(m, a, b) (((m) & (a)) | (~(m) & (b)))

/* One frame's rows 1 .. K-1: p0/q0 the column of frame j (D, starts), p1/q1 of j-1, p2/q2 of
 * j-2, each at row 0; c the frame's costs. */
static inline __attribute__((always_inline)) void dp_column(size_t K, const double *c, double *p0, const double *p1,
                                                             const double *p2, int64_t *q0, const int64_t *q1,
                                                             const int64_t *q2, const int with_starts) {
	const vd one = {1.0, 1.0, 1.0, 1.0}, two = {2.0, 2.0, 2.0, 2.0}, inf = {INFINITY, INFINITY, INFINITY, INFINITY};
	const vi none = {-1, -1, -1, -1};
	for (size_t i = 1; i < K; i += MDB_LANES) {
		vd v0, v1, v2, ci;
		memcpy(&v0, p1 + i - 1, sizeof v0); /* (1, 1), weight 1 */
		memcpy(&v1, p2 + i - 1, sizeof v1); /* (1, 2), weight 1 */
		memcpy(&v2, p1 + i - 2, sizeof v2); /* (2, 1), weight 2; row -1 is +inf */
		memcpy(&ci, c + i, sizeof ci);
		vi m1 = v1 < v0;
		vd best = (vd)SELECT(m1, (vi)v1, (vi)v0);
		vi m2 = v2 < best;
		best = (vd)SELECT(m2, (vi)v2, (vi)best);
		vd bw = (vd)SELECT(m2, (vi)two, (vi)one);
		vd d = best + bw * ci;
		memcpy(p0 + i, &d, sizeof d);
		if (with_starts) {
			vi t0, t1, t2;
			memcpy(&t0, q1 + i - 1, sizeof t0);
			memcpy(&t1, q2 + i - 1, sizeof t1);
			memcpy(&t2, q1 + i - 2, sizeof t2);
			vi st = SELECT(m2, t2, SELECT(m1, t1, t0));
			vi reached = d < inf;
			st = SELECT(reached, st, none);
			memcpy(q0 + i, &st, sizeof st);
		}
	}
}

#if defined(__x86_64__)
/* Chosen when the binary loads: AVX2 runs a vector of rows in one instruction, and without the
 * CPU's popcnt (every x86-64 since 2008) gcc calls libgcc's software popcount for every template
 * column and frame. */
#define MDB_CLONES __attribute__((target_clones("avx2", "popcnt", "default")))
#else
#define MDB_CLONES
#endif

static inline __attribute__((always_inline)) void dp(const mdb_template *t, const uint64_t *words, size_t n,
                                                      double *delta, int64_t *starts, size_t stride, double *buf,
                                                      int64_t *sbuf, const int with_starts) {
	size_t K = t->K;
	double *c = buf + 3 * stride;
	double *col[3] = {buf + PAD, buf + stride + PAD, buf + 2 * stride + PAD}; /* frames j, j-1, j-2 at row 0 */
	int64_t *scol[3] = {sbuf + PAD, sbuf + stride + PAD, sbuf + 2 * stride + PAD};
	for (size_t j = 0; j < n; j++) {
		uint64_t w = words[j];
		if (j == 0 || w != words[j - 1]) { /* a word often lasts a few frames: its costs are the same */
			for (size_t i = 0; i < K; i++) {
				c[i] = t->table[i * MDB_N_COST + (size_t)__builtin_popcountll((t->value[i] ^ w) & t->mask[i])];
			}
		}
		size_t r0 = j % 3, r1 = (j + 2) % 3, r2 = (j + 1) % 3;
		col[r0][0] = c[0];
		if (with_starts) {
			scol[r0][0] = (int64_t)j; /* row 0: a path starts here */
		}
		dp_column(K, c, col[r0], col[r1], col[r2], scol[r0], scol[r1], scol[r2], with_starts);
		delta[j] = col[r0][K - 1];
		if (with_starts) {
			starts[j] = scol[r0][K - 1];
		}
	}
}

void mdb_dp_scratch_free(mdb_dp_scratch *s) {
	free(s->buf);
	free(s->sbuf);
	memset(s, 0, sizeof *s);
}

MDB_CLONES int mdb_mt_distance_in(const mdb_template *t, const uint64_t *words, size_t n, double *delta,
                                  int64_t *starts, mdb_dp_scratch *s) {
	size_t K = t->K;
	/* a column: PAD rows, K rows, and the rows the last vector reaches past K-1, rounded up to
	 * 64 bytes (aligned_alloc takes whole multiples of its alignment) */
	size_t stride = (PAD + K + MDB_LANES + 7) / 8 * 8;
	if (stride > s->stride) {
		/* columns j, j-1, j-2 of D and the frame's costs; columns j, j-1, j-2 of the start frame
		 * of each cell's path (-1: none), following the chosen predecessor */
		mdb_dp_scratch_free(s);
		s->buf = aligned_alloc(64, 4 * stride * sizeof *s->buf);
		s->sbuf = aligned_alloc(64, 3 * stride * sizeof *s->sbuf);
		if (!s->buf || !s->sbuf) {
			mdb_dp_scratch_free(s);
			return -1;
		}
		s->stride = stride;
	}
	stride = s->stride;
	for (size_t i = 0; i < 3 * stride; i++) {
		s->buf[i] = INFINITY;
		s->sbuf[i] = -1;
	}
	for (size_t i = 0; i < stride; i++) {
		s->buf[3 * stride + i] = 0.0; /* the costs of the rows past K-1 */
	}
	if (starts) {
		dp(t, words, n, delta, starts, stride, s->buf, s->sbuf, 1);
	} else {
		dp(t, words, n, delta, NULL, stride, s->buf, s->sbuf, 0);
	}
	return 0;
}

int mdb_mt_distance(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts) {
	mdb_dp_scratch s = {0};
	int rc = mdb_mt_distance_in(t, words, n, delta, starts, &s);
	mdb_dp_scratch_free(&s);
	return rc;
}
