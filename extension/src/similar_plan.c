/* The plan of a query by example, as mocapdb.retrieval (weights.py, search.py, keyframes.py and
 * templates.distance.weighted_cost_tables) computes it, double for double:
 *
 * - sums are numpy's pairwise summation (pairwise_sum below: 8 accumulators, blocks of 128), as
 *   ndarray.sum gives along a contiguous axis; np.average(x, weights=1) is pairwise(x) / K;
 * - −log2 is the C library's (mocapdb.retrieval.weights uses math.log2 for this reason);
 * - the byte tables are (Σ w·v pairwise over the byte's 8 features + Σ_k w_k(1 − 2v_k)·bit_k in
 *   order k = 0..7) · factor, clipped at 0: weighted_cost_tables sums them elementwise in that
 *   order (a BLAS matmul would sum in its CPU kernel's order: OpenBLAS's on AMD Zen differs in the
 *   last bit), and bit_k is 0 or 1, so every product is exact;
 * - the keyframes' choices compare integers and correctly rounded quotients, and round halves to
 *   even (Python's round, numpy's round) with nearbyint. */
#include "similar_plan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double pairwise_sum(const double *a, size_t n, size_t stride) {
	if (n < 8) {
		double res = 0.0;
		for (size_t i = 0; i < n; i++) {
			res += a[i * stride];
		}
		return res;
	}
	if (n <= 128) {
		double r[8];
		size_t i;
		for (int j = 0; j < 8; j++) {
			r[j] = a[j * stride];
		}
		for (i = 8; i < n - (n % 8); i += 8) {
			for (int j = 0; j < 8; j++) {
				r[j] += a[(i + j) * stride];
			}
		}
		double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
		for (; i < n; i++) {
			res += a[i * stride];
		}
		return res;
	}
	size_t n2 = n / 2;
	n2 -= n2 % 8;
	return pairwise_sum(a, n2, stride) + pairwise_sum(a + n2 * stride, n - n2, stride);
}

void mdb_sim_frequencies(const int64_t *counts, int64_t n, double *p_on) {
	for (int f = 0; f < MDB_SIM_FEATURES; f++) {
		p_on[f] = ((double)counts[f] + 1.0) / ((double)n + 2.0);
	}
}

void mdb_sim_template_free(mdb_sim_template *t) {
	free(t->mask);
	free(t->value);
	free(t->fw);
	free(t->btable);
	memset(t, 0, sizeof *t);
}

static int template_alloc(mdb_sim_template *t, size_t K) {
	memset(t, 0, sizeof *t);
	t->K = K;
	t->mask = malloc(K * sizeof *t->mask);
	t->value = malloc(K * sizeof *t->value);
	t->fw = malloc(K * MDB_SIM_FEATURES * sizeof *t->fw);
	t->btable = malloc(K * MDB_SIM_BYTES * 256 * sizeof *t->btable);
	if (!t->mask || !t->value || !t->fw || !t->btable) {
		mdb_sim_template_free(t);
		return -1;
	}
	return 0;
}

static int bit(uint64_t w, int f) {
	return (int)((w >> f) & 1);
}

/* weighted_cost_tables(template, fw) with column weights 1 and doc_weight 1 */
static void byte_tables(mdb_sim_template *t) {
	size_t K = t->K;
	double w[MDB_SIM_FEATURES], wv[8], a[8];
	for (size_t i = 0; i < K; i++) {
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			w[f] = bit(t->mask[i], f) ? t->fw[i * MDB_SIM_FEATURES + f] : 0.0;
		}
		double total = pairwise_sum(w, MDB_SIM_FEATURES, 1);
		double factor = (1.0 + 1.0) / 2.0 / (double)K / (total > 0 ? total : 1.0);
		for (int b = 0; b < MDB_SIM_BYTES; b++) {
			for (int k = 0; k < 8; k++) {
				double v = (double)bit(t->value[i], 8 * b + k);
				wv[k] = w[8 * b + k] * v;
				a[k] = w[8 * b + k] * (1.0 - 2.0 * v);
			}
			double s0 = pairwise_sum(wv, 8, 1);
			double *row = t->btable + (i * MDB_SIM_BYTES + (size_t)b) * 256;
			for (int x = 0; x < 256; x++) {
				double acc = 0.0;
				for (int k = 0; k < 8; k++) {
					acc = acc + a[k] * (double)((x >> k) & 1);
				}
				double c = (s0 + acc) * factor;
				row[x] = c >= 0.0 ? c : 0.0; /* np.maximum(c, 0): c is never NaN */
			}
		}
	}
}

