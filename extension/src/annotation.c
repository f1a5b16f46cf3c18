/* The annotation chain after Δ, per motion (see annotation.h). Python twins:
 * _extract_hits_kernel, _segments_kernel, _merge_kernel, _margin_kernel, _won_kernel,
 * _segment_min_kernel (mocapdb.annotation.chain_kernels) and their callers in chain.py and
 * postprocess.py. */
#include "annotation.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* mocapdb.annotation.model.STEP_ORDER: within a step of a confidence map the raw score moves the
 * calibrated confidence this share of the way to the next step's value (a test compares the two) */
#define MDB_STEP_ORDER 0.01

void mdb_segments_free(mdb_segments *s) {
	free(s->at);
	memset(s, 0, sizeof *s);
}

static int push(mdb_segments *s, mdb_segment x) {
	if (s->n == s->cap) {
		size_t cap = s->cap ? 2 * s->cap : 32;
		mdb_segment *a = realloc(s->at, cap * sizeof *a);
		if (!a) {
			return -1;
		}
		s->at = a;
		s->cap = cap;
	}
	s->at[s->n++] = x;
	return 0;
}

typedef struct mdb_candidate {
	double d;
	size_t j;
} candidate;

void mdb_hit_scratch_free(mdb_hit_scratch *s) {
	free(s->at);
	free(s->tmp);
	memset(s, 0, sizeof *s);
}

/* Sort c[0 .. m) by Δ, ties in the order they come (frame order, as the kernel's stable sort), with
 * tmp[0 .. m) to merge into: runs of 16 by insertion, then bottom-up merges. */
static void sort_candidates(candidate *c, candidate *tmp, size_t m) {
	const size_t run = 16;
	for (size_t lo = 0; lo < m; lo += run) {
		size_t hi = lo + run < m ? lo + run : m;
		for (size_t i = lo + 1; i < hi; i++) {
			candidate x = c[i];
			size_t k = i;
			while (k > lo && c[k - 1].d > x.d) {
				c[k] = c[k - 1];
				k--;
			}
			c[k] = x;
		}
	}
	candidate *src = c, *dst = tmp;
	for (size_t width = run; width < m; width *= 2) {
		for (size_t lo = 0; lo < m; lo += 2 * width) {
			size_t mid = lo + width < m ? lo + width : m, hi = lo + 2 * width < m ? lo + 2 * width : m;
			size_t i = lo, j = mid;
			for (size_t k = lo; k < hi; k++) {
				dst[k] = j >= hi || (i < mid && src[i].d <= src[j].d) ? src[i++] : src[j++];
			}
		}
		candidate *swap = src;
		src = dst;
		dst = swap;
	}
	if (src != c) {
		memcpy(c, src, m * sizeof *c);
	}
}

typedef double vd2 __attribute__((vector_size(2 * sizeof(double))));
typedef int64_t vi2 __attribute__((vector_size(2 * sizeof(int64_t))));

/* cd[a .. b] that is +inf takes cost: a hit's path mostly crosses frames an earlier hit covered
 * (the candidates next to a hit end on nearly the same path), so two frames at a time, selected
 * without a branch (SSE2, which every x86-64 has, or NEON) */
static void fill_uncovered(double *cd, size_t a, size_t b, double cost) {
	const vd2 inf = {INFINITY, INFINITY}, c = {cost, cost};
	size_t f = a;
	for (; f + 1 <= b; f += 2) {
		vd2 x;
		memcpy(&x, cd + f, sizeof x);
		vi2 m = x == inf;
		x = (vd2)(((vi2)c & m) | ((vi2)x & ~m));
		memcpy(cd + f, &x, sizeof x);
	}
	if (f == b && cd[f] == INFINITY) {
		cd[f] = cost;
	}
}

int mdb_classification_delta(const double *delta, const int64_t *starts, size_t n, double tau, double *cd,
                             mdb_hit_scratch *s) {
	size_t m = 0;
	for (size_t j = 0; j < n; j++) {
		m += delta[j] <= tau;
	}
	if (m == 0) {
		return 0; /* no hit: +inf everywhere, cd left as it was */
	}
	for (size_t j = 0; j < n; j++) {
		cd[j] = INFINITY;
	}
	if (m > s->cap) {
		mdb_hit_scratch_free(s);
		s->at = malloc(m * sizeof *s->at);
		s->tmp = malloc(m * sizeof *s->tmp);
		if (!s->at || !s->tmp) {
			mdb_hit_scratch_free(s);
			return -1;
		}
		s->cap = m;
	}
	candidate *c = s->at;
	m = 0;
	for (size_t j = 0; j < n; j++) {
		if (delta[j] <= tau) {
			c[m++] = (candidate){delta[j], j};
		}
	}
	sort_candidates(c, s->tmp, m);
	for (size_t k = 0; k < m; k++) {
		size_t e = c[k].j;
		if (cd[e] < INFINITY) {
			continue; /* a hit covers it already */
		}
		double cost = delta[e];
		int64_t st = starts[e] < 0 ? 0 : starts[e]; /* finite Δ always has its start */
		fill_uncovered(cd, (size_t)st, e, cost);
	}
	return 1;
}

