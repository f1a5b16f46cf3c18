/* Ranking a query by example, step for step as mocapdb.retrieval.search (rank_slices, _rank,
 * search_segments) and mocapdb.retrieval.hits (select_hits, best_hits) do it: the same passes over
 * the same slices and windows, the same candidates visited in the same (Δ, frame) order, the same
 * cuts. Costs are Δ as distance.c computes it with the weighted byte tables (no further
 * arithmetic), so they are the Python UDF's doubles. */
#include "similar_rank.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void mdb_sim_hits_free(mdb_sim_hits *h) {
	free(h->at);
	memset(h, 0, sizeof *h);
}

int mdb_sim_hits_push(mdb_sim_hits *h, mdb_sim_hit x) {
	if (h->n == h->cap) {
		size_t cap = h->cap ? 2 * h->cap : 64;
		mdb_sim_hit *grown = realloc(h->at, cap * sizeof *grown);
		if (!grown) {
			return -1;
		}
		h->at = grown;
		h->cap = cap;
	}
	h->at[h->n++] = x;
	return 0;
}

static int by_cost_doc_start(const void *a, const void *b) {
	const mdb_sim_hit *x = a, *y = b;
	if (x->cost != y->cost) {
		return x->cost < y->cost ? -1 : 1;
	}
	if (x->doc != y->doc) {
		return x->doc < y->doc ? -1 : 1;
	}
	return (x->start > y->start) - (x->start < y->start);
}

void mdb_sim_hits_best(mdb_sim_hits *h, int64_t limit) {
	if (h->n > 1) { /* qsort's base must not be NULL, even for no elements */
		qsort(h->at, h->n, sizeof *h->at, by_cost_doc_start);
	}
	if ((int64_t)h->n > limit) {
		h->n = (size_t)limit;
	}
}

/* Scratch of one pass: Δ and starts of a slice, its candidate frames. */
typedef struct {
	double *delta;
	int64_t *starts;
	int64_t *cand;
	size_t cap;
	mdb_dp_scratch dp;
} pass_scratch;

static void scratch_free(pass_scratch *s) {
	free(s->delta);
	free(s->starts);
	free(s->cand);
	mdb_dp_scratch_free(&s->dp);
}

static int scratch_reserve(pass_scratch *s, size_t n) {
	if (n <= s->cap) {
		return 0;
	}
	free(s->delta);
	free(s->starts);
	free(s->cand);
	s->delta = malloc(n * sizeof *s->delta);
	s->starts = malloc(n * sizeof *s->starts);
	s->cand = malloc(n * sizeof *s->cand);
	s->cap = s->delta && s->starts && s->cand ? n : 0;
	return s->cap ? 0 : -1;
}

/* qsort has no context: the pass sets it (per thread: DuckDB may run the function on several) */
static _Thread_local const double *sort_delta;

static int by_delta_frame(const void *a, const void *b) {
	int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
	double dx = sort_delta[x], dy = sort_delta[y];
	if (dx != dy) {
		return dx < dy ? -1 : 1;
	}
	return (x > y) - (x < y);
}

/* _rank: Δ on each slice [ta[q], tb[q]) and its hits (select_hits: candidates in (Δ, frame) order,
 * a hit taken when none of its frames is marked, then marking them), at most limit per slice, the
 * best limit of all into out by (cost, slice, start); mark (n_words) is updated. */
static int rank_pass(const mdb_sim_template *t, double tau, const uint64_t *words, const int64_t *ta,
                     const int64_t *tb, size_t n, uint8_t *mark, int64_t limit, int minima, pass_scratch *s,
                     mdb_sim_hits *out) {
	mdb_template dt = {t->K, t->mask, t->value, NULL, t->btable};
	out->n = 0;
	for (size_t q = 0; q < n; q++) {
		size_t len = (size_t)(tb[q] - ta[q]);
		if (len == 0) {
			continue;
		}
		if (scratch_reserve(s, len) || mdb_mt_distance_in(&dt, words + ta[q], len, s->delta, s->starts, INFINITY, &s->dp)) {
			return -1;
		}
		const double *d = s->delta;
		size_t k = 0;
		for (size_t j = 0; j < len; j++) {
			double v = d[j];
			if (!(v <= tau)) {
				continue;
			}
			if (minima && ((j > 0 && d[j - 1] < v) || (j + 1 < len && d[j + 1] < v))) {
				continue;
			}
			s->cand[k++] = (int64_t)j;
		}
		sort_delta = d;
		qsort(s->cand, k, sizeof *s->cand, by_delta_frame);
		uint8_t *m = mark + ta[q];
		int64_t h = 0;
		for (size_t r = 0; r < k && h < limit; r++) {
			int64_t e = s->cand[r], st = s->starts[e];
			if (m[e]) {
				continue;
			}
			int free_ = 1;
			for (int64_t f = e - 1; f >= st && free_; f--) {
				free_ = !m[f];
			}
			if (!free_) {
				continue;
			}
			memset(m + st, 1, (size_t)(e - st + 1));
			if (mdb_sim_hits_push(out, (mdb_sim_hit){(int64_t)q, ta[q] + st, ta[q] + e, d[e]})) {
				return -1;
			}
			h++;
		}
	}
	mdb_sim_hits_best(out, limit);
	return 0;
}