int mdb_sim_clip_template(const uint64_t *words, size_t n, const double *p_on, mdb_sim_template *out) {
	if (template_alloc(out, n)) {
		return -1;
	}
	const uint64_t all = (((uint64_t)1) << MDB_SIM_FEATURES) - 1;
	double info_on[MDB_SIM_FEATURES], info_off[MDB_SIM_FEATURES];
	for (int f = 0; f < MDB_SIM_FEATURES; f++) {
		info_on[f] = -log2(p_on[f]);
		info_off[f] = -log2(1.0 - p_on[f]);
	}
	for (size_t i = 0; i < n; i++) {
		out->mask[i] = all;
		out->value[i] = words[i] & all;
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			out->fw[i * MDB_SIM_FEATURES + f] = bit(out->value[i], f) ? info_on[f] : info_off[f];
		}
	}
	byte_tables(out);
	return 0;
}

int mdb_sim_sparse_template(const mdb_sim_template *t, size_t step, mdb_sim_template *out) {
	size_t K = (t->K + step - 1) / step;
	if (template_alloc(out, K)) {
		return -1;
	}
	for (size_t i = 0; i < K; i++) {
		out->mask[i] = t->mask[i * step];
		out->value[i] = t->value[i * step];
		memcpy(out->fw + i * MDB_SIM_FEATURES, t->fw + i * step * MDB_SIM_FEATURES, MDB_SIM_FEATURES * sizeof *out->fw);
	}
	byte_tables(out);
	return 0;
}

double mdb_sim_chance(const mdb_sim_template *t, const double *p_on) {
	size_t K = t->K;
	double *per_column = malloc((K ? K : 1) * sizeof *per_column);
	double w[MDB_SIM_FEATURES], x[MDB_SIM_FEATURES];
	if (!per_column) {
		return NAN;
	}
	for (size_t i = 0; i < K; i++) {
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			double pv = bit(t->value[i], f) ? p_on[f] : 1.0 - p_on[f];
			w[f] = bit(t->mask[i], f) ? t->fw[i * MDB_SIM_FEATURES + f] : 0.0;
			x[f] = w[f] * (1.0 - pv);
		}
		double total = pairwise_sum(w, MDB_SIM_FEATURES, 1);
		per_column[i] = total > 0 ? pairwise_sum(x, MDB_SIM_FEATURES, 1) / total : 0.0;
	}
	/* np.average(per_column, weights=ones): Σ (x · 1) / Σ 1 */
	double chance = pairwise_sum(per_column, K, 1) / (double)K;
	free(per_column);
	return chance;
}

size_t mdb_sim_coarse_step(size_t K) {
	if (K < MDB_SIM_COARSE_MIN_COLUMNS) {
		return 1;
	}
	size_t s = K / MDB_SIM_COARSE_COLUMNS;
	return s > 2 ? s : 2;
}

int64_t mdb_sim_rank_cells(int64_t n_frames, size_t K) {
	int64_t step = (int64_t)mdb_sim_coarse_step(K);
	return (n_frames + step - 1) / step * (((int64_t)K + step - 1) / step + MDB_SIM_FRAME_CELLS);
}

/* ---------------------------------------------------------------------------------------------
 * keyframes taken from the query (mocapdb.retrieval.keyframes) */

typedef struct {
	int n;                                /* features on the path */
	int feature[MDB_SIM_KF_MAX_FEATURES]; /* in the order added */
	int64_t count[MDB_SIM_KF_MAX_FEATURES];
} kf_path;

