/* A query by example over the archive, step for step as mocapdb.storage.retrieval.search_archive
 * (similar_search.h). */
#include "similar_search.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "functions.h"
#include "similar_plan.h"
#include "similar_read.h"

DUCKDB_EXTENSION_EXTERN

/* A batch of motions' words, rebuilt from the index's full runs. */
typedef struct {
	const uint64_t *words;
	const int64_t *off; /* batch motion k at words + off[k] */
} batch_words;

static int fetch_words(void *p, const int64_t *doc, const int64_t *start, const int64_t *stop, size_t n, uint64_t *out) {
	const batch_words *b = p;
	for (size_t k = 0; k < n; k++) {
		size_t len = (size_t)(stop[k] - start[k]);
		if (len) {
			memcpy(out, b->words + b->off[doc[k]] + start[k], len * sizeof *out);
			out += len;
		}
	}
	return 0;
}

typedef struct {
	int64_t *doc, *start, *stop;
	size_t n, cap;
} segments;

static void segments_free(segments *s) {
	free(s->doc);
	free(s->start);
	free(s->stop);
	memset(s, 0, sizeof *s);
}

static int segments_reserve(segments *s, size_t n) {
	if (n <= s->cap) {
		return 0;
	}
	if (mdb_grow(&s->doc, sizeof *s->doc, n) || mdb_grow(&s->start, sizeof *s->start, n) ||
	    mdb_grow(&s->stop, sizeof *s->stop, n)) {
		return -1;
	}
	s->cap = n;
	return 0;
}

/* keyframe_search of one level on the batch's motions (runs ra[k] .. ra[k+1] each): merged,
 * widened segments in (doc, start) order; its frames in *frames */
static int level_segments(const mdb_query *q, const mdb_runs *runs, const size_t *ra, const int64_t *len, size_t m,
                          segments *out, int64_t *frames, mdb_error *err) {
	mdb_spans iv = {0}, hits = {0};
	size_t off[MDB_MAX_KEYFRAMES + 1];
	int rc = 0;
	out->n = 0;
	*frames = 0;
	for (size_t k = 0; k < m && rc == 0; k++) {
		if (ra[k] == ra[k + 1] || len[k] <= 0) {
			continue;
		}
		iv.n = 0;
		hits.n = 0;
		off[0] = 0;
		int absent = 0;
		for (size_t j = 0; j < q->K && rc == 0 && !absent; j++) {
			rc = mdb_keyframe_intervals(runs, ra[k], ra[k + 1], q->mask[j], q->value[j], &iv);
			off[j + 1] = iv.n;
			absent = off[j + 1] == off[j];
		}
		if (rc == 0 && !absent) {
			rc = mdb_chain_document(q->K, iv.start, iv.end, off, q->d_min, q->d_max, len[k], q->ext_l, q->ext_r, &hits);
		}
		if (rc == 0 && segments_reserve(out, out->n + hits.n)) {
			rc = -1;
		}
		for (size_t i = 0; rc == 0 && i < hits.n; i++) {
			out->doc[out->n] = (int64_t)k;
			out->start[out->n] = hits.start[i];
			out->stop[out->n++] = hits.end[i] + 1;
			*frames += hits.end[i] - hits.start[i] + 1;
		}
	}
	mdb_spans_free(&iv);
	mdb_spans_free(&hits);
	if (rc == -2) {
		snprintf(err->text, sizeof err->text, MDB_SIM_WHAT ": illegal interval in the reconstruction of a keyframe hit");
	} else if (rc) {
		mdb_sim_oom(err);
	}
	return rc;
}