typedef struct {
	int64_t lo, hi;
	size_t order;
} window;

static int by_lo(const void *a, const void *b) {
	const window *x = a, *y = b;
	if (x->lo != y->lo) {
		return x->lo < y->lo ? -1 : 1;
	}
	return (x->order > y->order) - (x->order < y->order);
}

/* the slice holding word index x: searchsorted(ta, x, side='right') - 1 */
static int64_t slice_of(const int64_t *ta, size_t n, int64_t x) {
	size_t lo = 0, hi = n;
	while (lo < hi) {
		size_t mid = (lo + hi) / 2;
		if (ta[mid] <= x) {
			lo = mid + 1;
		} else {
			hi = mid;
		}
	}
	return (int64_t)lo - 1;
}

int mdb_sim_rank_slices(const mdb_sim_ranker *r, const uint64_t *words, size_t n_words, const int64_t *ta,
                        const int64_t *tb, size_t n, const uint8_t *taken, int64_t limit, mdb_sim_hits *out) {
	pass_scratch s = {0};
	mdb_sim_hits found = {0}, hits = {0};
	uint8_t *mark = calloc(n_words ? n_words : 1, 1);
	uint64_t *sw = NULL;
	uint8_t *smark = NULL;
	int64_t *cbase = NULL, *wlo = NULL, *whi = NULL;
	window *win = NULL;
	int rc = -1;
	int64_t step = (int64_t)r->step, K = (int64_t)r->t->K;
	if (!mark) {
		goto done;
	}
	if (taken) {
		memcpy(mark, taken, n_words);
	}
	if (step == 1 || !r->sparse) {
		if (rank_pass(r->t, r->tau, words, ta, tb, n, mark, limit, 0, &s, &hits)) {
			goto done;
		}
	} else {
		/* the slices' frames ta, ta + step, … (coarse_step) and the template's every step-th column */
		cbase = malloc((n + 1) * sizeof *cbase);
		if (!cbase) {
			goto done;
		}
		cbase[0] = 0;
		for (size_t q = 0; q < n; q++) {
			cbase[q + 1] = cbase[q] + (tb[q] - ta[q] + step - 1) / step;
		}
		size_t M = (size_t)cbase[n];
		sw = malloc((M ? M : 1) * sizeof *sw);
		smark = calloc(M ? M : 1, 1);
		if (!sw || !smark) {
			goto done;
		}
		for (size_t q = 0; q < n; q++) {
			for (int64_t m = 0; m < cbase[q + 1] - cbase[q]; m++) {
				sw[cbase[q] + m] = words[ta[q] + step * m];
				smark[cbase[q] + m] = taken ? taken[ta[q] + step * m] : 0;
			}
		}
		if (rank_pass(r->sparse, r->tau, sw, cbase, cbase + 1, n, smark, MDB_SIM_COARSE_FACTOR * limit, 1, &s,
		              &found)) {
			goto done;
		}
		/* each coarse hit's place at full resolution, widened by K each side, overlapping ones merged */
		win = malloc((found.n ? found.n : 1) * sizeof *win);
		wlo = malloc((found.n ? found.n : 1) * sizeof *wlo);
		whi = malloc((found.n ? found.n : 1) * sizeof *whi);
		if (!win || !wlo || !whi) {
			goto done;
		}
		for (size_t i = 0; i < found.n; i++) {
			int64_t q = found.at[i].doc;
			int64_t lo = ta[q] + step * (found.at[i].start - cbase[q]) - K;
			int64_t hi = ta[q] + step * (found.at[i].end - cbase[q]) + step + K;
			win[i] = (window){lo > ta[q] ? lo : ta[q], hi < tb[q] ? hi : tb[q], i};
		}
		qsort(win, found.n, sizeof *win, by_lo);
		size_t nw = 0;
		int64_t reach = 0;
		for (size_t i = 0; i < found.n; i++) {
			if (i == 0 || win[i].lo >= reach) { /* overlapping windows merge, touching ones do not */
				wlo[nw] = win[i].lo;
				whi[nw++] = win[i].hi;
			} else if (win[i].hi > whi[nw - 1]) {
				whi[nw - 1] = win[i].hi;
			}
			reach = i == 0 || win[i].hi > reach ? win[i].hi : reach;
		}
		if (rank_pass(r->t, r->tau, words, wlo, whi, nw, mark, limit, 0, &s, &hits)) {
			goto done;
		}
		for (size_t i = 0; i < hits.n; i++) {
			hits.at[i].doc = slice_of(ta, n, wlo[hits.at[i].doc]);
		}
		mdb_sim_hits_best(&hits, limit);
	}
	for (size_t i = 0; i < hits.n; i++) {
		if (mdb_sim_hits_push(out, hits.at[i])) {
			goto done;
		}
	}
	rc = 0;
done:
	scratch_free(&s);
	mdb_sim_hits_free(&found);
	mdb_sim_hits_free(&hits);
	free(mark);
	free(sw);
	free(smark);
	free(cbase);
	free(win);
	free(wlo);
	free(whi);
	return rc;
}

