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

int mdb_mt_distance(const mdb_template *t, const uint64_t *words, size_t n, double *delta) {
	size_t K = t->K;
	/* columns j-2, j-1, j of D and the frame's costs */
	double *buf = malloc(4 * K * sizeof *buf);
	if (!buf) {
		return -1;
	}
	double *d2 = buf, *d1 = buf + K, *d0 = buf + 2 * K, *c = buf + 3 * K;
	for (size_t i = 0; i < 2 * K; i++) {
		buf[i] = INFINITY;
	}
	for (size_t j = 0; j < n; j++) {
		uint64_t w = words[j];
		for (size_t i = 0; i < K; i++) {
			c[i] = t->table[i * MDB_N_COST + __builtin_popcountll((t->value[i] ^ w) & t->mask[i])];
		}
		d0[0] = c[0];
		for (size_t i = 1; i < K; i++) {
			double v0 = d1[i - 1];                    /* (1, 1), weight 1 */
			double v1 = d2[i - 1];                    /* (1, 2), weight 1 */
			double v2 = i >= 2 ? d1[i - 2] : INFINITY; /* (2, 1), weight 2 */
			int m1 = v1 < v0;
			double best = m1 ? v1 : v0, bw = 1.0;
			if (v2 < best) {
				best = v2;
				bw = 2.0;
			}
			d0[i] = best + bw * c[i];
		}
		delta[j] = d0[K - 1];
		double *old = d2; /* rotate: j-1 becomes j-2, j becomes j-1 */
		d2 = d1;
		d1 = d0;
		d0 = old;
	}
	free(buf);
	return 0;
}