/* _greedy_path: add the candidate feature leaving the fewest sample frames (the first on ties) */
static void greedy_path(uint64_t cand, uint64_t value, const uint64_t *sets, const uint64_t *everything, size_t words,
                        int64_t n, uint64_t *cur, kf_path *path) {
	int64_t count = n;
	memcpy(cur, everything, words * sizeof *cur);
	path->n = 0;
	while (cand && path->n < MDB_SIM_KF_MAX_FEATURES && count > 0) {
		int best = -1;
		int64_t best_count = 0;
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			if (!bit(cand, f)) {
				continue;
			}
			const uint64_t *set = sets + ((size_t)f * 2 + (size_t)bit(value, f)) * words;
			int64_t c = 0;
			for (size_t k = 0; k < words; k++) {
				c += __builtin_popcountll(cur[k] & set[k]);
			}
			if (best < 0 || c < best_count) {
				best = f;
				best_count = c;
			}
		}
		if (best_count >= count) {
			break;
		}
		const uint64_t *set = sets + ((size_t)best * 2 + (size_t)bit(value, best)) * words;
		for (size_t k = 0; k < words; k++) {
			cur[k] &= set[k];
		}
		count = best_count;
		path->feature[path->n] = best;
		path->count[path->n] = count;
		path->n++;
		cand &= ~(((uint64_t)1) << best);
	}
}

typedef struct {
	double freq;
	int n_features;
	int64_t column;
	uint64_t mask, value;
} kf_scored;

static int by_score(const void *a, const void *b) {
	const kf_scored *x = a, *y = b;
	if (x->freq != y->freq) {
		return x->freq < y->freq ? -1 : 1;
	}
	if (x->n_features != y->n_features) {
		return x->n_features < y->n_features ? -1 : 1;
	}
	return (x->column > y->column) - (x->column < y->column);
}

/* pick_keyframes: 0 when no column has a path, else the query in *q */
static int pick(const kf_path *paths, const int64_t *cols, size_t n_cols, const mdb_sim_template *t, int64_t n,
                int n_keyframes, double frequency, kf_scored *scored, mdb_query *q) {
	size_t n_scored = 0;
	double K = (double)t->K;
	for (size_t c = 0; c < n_cols; c++) {
		const kf_path *p = &paths[c];
		if (p->n == 0) {
			continue;
		}
		int k = p->n - 1;
		for (int j = 0; j < p->n; j++) {
			if ((double)p->count[j] / (double)n <= frequency) {
				k = j;
				break;
			}
		}
		kf_scored s = {(double)p->count[k] / (double)n, k + 1, cols[c], 0, 0};
		for (int j = 0; j <= k; j++) {
			s.mask |= ((uint64_t)1) << p->feature[j];
		}
		s.value = s.mask & t->value[cols[c]];
		scored[n_scored++] = s;
	}
	qsort(scored, n_scored, sizeof *scored, by_score);
	kf_scored picked[3];
	int n_picked = 0;
	for (size_t i = 0; i < n_scored && n_picked < n_keyframes; i++) {
		int far = 1;
		for (int j = 0; j < n_picked; j++) {
			int64_t d = scored[i].column - picked[j].column;
			far &= (double)(d < 0 ? -d : d) >= K / 4;
		}
		if (far) {
			picked[n_picked++] = scored[i];
		}
	}
	if (n_picked == 0) {
		return 0;
	}
	for (int i = 1; i < n_picked; i++) { /* by column */
		for (int j = i; j > 0 && picked[j].column < picked[j - 1].column; j--) {
			kf_scored x = picked[j];
			picked[j] = picked[j - 1];
			picked[j - 1] = x;
		}
	}
	memset(q, 0, sizeof *q);
	q->K = (size_t)n_picked;
	for (int i = 0; i < n_picked; i++) {
		q->mask[i] = picked[i].mask;
		q->value[i] = picked[i].value;
		if (i > 0) {
			int64_t gap = picked[i].column - picked[i - 1].column;
			q->d_min[i - 1] = (gap + 1) / 2; /* ceil(gap / 2) */
			q->d_max[i - 1] = 2 * gap;
		}
	}
	q->ext_l = 2 * picked[0].column;
	q->ext_r = 2 * ((int64_t)t->K - 1 - picked[n_picked - 1].column);
	return 1;
}