int mdb_sim_search_segments(const mdb_sim_ranker *r, mdb_sim_fetch fetch, void *ctx, const int64_t *doc,
                            const int64_t *start, const int64_t *stop, size_t n, int64_t ex_doc, int64_t ex_first,
                            int64_t ex_last, int64_t limit, mdb_sim_hits *out) {
	mdb_sim_hits hits = {0};
	int64_t *base = malloc((n + 1) * sizeof *base);
	uint64_t *words = NULL;
	uint8_t *taken = NULL;
	size_t words_cap = 0;
	int rc = -1;
	if (!base) {
		goto done;
	}
	size_t a = 0;
	int64_t before = 0; /* frames of the segments before a */
	while (a < n) {
		/* a batch: the segments whose frames before them fall in the same window of MDB_SIM_RANK_BATCH */
		int64_t w = before / MDB_SIM_RANK_BATCH;
		size_t b = a;
		int64_t f = before;
		while (b < n && f / MDB_SIM_RANK_BATCH == w) {
			f += stop[b] - start[b];
			b++;
		}
		size_t m = b - a;
		base[0] = 0;
		for (size_t k = 0; k < m; k++) {
			base[k + 1] = base[k] + stop[a + k] - start[a + k];
		}
		size_t N = (size_t)base[m];
		if (N > words_cap) {
			free(words);
			free(taken);
			words = malloc(N * sizeof *words);
			taken = malloc(N);
			words_cap = words && taken ? N : 0;
			if (!words_cap) {
				goto done;
			}
		}
		if (fetch(ctx, doc + a, start + a, stop + a, m, words)) {
			rc = -2;
			goto done;
		}
		int any = 0;
		if (N) {
			memset(taken, 0, N);
		}
		for (size_t k = 0; k < m; k++) {
			if (doc[a + k] == ex_doc && start[a + k] <= ex_last && stop[a + k] > ex_first) {
				int64_t lo = ex_first > start[a + k] ? ex_first : start[a + k];
				int64_t hi = ex_last + 1 < stop[a + k] ? ex_last + 1 : stop[a + k];
				memset(taken + base[k] + lo - start[a + k], 1, (size_t)(hi - lo));
				any = 1;
			}
		}
		hits.n = 0;
		if (mdb_sim_rank_slices(r, words, N, base, base + 1, m, any ? taken : NULL, limit, &hits)) {
			goto done;
		}
		for (size_t i = 0; i < hits.n; i++) {
			size_t k = (size_t)hits.at[i].doc;
			mdb_sim_hit h = {doc[a + k], hits.at[i].start + start[a + k] - base[k], hits.at[i].end + start[a + k] - base[k],
			                 hits.at[i].cost};
			if (mdb_sim_hits_push(out, h)) {
				goto done;
			}
		}
		mdb_sim_hits_best(out, limit);
		before = f;
		a = b;
	}
	rc = 0;
done:
	mdb_sim_hits_free(&hits);
	free(base);
	free(words);
	free(taken);
	return rc;
}