/* One batch of motions ids[a .. b): its words from the index, preselected or whole, ranked. */
static int search_batch(mdb_state *st, const mdb_sim_motions *motions, size_t a, size_t b, int64_t n_frames,
                        int64_t budget, const mdb_sim_ranker *r, const mdb_query *levels, int n_levels, int64_t q_id, int64_t q_first,
                        int64_t q_last, int64_t limit, mdb_sim_hits *found, mdb_error *err) {
	size_t m = b - a;
	int rc = -1;
	mdb_batch *batch = mdb_acquire_runs(st, motions->id[a], motions->id[b - 1], err);
	int64_t *off = malloc((m + 1) * sizeof *off);
	size_t *ra = malloc((m + 1) * sizeof *ra);
	uint64_t *w = NULL;
	segments segs = {0};
	mdb_sim_hits hits = {0};
	if (!batch) {
		goto done;
	}
	if (!off || !ra) {
		mdb_sim_oom(err);
		goto done;
	}
	const mdb_runs *runs = &batch->runs;
	off[0] = 0;
	for (size_t k = 0; k < m; k++) {
		off[k + 1] = off[k] + motions->len[a + k];
	}
	w = malloc((size_t)(off[m] ? off[m] : 1) * sizeof *w);
	if (!w) {
		mdb_sim_oom(err);
		goto done;
	}
	/* each motion's words from its runs, which tile it */
	size_t i = 0;
	for (size_t k = 0; k < m; k++) {
		int32_t id = motions->id[a + k];
		while (i < runs->n && runs->motion[i] < id) {
			i++; /* a motion not ranked (no complete feature rows) */
		}
		ra[k] = i;
		int64_t f = 0;
		while (i < runs->n && runs->motion[i] == id) {
			if (runs->start[i] != f || f + runs->len[i] > motions->len[a + k]) {
				break;
			}
			for (int64_t j = 0; j < runs->len[i]; j++) {
				w[off[k] + f + j] = runs->word[i];
			}
			f += runs->len[i];
			i++;
		}
		if (f != motions->len[a + k] || (i < runs->n && runs->motion[i] == id)) {
			snprintf(err->text, sizeof err->text,
			         MDB_SIM_WHAT ": the keyframe index does not hold motion %d as its features do; rebuild it with `mocapdb "
			              "create-index`",
			         id);
			goto done;
		}
	}
	ra[m] = i;
	int64_t batch_frames = off[m];
	if (n_levels == 0) {
		if (segments_reserve(&segs, m)) {
			mdb_sim_oom(err);
			goto done;
		}
		for (size_t k = 0; k < m; k++) {
			segs.doc[k] = (int64_t)k;
			segs.start[k] = 0;
			segs.stop[k] = motions->len[a + k];
		}
		segs.n = m;
	} else {
		/* preselect(force=True): the most lenient level within the batch's share of the budget, else
		 * the strictest; the share int(CELL_BUDGET · frames / n_frames), a correctly rounded quotient
		 * (exact operands below 2^53) truncated as Python's int() does */
		int64_t share = (int64_t)((double)(budget * batch_frames) / (double)n_frames);
		for (int l = 0; l < n_levels; l++) {
			int64_t frames;
			if (level_segments(&levels[l], runs, ra, motions->len + a, m, &segs, &frames, err)) {
				goto done;
			}
			if (mdb_sim_rank_cells(frames, r->t->K) <= share) {
				break;
			}
		}
	}
	int64_t ex_doc = -1;
	for (size_t k = 0; k < m; k++) {
		if (motions->id[a + k] == q_id) {
			ex_doc = (int64_t)k;
		}
	}
	batch_words bw = {w, off};
	int s = mdb_sim_search_segments(r, fetch_words, &bw, segs.doc, segs.start, segs.stop, segs.n, ex_doc, q_first,
	                                q_last, limit, &hits);
	if (s) {
		mdb_sim_oom(err);
		goto done;
	}
	for (size_t h = 0; h < hits.n; h++) {
		mdb_sim_hit x = hits.at[h];
		x.doc = motions->id[a + (size_t)x.doc];
		if (mdb_sim_hits_push(found, x)) {
			mdb_sim_oom(err);
			goto done;
		}
	}
	mdb_sim_hits_best(found, limit);
	rc = 0;
done:
	if (batch) {
		mdb_release_runs(st, batch);
	}
	free(off);
	free(ra);
	free(w);
	segments_free(&segs);
	mdb_sim_hits_free(&hits);
	return rc;
}

/* CELL_BUDGET: MOCAPDB_CELL_BUDGET when a positive integer below 2^31 (as mocapdb.retrieval.search
 * reads it) */