/* Δarg at frame f over rows[0 .. L): the first row with the minimal value, -1 where all are +inf. */
static long best_row(const double *const *rows, size_t L, size_t f) {
	long lab = -1;
	double best = INFINITY;
	for (size_t p = 0; p < L; p++) {
		if (rows[p][f] < best) {
			best = rows[p][f];
			lab = (long)p;
		}
	}
	return lab;
}

static int by_label_start(const void *a, const void *b) {
	const mdb_segment *x = a, *y = b;
	if (x->label != y->label) {
		return x->label < y->label ? -1 : 1;
	}
	return (x->start > y->start) - (x->start < y->start);
}

/* form_segments of one document: runs of Δarg over rows, extended along their row while it does
 * not increase, sorted by (label, start) and merged; row p is label label_of[p]. */
static int form_segments(const double *const *rows, const int64_t *label_of, size_t L, size_t n, mdb_segments *out) {
	mdb_segments runs = {0};
	long prev = -1;
	size_t run_start = 0;
	for (size_t f = 0; f <= n; f++) {
		long lab = f < n ? best_row(rows, L, f) : -1;
		if (f != n && lab == prev) {
			continue;
		}
		if (prev >= 0 && f > 0) {
			const double *r = rows[prev];
			size_t s = run_start, e = f - 1;
			double s_cost = r[s], e_cost = r[e];
			while (s >= 1 && r[s - 1] <= s_cost) {
				s_cost = r[--s];
			}
			while (e + 1 < n && r[e + 1] <= e_cost) {
				e_cost = r[++e];
			}
			mdb_segment x = {prev, (int64_t)s, (int64_t)e, s_cost < e_cost ? s_cost : e_cost, 0.0};
			if (push(&runs, x)) {
				mdb_segments_free(&runs);
				return -1;
			}
		}
		prev = lab;
		run_start = f;
	}
	/* equal (label, start) pairs merge into the same union whatever their order */
	if (runs.n > 1) {
		qsort(runs.at, runs.n, sizeof *runs.at, by_label_start);
	}
	int rc = 0;
	for (size_t i = 0; i < runs.n && rc == 0; i++) {
		mdb_segment x = runs.at[i];
		x.label = label_of[x.label];
		mdb_segment *last = out->n ? &out->at[out->n - 1] : NULL;
		if (i > 0 && last->label == x.label && x.start <= last->end) {
			last->end = last->end > x.end ? last->end : x.end;
			last->cost = last->cost < x.cost ? last->cost : x.cost;
		} else {
			rc = push(out, x);
		}
	}
	mdb_segments_free(&runs);
	return rc;
}

static int by_label(const void *a, const void *b) {
	const mdb_segment *x = a, *y = b;
	if (x->label != y->label) {
		return x->label < y->label ? -1 : 1;
	}
	/* stable: the position before sorting, kept in confidence until it is computed */
	return (x->confidence > y->confidence) - (x->confidence < y->confidence);
}