/* The same keyframes at the same positions (ext_l = 2·p_1 and d_max = 2·gap determine them). */
static int same_query(const mdb_query *a, const mdb_query *b) {
	if (a->K != b->K || a->ext_l != b->ext_l) {
		return 0;
	}
	for (size_t i = 0; i < a->K; i++) {
		if (a->mask[i] != b->mask[i] || a->value[i] != b->value[i] || (i > 0 && a->d_max[i - 1] != b->d_max[i - 1])) {
			return 0;
		}
	}
	return 1;
}

int mdb_sim_keyframes(const mdb_sim_template *t, const uint64_t *sample, size_t n, mdb_query *out) {
	static const int level_keyframes[MDB_SIM_LEVELS] = {1, 1, 2, 2, 3, 3};
	static const double level_frequency[MDB_SIM_LEVELS] = {0.3, 0.1, 0.3, 0.1, 0.1, 0.03};
	size_t K = t->K, words = (n + 63) / 64;
	if (n == 0 || K == 0) {
		return 0;
	}
	/* per feature and value the sample frames having it (_sample_bitsets), and every frame */
	uint64_t *sets = calloc((size_t)MDB_SIM_FEATURES * 2 * words, sizeof *sets);
	uint64_t *everything = calloc(words, sizeof *everything);
	uint64_t *cur = malloc(words * sizeof *cur);
	size_t n_cols_max = K < MDB_SIM_KF_CANDIDATES ? K : MDB_SIM_KF_CANDIDATES;
	int64_t *cols = malloc(n_cols_max * sizeof *cols);
	kf_path *paths = malloc(n_cols_max * sizeof *paths);
	kf_scored *scored = malloc(n_cols_max * sizeof *scored);
	int rc = -1;
	if (!sets || !everything || !cur || !cols || !paths || !scored) {
		goto done;
	}
	for (size_t j = 0; j < n; j++) {
		everything[j / 64] |= ((uint64_t)1) << (j % 64);
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			sets[((size_t)f * 2 + (size_t)bit(sample[j], f)) * words + j / 64] |= ((uint64_t)1) << (j % 64);
		}
	}
	/* stable_features: fixed with one value within radius = max(1, round(0.15 K)) of the column */
	double r = nearbyint(MDB_SIM_KF_STABLE * (double)K);
	int64_t radius = r < 1 ? 1 : (int64_t)r;
	/* the candidate columns: np.unique(np.linspace(0, K - 1, min(K, 32)).round()) */
	size_t n_cols = 0;
	double step = (double)(K - 1) / (double)(n_cols_max - 1);
	for (size_t i = 0; i < n_cols_max; i++) {
		double y = i + 1 == n_cols_max ? (double)(K - 1) : (double)i * step;
		int64_t c = (int64_t)nearbyint(y);
		if (n_cols == 0 || cols[n_cols - 1] != c) { /* ascending: unique is dropping repeats */
			cols[n_cols++] = c;
		}
	}
	for (size_t c = 0; c < n_cols; c++) {
		int64_t i = cols[c];
		uint64_t ok = t->mask[i];
		for (int64_t s = 1; s <= radius; s++) {
			int64_t hi = i + s < (int64_t)K - 1 ? i + s : (int64_t)K - 1, lo = i - s > 0 ? i - s : 0;
			ok &= t->mask[hi] & ~(t->value[hi] ^ t->value[i]);
			ok &= t->mask[lo] & ~(t->value[lo] ^ t->value[i]);
		}
		ok &= (((uint64_t)1) << MDB_SIM_FEATURES) - 1;
		greedy_path(ok, t->value[i], sets, everything, words, (int64_t)n, cur, &paths[c]);
	}
	int n_out = 0;
	for (int l = 0; l < MDB_SIM_LEVELS; l++) {
		mdb_query q;
		if (!pick(paths, cols, n_cols, t, (int64_t)n, level_keyframes[l], level_frequency[l], scored, &q)) {
			continue;
		}
		int dup = 0;
		for (int k = 0; k < n_out && !dup; k++) {
			dup = same_query(&out[k], &q);
		}
		if (!dup) {
			out[n_out++] = q;
		}
	}
	rc = n_out;
done:
	free(sets);
	free(everything);
	free(cur);
	free(cols);
	free(paths);
	free(scored);
	return rc;
}
