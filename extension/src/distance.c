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

/* The DP (distance_dp.h) in the widest vectors the CPU has: 8 rows at a time with AVX-512, 4 with
 * AVX2, else 2 (SSE2, which every x86-64 has, and NEON): gcc splits a vector wider than the
 * CPU's into scalar code, slower than the plain loop. The x86-64 builds carry all three and pick
 * when called; without the CPU's popcnt (every x86-64 since 2008) gcc calls libgcc's software
 * popcount for every template column and frame, hence its clone of the narrow one. */
#define PAD 7 /* rows of +inf above row 0: row 1's vector starts on a vector boundary */
#define MAX_LANES 8

/* the lanes of a where m is set, those of b elsewhere (m: all bits or none, as comparisons give) */
#define SELECT(m, a, b) (((m) & (a)) | (~(m) & (b)))

#if defined(__x86_64__)
/* the predecessor lanes of dp_column's aligned loads: [b, a] from lane LANES-1, and from LANES-2 */
#define DP_LANES 8
#define DP_BACK1 {7, 8, 9, 10, 11, 12, 13, 14}
#define DP_BACK2 {6, 7, 8, 9, 10, 11, 12, 13}
#define DP_FN dp_avx512
#define DP_ATTR __attribute__((target("avx512f")))
#include "distance_dp.h"
#define DP_LANES 4
#define DP_BACK1 {3, 4, 5, 6}
#define DP_BACK2 {2, 3, 4, 5}
#define DP_FN dp_avx2
#define DP_ATTR __attribute__((target("avx2")))
#include "distance_dp.h"
#define DP_LANES 2
#define DP_BACK1 {1, 2}
#define DP_BACK2 {0, 1}
#define DP_FN dp_sse2
#define DP_ATTR __attribute__((target_clones("popcnt", "default")))
#include "distance_dp.h"

static void dp(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts, size_t stride,
               double *buf, int64_t *sbuf, double bound, size_t *dirty) {
	__builtin_cpu_init();
	if (__builtin_cpu_supports("avx512f")) {
		dp_avx512(t, words, n, delta, starts, stride, buf, sbuf, bound, dirty);
	} else if (__builtin_cpu_supports("avx2")) {
		dp_avx2(t, words, n, delta, starts, stride, buf, sbuf, bound, dirty);
	} else {
		dp_sse2(t, words, n, delta, starts, stride, buf, sbuf, bound, dirty);
	}
}
#else
#define DP_LANES 2
#define DP_BACK1 {1, 2}
#define DP_BACK2 {0, 1}
#define DP_FN dp
#define DP_ATTR
#include "distance_dp.h"
#endif

void mdb_dp_scratch_free(mdb_dp_scratch *s) {
	free(s->buf);
	free(s->sbuf);
	memset(s, 0, sizeof *s);
}

int mdb_mt_distance_in(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts,
                       double bound, mdb_dp_scratch *s) {
	size_t K = t->K;
	/* a column: PAD rows, K rows, and the rows the last vector reaches past K-1, rounded up to
	 * 64 bytes (aligned_alloc takes whole multiples of its alignment) */
	size_t stride = (PAD + K + MAX_LANES + 7) / 8 * 8;
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
		s->dirty = stride; /* not set up yet */
	}
	stride = s->stride;
	if (bound < INFINITY && s->dirty < stride) {
		/* a bounded DP reads only rows it or the previous calls wrote as finite (rows 0 .. dirty-1
		 * of a column below its PAD), and every other row is +inf since the last full set-up: a
		 * slice's ring is ready once those are +inf again (a few rows where a short reach was
		 * enough, instead of the whole ring per slice) */
		for (size_t r = 0; r < 3; r++) {
			for (size_t i = 0; i < s->dirty; i++) {
				s->buf[r * stride + PAD + i] = INFINITY;
			}
		}
	} else {
		for (size_t i = 0; i < 3 * stride; i++) {
			s->buf[i] = INFINITY;
			s->sbuf[i] = -1;
		}
		for (size_t i = 0; i < stride; i++) {
			s->buf[3 * stride + i] = 0.0; /* the costs of the rows past K-1 */
		}
	}
	s->dirty = 0;
	dp(t, words, n, delta, starts, stride, s->buf, s->sbuf, bound, &s->dirty);
	if (bound == INFINITY) {
		s->dirty = stride; /* every row of the ring written */
	}
	return 0;
}

int mdb_mt_distance(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts) {
	mdb_dp_scratch s = {0};
	int rc = mdb_mt_distance_in(t, words, n, delta, starts, INFINITY, &s);
	mdb_dp_scratch_free(&s);
	return rc;
}