static int64_t cell_budget(void) {
	const char *text = getenv("MOCAPDB_CELL_BUDGET");
	if (!text) {
		return MDB_SIM_CELL_BUDGET;
	}
	while (*text == ' ' || *text == '\t' || *text == '\n') {
		text++;
	}
	int64_t v = 0;
	const char *p = text;
	for (; *p >= '0' && *p <= '9' && v <= INT32_MAX; p++) {
		v = 10 * v + (*p - '0');
	}
	while (*p == ' ' || *p == '\t' || *p == '\n') {
		p++;
	}
	/* below 2^31: budget · frames stays below 2^53 for batches of up to 2^22 frames (exact) */
	return *text == 0 ? MDB_SIM_CELL_BUDGET : (*p == 0 && p > text && v > 0 && v <= INT32_MAX ? v : MDB_SIM_CELL_BUDGET);
}

/* search_archive for one query stretch: the best limit hits of the archive, doc = motion id */
int mdb_sim_search_archive(mdb_state *st, int64_t q_id, int64_t q_first, const uint64_t *q_words, size_t K,
                           int64_t limit, mdb_sim_hits *found, mdb_error *err) {
	mdb_sim_motions motions = {0};
	mdb_sim_words sample = {0};
	mdb_sim_template t = {0}, sparse = {0};
	mdb_query levels[MDB_SIM_LEVELS];
	int n_levels = 0, rc = -1;
	int64_t budget = cell_budget();
	if (mdb_sim_check_index(st, err) || mdb_sim_read_motions(st, &motions, err)) {
		goto done;
	}
	int64_t n_frames = 0;
	for (size_t k = 0; k < motions.n; k++) {
		n_frames += motions.len[k];
	}
	if (n_frames == 0) {
		snprintf(err->text, sizeof err->text, MDB_SIM_WHAT ": the archive is empty: ingest motions first");
		goto done;
	}
	int64_t step = n_frames / MDB_SIM_SAMPLE_FRAMES;
	int32_t step32 = (int32_t)(step > 1 ? step : 1);
	if (mdb_sim_read_sample(st, step32, &sample, err)) {
		goto done;
	}
	if (sample.n == 0) {
		snprintf(err->text, sizeof err->text,
		         MDB_SIM_WHAT ": the archive sample must be a non-empty 1-D array of words (an empty archive?)");
		goto done;
	}
	int64_t counts[MDB_SIM_FEATURES] = {0};
	for (size_t j = 0; j < sample.n; j++) {
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			counts[f] += (int64_t)((sample.w[j] >> f) & 1);
		}
	}
	double p_on[MDB_SIM_FEATURES];
	mdb_sim_frequencies(counts, (int64_t)sample.n, p_on);
	if (mdb_sim_clip_template(q_words, K, p_on, &t)) {
		mdb_sim_oom(err);
		goto done;
	}
	double chance = mdb_sim_chance(&t, p_on);
	mdb_sim_ranker r = {&t, NULL, mdb_sim_coarse_step(K), MDB_SIM_TAU_FACTOR * chance};
	if (r.step > 1) {
		if (mdb_sim_sparse_template(&t, r.step, &sparse)) {
			mdb_sim_oom(err);
			goto done;
		}
		r.sparse = &sparse;
	}
	/* the archive within the budget: no preselection, and no keyframes to take from the query */
	if (mdb_sim_rank_cells(n_frames, K) > budget) {
		n_levels = mdb_sim_keyframes(&t, sample.w, sample.n, levels);
		if (n_levels < 0) {
			mdb_sim_oom(err);
			goto done;
		}
	}
	/* frame_batches: consecutive motions of at most MDB_BATCH_FRAMES frames (a longer one alone) */
	size_t a = 0;
	while (a < motions.n) {
		size_t b = a + 1;
		int64_t frames = motions.len[a];
		while (b < motions.n && frames + motions.len[b] <= MDB_BATCH_FRAMES) {
			frames += motions.len[b++];
		}
		if (search_batch(st, &motions, a, b, n_frames, budget, &r, levels, n_levels, q_id, q_first,
		                 q_first + (int64_t)K - 1, limit, found, err)) {
			goto done;
		}
		a = b;
	}
	rc = 0;
done:
	mdb_sim_motions_free(&motions);
	free(sample.w);
	mdb_sim_template_free(&t);
	mdb_sim_template_free(&sparse);
	return rc;
}