int mdb_label_segments(double *label_cd, const double *label_ratio, size_t n, const mdb_label_rules *rules,
                       mdb_segments *out) {
	size_t L = rules->n_labels, R = 0;
	int rc = -1;
	double **rows = malloc((L ? L : 1) * sizeof *rows);
	int64_t *ident = malloc((L ? L : 1) * sizeof *ident);
	mdb_segments segs = {0};
	if (!rows || !ident) {
		goto done;
	}
	/* The rows that compete, rows[r] of label ident[r]: a label's that is set and not concurrent (a
	 * concurrent label's row leaves the competition: its segments are its own runs). A row left out
	 * is +inf throughout in the paper's chain, and +inf never wins Δarg (strict "<") nor moves the
	 * margin's best and second best: the segments are the same. */
	for (size_t p = 0; p < L; p++) {
		if ((!rules->set || rules->set[p]) && !rules->concurrent[p]) {
			rows[R] = label_cd + p * n;
			ident[R++] = (int64_t)p;
		}
	}
	if (rules->margin > 0) { /* _margin_kernel */
		for (size_t f = 0; f < n; f++) {
			double best = INFINITY, second = INFINITY;
			for (size_t r = 0; r < R; r++) {
				double v = rows[r][f];
				if (v < best) {
					second = best;
					best = v;
				} else if (v < second) {
					second = v;
				}
			}
			if (best < INFINITY && second - best < rules->margin) {
				for (size_t r = 0; r < R; r++) {
					rows[r][f] = INFINITY;
				}
			}
		}
	}
	if (form_segments((const double *const *)rows, ident, R, n, &segs)) {
		goto done;
	}
	/* postprocess.document_minimum: in a motion shorter than twice a label's minimum, half of it
	 * (rounded up) is the most the minimum asks, and a third of that the most min_won asks */
	int64_t half = ((int64_t)n + 1) / 2;
	int64_t half_won = (int64_t)ceil((double)half * MDB_WON_FRACTION - 1e-9);
	/* drop_unwon_segments: the label must be Δarg on min_won of its frames */
	size_t kept = 0;
	for (size_t i = 0; i < segs.n; i++) {
		mdb_segment x = segs.at[i];
		int64_t want = rules->min_won[x.label] < half_won ? rules->min_won[x.label] : half_won;
		if (want > 0) {
			int64_t won = 0;
			for (int64_t f = x.start; f <= x.end; f++) {
				long r = best_row((const double *const *)rows, R, (size_t)f);
				won += r >= 0 && ident[r] == x.label;
			}
			if (won < want) {
				continue;
			}
		}
		segs.at[kept++] = x;
	}
	segs.n = kept;
	size_t n_own = 0;
	for (size_t p = 0; p < L; p++) {
		if ((!rules->set || rules->set[p]) && rules->concurrent[p]) { /* its row, untouched by the margin */
			const double *row = label_cd + p * n;
			int64_t lab = (int64_t)p;
			n_own++;
			if (form_segments(&row, &lab, 1, n, &segs)) {
				goto done;
			}
		}
	}
	if (n_own && segs.n > 1) { /* _sort_by_label: stable by label order */
		for (size_t i = 0; i < segs.n; i++) {
			segs.at[i].confidence = (double)i;
		}
		qsort(segs.at, segs.n, sizeof *segs.at, by_label);
	}
	for (size_t i = 0; i < segs.n; i++) {
		mdb_segment x = segs.at[i];
		/* segment_confidence: 1 − the smallest Δ̄^τ/τ of the label over the segment, in [0, 1] */
		double best = INFINITY;
		for (int64_t f = x.start; f <= x.end; f++) {
			double v = label_ratio[(size_t)x.label * n + (size_t)f];
			if (v < best) {
				best = v;
			}
		}
		double conf = 1.0 - best;
		x.confidence = conf < 0.0 ? 0.0 : conf > 1.0 ? 1.0 : conf;
		/* postprocess.calibrate_confidence: of the label's map with the largest min_length the
		 * segment reaches, the score (postprocess.length_score: with l = min(n, F) / F,
		 * raw · (1 + w · l) / (1 + w) where the length multiplies, else (raw + w · l) / (1 + w)), then
		 * the value of the last
		 * step whose cut is <= the score, plus MDB_STEP_ORDER of the way to the next step's value (1
		 * after the last) as far as the score lies towards the next cut (1): the same operations in
		 * the same order */
		size_t steps = rules->conf_n[x.label], g = steps;
		const int64_t *min_length = steps ? rules->conf_min_length[x.label] : NULL;
		for (size_t j = 0; j < steps; j++) {
			if (min_length[j] <= x.end - x.start + 1 && (g == steps || min_length[j] > min_length[g])) {
				g = j;
			}
		}
		if (g < steps) {
			const double *cut = rules->conf_cut[x.label];
			int64_t len = x.end - x.start + 1, full = rules->conf_full_length[x.label][g];
			double weight = rules->conf_length_weight[x.label][g];
			double share = (double)(len < full ? len : full) / (double)full;
			x.confidence = rules->conf_length_product[x.label][g]
			                   ? x.confidence * (1.0 + weight * share) / (1.0 + weight)
			                   : (x.confidence + weight * share) / (1.0 + weight);
			while (g + 1 < steps && min_length[g + 1] == min_length[g] && cut[g + 1] <= x.confidence) {
				g++;
			}
			const double *value = rules->conf_value[x.label];
			double c0 = cut[g], v0 = value[g], c1 = 1.0, v1 = 1.0;
			if (g + 1 < steps && min_length[g + 1] == min_length[g]) {
				c1 = cut[g + 1];
				v1 = value[g + 1];
			}
			double frac = c1 > c0 ? (x.confidence - c0) / (c1 - c0) : 0.0;
			frac = frac < 0.0 ? 0.0 : frac > 1.0 ? 1.0 : frac;
			/* nothing added where nothing is to add: a step's value stands as stored (-0.0 too) */
			x.confidence = frac > 0.0 && v1 > v0 ? v0 + MDB_STEP_ORDER * (v1 - v0) * frac : v0;
		}
		/* drop_short_segments: a concurrent label's minimum is its own duration, never capped */
		int64_t need = rules->min_frames[x.label];
		if (!rules->concurrent[x.label] && half < need) {
			need = half;
		}
		if (x.end - x.start + 1 >= need && push(out, x)) {
			goto done;
		}
	}
	rc = 0;
done:
	mdb_segments_free(&segs);
	free(rows);
	free(ident);
	return rc;
}
