/* annotate(motion [, model [, tau [, keyframes]]]): the segments of a stored motion under a stored
 * model, LIST(STRUCT(label, start_frame, end_frame, cost, start_s, end_s, confidence)), as the Python
 * UDF (mocapdb.storage.annotations.annotate_motions → mocapdb.annotation.results.segment_table)
 * returns them: Δ per class on the whole motion or, with keyframe preselection, on the slices its
 * stored keyframe query finds (widened by the annotation margins), Δ̄^τ, the label rows and the
 * segmenter of annotation.c. A NULL or unknown motion gives NULL; a NULL or unknown model, or a
 * negative or NaN tau, is an error. tau NULL: each class's τ; keyframes NULL: preselection when the
 * model has keyframe queries. Motions are read a batch at a time and annotated each on its own
 * (every step of the chain is per motion), a batch's motions shared by up to one thread per CPU. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "annotation.h"
#include "archive.h"
#include "functions.h"

DUCKDB_EXTENSION_EXTERN

#define WHAT "annotate"

/* The models of one call, read once each. */
typedef struct {
	char *name;
	mdb_model_entry *entry; /* held for the call (model_cache.c) */
	const mdb_model *m;
	int64_t *min_frames, *min_won; /* per label */
	int64_t *name_rank;            /* per label: its place in the labels sorted by name */
	int any_query;
	/* the model's distinct keyframes (classes share many: 51 of the default model's 83), and per
	 * class and keyframe its index among them: a motion's intervals of one are found once */
	size_t n_kf;
	uint64_t *kf_mask, *kf_value;
	uint16_t *kf_of; /* [class * MDB_MAX_KEYFRAMES + keyframe] */
} named_model;

typedef struct {
	named_model *at;
	size_t n;
} models;

static void models_free(mdb_state *st, models *ms) {
	for (size_t i = 0; i < ms->n; i++) {
		free(ms->at[i].name);
		free(ms->at[i].min_frames);
		free(ms->at[i].min_won);
		free(ms->at[i].name_rank);
		free(ms->at[i].kf_mask);
		free(ms->at[i].kf_value);
		free(ms->at[i].kf_of);
		mdb_release_model(st, ms->at[i].entry);
	}
	free(ms->at);
}

static named_model *model_of(mdb_state *st, models *ms, const char *name, mdb_error *err) {
	for (size_t i = 0; i < ms->n; i++) {
		if (strcmp(ms->at[i].name, name) == 0) {
			return &ms->at[i];
		}
	}
	named_model *grown = realloc(ms->at, (ms->n + 1) * sizeof *grown);
	if (!grown) {
		snprintf(err->text, sizeof err->text, WHAT ": out of memory");
		return NULL;
	}
	ms->at = grown;
	named_model *x = &ms->at[ms->n];
	memset(x, 0, sizeof *x);
	if (mdb_acquire_model(st, name, &x->entry, err)) {
		return NULL;
	}
	ms->n++;
	x->m = mdb_entry_model(x->entry);
	size_t L = x->m->n_labels;
	x->name = strdup(name);
	x->min_frames = malloc((L ? L : 1) * sizeof *x->min_frames);
	x->min_won = malloc((L ? L : 1) * sizeof *x->min_won);
	x->name_rank = malloc((L ? L : 1) * sizeof *x->name_rank);
	size_t C = x->m->n_classes ? x->m->n_classes : 1;
	x->kf_mask = malloc(C * MDB_MAX_KEYFRAMES * sizeof *x->kf_mask);
	x->kf_value = malloc(C * MDB_MAX_KEYFRAMES * sizeof *x->kf_value);
	x->kf_of = malloc(C * MDB_MAX_KEYFRAMES * sizeof *x->kf_of);
	if (!x->name || !x->min_frames || !x->min_won || !x->name_rank || !x->kf_mask || !x->kf_value || !x->kf_of) {
		snprintf(err->text, sizeof err->text, WHAT ": out of memory");
		return NULL;
	}
	for (size_t k = 0; k < x->m->n_classes; k++) {
		const mdb_query *q = &x->m->query[k];
		for (size_t i = 0; i < q->K; i++) {
			size_t d = 0;
			while (d < x->n_kf && (x->kf_mask[d] != q->mask[i] || x->kf_value[d] != q->value[i])) {
				d++;
			}
			if (d == x->n_kf) {
				x->kf_mask[d] = q->mask[i];
				x->kf_value[d] = q->value[i];
				x->n_kf++;
			}
			x->kf_of[k * MDB_MAX_KEYFRAMES + i] = (uint16_t)d;
		}
	}
	/* postprocess.label_min_frames / label_min_won: per label its most lenient class */
	for (size_t p = 0; p < L; p++) {
		x->min_frames[p] = INT64_MAX;
	}
	for (size_t k = 0; k < x->m->n_classes; k++) {
		int64_t p = x->m->label_of[k];
		if (x->m->min_frames[k] < x->min_frames[p]) {
			x->min_frames[p] = x->m->min_frames[k];
		}
		x->any_query |= x->m->query[k].K > 0;
	}
	for (size_t p = 0; p < L; p++) {
		x->name_rank[p] = 0;
		for (size_t q = 0; q < L; q++) {
			x->name_rank[p] += strcmp(x->m->label[q], x->m->label[p]) < 0;
		}
		x->min_won[p] = (int64_t)ceil((double)x->min_frames[p] * MDB_WON_FRACTION - 1e-9);
	}
	return x;
}

/* Per-motion work arrays, grown as motions need, and the scratch of Δ and the hit extraction. */
typedef struct {
	double *label_cd, *label_ratio, *delta, *cd;
	int64_t *starts, *stamp;
	char *touched; /* per label: its rows were set for this motion (the others are never read) */
	size_t frames, cells, labels;
	/* the motion's intervals of each distinct keyframe found so far: at kf_at[d] in kf_pool, kf_n[d]
	 * of them (SIZE_MAX: not yet looked for) */
	mdb_spans kf_pool;
	size_t *kf_at, *kf_n, kf_cap;
	mdb_spans slices, iv;
	mdb_dp_scratch dp;
	mdb_hit_scratch hits;
} work;

static void work_free(work *w) {
	free(w->label_cd);
	free(w->label_ratio);
	free(w->delta);
	free(w->cd);
	free(w->starts);
	free(w->stamp);
	free(w->touched);
	free(w->kf_at);
	free(w->kf_n);
	mdb_spans_free(&w->kf_pool);
	mdb_spans_free(&w->slices);
	mdb_spans_free(&w->iv);
	mdb_dp_scratch_free(&w->dp);
	mdb_hit_scratch_free(&w->hits);
}

static int work_reserve(work *w, size_t n, size_t L, size_t n_kf) {
	n = n ? n : 1;
	L = L ? L : 1;
	if (n_kf > w->kf_cap) {
		free(w->kf_at);
		free(w->kf_n);
		w->kf_at = malloc(n_kf * sizeof *w->kf_at);
		w->kf_n = malloc(n_kf * sizeof *w->kf_n);
		w->kf_cap = w->kf_at && w->kf_n ? n_kf : 0;
		if (!w->kf_cap) {
			return -1;
		}
	}
	if (n > w->frames) {
		free(w->delta);
		free(w->cd);
		free(w->starts);
		free(w->stamp);
		w->delta = malloc(n * sizeof *w->delta);
		w->cd = malloc(n * sizeof *w->cd);
		w->starts = malloc(n * sizeof *w->starts);
		w->stamp = malloc(n * sizeof *w->stamp);
		w->frames = n;
		if (!w->delta || !w->cd || !w->starts || !w->stamp) {
			w->frames = 0;
			return -1;
		}
	}
	if (L > w->labels) {
		free(w->touched);
		w->touched = malloc(L);
		w->labels = w->touched ? L : 0;
		if (!w->touched) {
			return -1;
		}
	}
	if (n * L > w->cells) {
		free(w->label_cd);
		free(w->label_ratio);
		w->label_cd = malloc(n * L * sizeof *w->label_cd);
		w->label_ratio = malloc(n * L * sizeof *w->label_ratio);
		w->cells = n * L;
		if (!w->label_cd || !w->label_ratio) {
			w->cells = 0;
			return -1;
		}
	}
	return 0;
}

/* The preselected slices of class k of one motion (its runs r[a..b)), into w->slices; the intervals
 * of its keyframes from those found for the motion so far (kf: the keyframes' distinct indices). */
static int class_slices(const mdb_query *q, const uint16_t *kf, const mdb_runs *r, size_t a, size_t b, int64_t n,
                        work *w) {
	size_t off[MDB_MAX_KEYFRAMES + 1];
	w->slices.n = 0;
	w->iv.n = 0;
	off[0] = 0;
	for (size_t k = 0; k < q->K; k++) {
		size_t d = kf[k];
		if (w->kf_n[d] == SIZE_MAX) {
			w->kf_at[d] = w->kf_pool.n;
			if (mdb_keyframe_intervals(r, a, b, q->mask[k], q->value[k], &w->kf_pool)) {
				return -1;
			}
			w->kf_n[d] = w->kf_pool.n - w->kf_at[d];
		}
		for (size_t i = w->kf_at[d]; i < w->kf_at[d] + w->kf_n[d]; i++) {
			if (mdb_spans_push(&w->iv, w->kf_pool.start[i], w->kf_pool.end[i])) {
				return -1;
			}
		}
		off[k + 1] = w->iv.n;
		if (off[k + 1] == off[k]) {
			return 0; /* a keyframe that never matches: no chain */
		}
	}
	return mdb_chain_document(q->K, w->iv.start, w->iv.end, off, q->d_min, q->d_max, n, q->ext_l, q->ext_r,
	                          &w->slices);
}

/* The segments of one motion of n frames (words), runs its postings (NULL: no preselection). */
static int annotate_motion(const named_model *nm, const uint64_t *words, size_t n, const mdb_runs *runs, size_t ra,
                           size_t rb, int tau_given, double tau, work *w, mdb_segments *out, mdb_error *err) {
	const mdb_model *m = nm->m;
	size_t L = m->n_labels;
	if (work_reserve(w, n, L, nm->n_kf)) {
		snprintf(err->text, sizeof err->text, WHAT ": out of memory");
		return -1;
	}
	/* a label's rows are +inf until a class of it has a hit: set then (most labels have none in a
	 * motion, and its rows are n doubles each) */
	memset(w->touched, 0, L);
	w->kf_pool.n = 0;
	for (size_t d = 0; d < nm->n_kf; d++) {
		w->kf_n[d] = SIZE_MAX;
	}
	for (size_t f = 0; f < n; f++) {
		w->stamp[f] = -1;
	}
	for (size_t k = 0; k < m->n_classes; k++) {
		double t = tau_given ? tau : m->tau[k];
		int rc = 0;
		if (runs && m->query[k].K > 0) {
			rc = class_slices(&m->query[k], nm->kf_of + k * MDB_MAX_KEYFRAMES, runs, ra, rb, (int64_t)n, w);
		} else {
			w->slices.n = 0;
			rc = n ? mdb_spans_push(&w->slices, 0, (int64_t)n - 1) : 0;
		}
		if (rc) {
			snprintf(err->text, sizeof err->text,
			         rc == -2 ? WHAT ": illegal interval in the reconstruction of a keyframe hit" : WHAT ": out of memory");
			return -1;
		}
		/* Each slice is a document of its own, and where slices overlap the class's Δ̄^τ is the later
		 * one's: so the slices are taken last to first and a frame takes the first value it gets
		 * (stamp: the last class that gave it one). combine_by_label: the label's row keeps the
		 * minimum over its classes (the class's rows are +inf outside its slices). */
		double *label_cd = w->label_cd + (size_t)m->label_of[k] * n;
		double *label_ratio = w->label_ratio + (size_t)m->label_of[k] * n;
		/* with preselection, Δ is computed only where it can be <= τ (the rest cannot make a hit):
		 * the same Δ̄^τ, with fewer cells of the DP (distance.h) */
		double bound = runs ? t : INFINITY;
		for (size_t q = w->slices.n; q-- > 0;) {
			size_t a = (size_t)w->slices.start[q], len = (size_t)(w->slices.end[q] - w->slices.start[q] + 1);
			int hits = -1;
			if (mdb_mt_distance_in(&m->tpl[k], words + a, len, w->delta, w->starts, bound, &w->dp) ||
			    (hits = mdb_classification_delta(w->delta, w->starts, len, t, w->cd, &w->hits)) < 0) {
				snprintf(err->text, sizeof err->text, WHAT ": out of memory");
				return -1;
			}
			if (!hits) { /* +inf throughout: the slice only claims its frames */
				for (size_t j = 0; j < len; j++) {
					w->stamp[a + j] = (int64_t)k;
				}
				continue;
			}
			if (!w->touched[m->label_of[k]]) {
				w->touched[m->label_of[k]] = 1;
				for (size_t f = 0; f < n; f++) {
					label_cd[f] = INFINITY;
					label_ratio[f] = INFINITY;
				}
			}
			for (size_t j = 0; j < len; j++) {
				if (w->stamp[a + j] == (int64_t)k) {
					continue; /* a later slice gave it its value */
				}
				w->stamp[a + j] = (int64_t)k;
				double cd = w->cd[j];
				if (cd == INFINITY) {
					continue; /* lowers neither row */
				}
				/* chain._tau_ratio: at τ = 0 only a perfect match counts, as 0 */
				double ratio = t > 0 ? cd / t : cd <= 0 ? 0.0 : INFINITY;
				if (cd < label_cd[a + j]) {
					label_cd[a + j] = cd;
				}
				if (ratio < label_ratio[a + j]) {
					label_ratio[a + j] = ratio;
				}
			}
		}
	}
	mdb_label_rules rules = {L,
	                         m->concurrent,
	                         nm->min_frames,
	                         nm->min_won,
	                         m->margin,
	                         m->conf_n,
	                         m->conf_cut,
	                         m->conf_value,
	                         m->conf_min_length,
	                         m->conf_length_weight,
	                         m->conf_full_length,
	                         m->conf_length_product,
	                         w->touched};
	if (mdb_label_segments(w->label_cd, w->label_ratio, n, &rules, out)) {
		snprintf(err->text, sizeof err->text, WHAT ": out of memory");
		return -1;
	}
	return 0;
}

/* segment_table's order within a motion: start frame, then label name (by its rank) */
typedef struct {
	int64_t start, rank;
	size_t i;
} sort_key;

static int by_start_label(const void *a, const void *b) {
	const sort_key *x = a, *y = b;
	if (x->start != y->start) {
		return x->start < y->start ? -1 : 1;
	}
	if (x->rank != y->rank) {
		return x->rank < y->rank ? -1 : 1;
	}
	return (x->i > y->i) - (x->i < y->i);
}

/* Sort the segments as segment_table; 0 or -1 (out of memory). */
static int sort_segments(mdb_segments *s, const int64_t *name_rank) {
	if (s->n < 2) {
		return 0;
	}
	sort_key *k = malloc((s->n ? s->n : 1) * sizeof *k);
	mdb_segment *sorted = malloc((s->n ? s->n : 1) * sizeof *sorted);
	if (!k || !sorted) {
		free(k);
		free(sorted);
		return -1;
	}
	for (size_t i = 0; i < s->n; i++) {
		k[i] = (sort_key){s->at[i].start, name_rank[s->at[i].label], i};
	}
	qsort(k, s->n, sizeof *k, by_start_label);
	for (size_t i = 0; i < s->n; i++) {
		sorted[i] = s->at[k[i].i];
	}
	memcpy(s->at, sorted, s->n * sizeof *sorted);
	free(k);
	free(sorted);
	return 0;
}

static int valid(duckdb_vector v, idx_t row) {
	return duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), row);
}

/* Append a motion's segments to the list vector; 0 or -1 (out of memory). */
static int write_segments(duckdb_vector output, const mdb_model *m, const mdb_segments *s, double fps, size_t *total) {
	if (duckdb_list_vector_reserve(output, *total + s->n) == DuckDBError) {
		return -1;
	}
	duckdb_vector child = duckdb_list_vector_get_child(output);
	duckdb_vector f_label = duckdb_struct_vector_get_child(child, 0);
	int32_t *start = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 1));
	int32_t *end = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 2));
	double *cost = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 3));
	double *start_s = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 4));
	double *end_s = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 5));
	double *conf = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 6));
	for (size_t i = 0; i < s->n; i++) {
		const mdb_segment *x = &s->at[i];
		size_t o = *total + i;
		duckdb_vector_assign_string_element(f_label, o, m->label[x->label]);
		start[o] = (int32_t)(x->start + 1);
		end[o] = (int32_t)(x->end + 1);
		cost[o] = x->cost;
		start_s[o] = (double)x->start / fps;
		end_s[o] = (double)(x->end + 1) / fps;
		conf[o] = x->confidence;
	}
	*total += s->n;
	duckdb_list_vector_set_size(output, *total);
	return 0;
}

/* A row with a motion to annotate and its settings. */
typedef struct {
	int32_t motion;
	idx_t row;
	size_t model;
	int tau_given, preselect;
	double tau;
} item;

static int by_motion(const void *a, const void *b) {
	const item *x = a, *y = b;
	if (x->motion != y->motion) {
		return x->motion < y->motion ? -1 : 1;
	}
	return (x->row > y->row) - (x->row < y->row);
}

/* Check every row's arguments and read its model (errors before any work); the rows with a
 * motion into items, NULL for the others. */
static int collect(mdb_state *st, duckdb_data_chunk input, idx_t n, models *ms, item *items, size_t *n_items,
                   uint64_t *out_valid, mdb_error *err) {
	idx_t n_cols = duckdb_data_chunk_get_column_count(input);
	duckdb_vector v_motion = duckdb_data_chunk_get_vector(input, 0);
	duckdb_vector v_model = n_cols > 1 ? duckdb_data_chunk_get_vector(input, 1) : NULL;
	duckdb_vector v_tau = n_cols > 2 ? duckdb_data_chunk_get_vector(input, 2) : NULL;
	duckdb_vector v_kf = n_cols > 3 ? duckdb_data_chunk_get_vector(input, 3) : NULL;
	int64_t *motion = duckdb_vector_get_data(v_motion);
	double *tau = v_tau ? duckdb_vector_get_data(v_tau) : NULL;
	bool *kf = v_kf ? duckdb_vector_get_data(v_kf) : NULL;
	*n_items = 0;
	for (idx_t row = 0; row < n; row++) {
		char *name = v_model ? (valid(v_model, row) ? mdb_string_at(v_model, row) : NULL) : strdup("default");
		if (!name) {
			snprintf(err->text, sizeof err->text,
			         v_model && !valid(v_model, row) ? WHAT ": model is NULL; give a model name (default: 'default')"
			                                         : WHAT ": out of memory");
			return -1;
		}
		named_model *nm = model_of(st, ms, name, err);
		free(name);
		if (!nm) {
			return -1;
		}
		item it = {0, row, (size_t)(nm - ms->at), v_tau && valid(v_tau, row), 0, 0.0};
		if (it.tau_given && !(tau[row] >= 0)) {
			snprintf(err->text, sizeof err->text,
			         WHAT ": tau must be a non-negative number or NULL (each class's tau), got %g", tau[row]);
			return -1;
		}
		it.tau = it.tau_given ? tau[row] : 0.0;
		it.preselect = v_kf && valid(v_kf, row) ? kf[row] : nm->any_query;
		if (!valid(v_motion, row) || motion[row] < INT32_MIN || motion[row] > INT32_MAX) {
			duckdb_validity_set_row_invalid(out_valid, row); /* no such motion: NULL */
			continue;
		}
		it.motion = (int32_t)motion[row];
		items[(*n_items)++] = it;
	}
	return 0;
}

/* most threads one call annotates with (motions are independent) */
#define MAX_THREADS 8

/* The threads of a batch take its items first .. last-1 one at a time (motions differ in length by
 * orders of magnitude), each motion's segments into out[q - first] (stored[q - first] = 0: the
 * motion is not stored). */
typedef struct {
	const item *items;
	size_t first, last, next; /* next: the next item to take (atomic) */
	const models *ms;
	const mdb_words_batch *wb;
	const mdb_runs *runs; /* the batch's postings, or NULL */
	mdb_segments *out;
	char *stored;
	double *fps; /* per item: the rate of its motion's frames */
	int failed;   /* atomic: one thread failed, the others stop */
} batch_work;

typedef struct {
	batch_work *bw;
	work w;
	mdb_error err;
	int failed;
} job;

static void *run_job(void *p) {
	job *j = p;
	batch_work *bw = j->bw;
	for (;;) {
		size_t q = __atomic_fetch_add(&bw->next, 1, __ATOMIC_RELAXED);
		if (q >= bw->last || __atomic_load_n(&bw->failed, __ATOMIC_RELAXED)) {
			break;
		}
		const item *it = &bw->items[q];
		size_t k = mdb_lower_bound(bw->wb->id, bw->wb->n, it->motion);
		if (k == bw->wb->n || bw->wb->id[k] != it->motion) {
			continue; /* not stored: NULL */
		}
		bw->stored[q - bw->first] = 1;
		bw->fps[q - bw->first] = bw->wb->fps[k];
		/* the motion's runs: ra .. rb of the batch's (motion, run) order */
		const mdb_runs *runs = it->preselect ? bw->runs : NULL;
		size_t ra = 0, rb = 0;
		if (runs) {
			ra = mdb_lower_bound(runs->motion, runs->n, it->motion);
			for (rb = ra; rb < runs->n && runs->motion[rb] == it->motion; rb++) {
			}
		}
		const named_model *nm = &bw->ms->at[it->model];
		mdb_segments *segs = &bw->out[q - bw->first];
		int rc = annotate_motion(nm, bw->wb->words + bw->wb->off[k], (size_t)bw->wb->n_frames[k], runs, ra, rb,
		                         it->tau_given, it->tau, &j->w, segs, &j->err);
		if (!rc && sort_segments(segs, nm->name_rank)) {
			snprintf(j->err.text, sizeof j->err.text, WHAT ": out of memory");
			rc = -1;
		}
		if (rc) {
			j->failed = 1;
			__atomic_store_n(&bw->failed, 1, __ATOMIC_RELAXED);
		}
	}
	return NULL;
}

/* Run the batch's items on up to n_jobs threads (the calling one included); 0, or -1 with err set. */
static int annotate_batch(batch_work *bw, job *jobs, size_t n_jobs, mdb_error *err) {
	size_t n = bw->last - bw->first;
	if (n_jobs > n) {
		n_jobs = n ? n : 1;
	}
	pthread_t tid[MAX_THREADS];
	int started[MAX_THREADS] = {0};
	bw->next = bw->first;
	bw->failed = 0;
	for (size_t t = 0; t < n_jobs; t++) {
		jobs[t].bw = bw;
		jobs[t].failed = 0;
		/* the calling thread runs job 0; a thread that cannot start leaves the items to the others */
		started[t] = t > 0 && pthread_create(&tid[t], NULL, run_job, &jobs[t]) == 0;
	}
	run_job(&jobs[0]);
	int rc = 0;
	for (size_t t = 0; t < n_jobs; t++) {
		if (started[t]) {
			pthread_join(tid[t], NULL);
		}
		if (jobs[t].failed && rc == 0) {
			*err = jobs[t].err;
			rc = -1;
		}
	}
	return rc;
}

static int by_id(const void *a, const void *b) {
	int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
	return (x > y) - (x < y);
}

/* The motion ids collect() takes into items, ascending (a motion as often as rows name it). */
static size_t motion_ids(duckdb_data_chunk input, idx_t n, int32_t *ids) {
	duckdb_vector v = duckdb_data_chunk_get_vector(input, 0);
	int64_t *motion = duckdb_vector_get_data(v);
	size_t k = 0;
	for (idx_t row = 0; row < n; row++) {
		if (valid(v, row) && motion[row] >= INT32_MIN && motion[row] <= INT32_MAX) {
			ids[k++] = (int32_t)motion[row];
		}
	}
	qsort(ids, k, sizeof *ids, by_id);
	return k;
}

/* What a call reads without its model: the motions' frame counts and the first batch's words, on
 * the extension's data connection while the calling thread gets the model on the main one (the
 * query that says whether a kept model is current, or the model's read: model_cache.c). */
typedef struct {
	mdb_state *st;
	const int32_t *ids;
	size_t n_ids;
	mdb_motions *range;
	size_t *m, *i;
	mdb_words_batch *b;
	mdb_error err;
	int rc;
	/* planned: the first batch's motions (b's ids, *i) are known (1), or cannot be (-1); 0: not yet */
	pthread_mutex_t mu;
	pthread_cond_t cv;
	int planned;
} prefetch;

static void *run_prefetch(void *p) {
	prefetch *f = p;
	int rc = mdb_read_motion_range(f->st, f->ids[0], f->ids[f->n_ids - 1], f->range, &f->err) ||
	         mdb_plan_batch(f->range, f->m, f->ids, f->n_ids, f->i, MDB_BATCH_FRAMES, f->b, &f->err);
	pthread_mutex_lock(&f->mu);
	f->planned = rc ? -1 : 1;
	pthread_cond_signal(&f->cv);
	pthread_mutex_unlock(&f->mu);
	f->rc = rc || mdb_read_batch_words(f->st, f->b, &f->err);
	return NULL;
}

/* The first batch's index runs, read on the main connection while the data connection reads its
 * words (the batch's motions are known before its words are read): NULL when none is needed, or
 * after an error (*failed, err set). */
static mdb_batch *early_runs(mdb_state *st, prefetch *f, const item *items, int *failed, mdb_error *err) {
	pthread_mutex_lock(&f->mu);
	while (!f->planned) {
		pthread_cond_wait(&f->cv, &f->mu);
	}
	int planned = f->planned;
	pthread_mutex_unlock(&f->mu);
	int preselect = 0;
	for (size_t q = 0; planned == 1 && q < *f->i; q++) {
		preselect |= items[q].preselect;
	}
	if (!preselect || !f->b->n) {
		return NULL;
	}
	mdb_batch *batch = mdb_acquire_runs(st, f->b->id[0], f->b->id[f->b->n - 1], err);
	*failed = !batch;
	return batch;
}

/* Rows' motions a batch at a time (mdb_read_batch: one query for the words, one for the postings
 * when a row preselects; the first batch read while the model is), then each row's segments into
 * the list vector. */
static void annotate_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	duckdb_vector_ensure_validity_writable(output);
	uint64_t *out_valid = duckdb_vector_get_validity(output);
	models ms = {0};
	mdb_motions range = {0};
	mdb_words_batch b = {0};
	mdb_error err = {{0}};
	mdb_batch *batch = NULL, *early = NULL; /* early: the first batch's runs, read beside its words */
	mdb_error early_err = {{0}};
	int early_failed = 0;
	job jobs[MAX_THREADS];
	long cpus = sysconf(_SC_NPROCESSORS_ONLN);
	size_t n_jobs = cpus < 1 ? 1 : cpus > MAX_THREADS ? MAX_THREADS : (size_t)cpus;
	item *items = malloc((n ? n : 1) * sizeof *items);
	int32_t *ids = malloc((n ? n : 1) * sizeof *ids);
	mdb_segments *out = calloc(n ? n : 1, sizeof *out);
	char *stored = malloc(n ? n : 1);
	double *fps = malloc((n ? n : 1) * sizeof *fps);
	size_t n_items = 0, total = 0;
	int failed = 1;
	memset(jobs, 0, sizeof jobs);
	for (idx_t row = 0; row < n; row++) {
		entries[row].offset = 0;
		entries[row].length = 0;
	}
	if (!items || !ids || !out || !stored || !fps) {
		snprintf(err.text, sizeof err.text, WHAT ": out of memory");
		goto done;
	}
	if (mdb_check_live(st, &err)) {
		goto done;
	}
	size_t i = 0, m = 0; /* next item; next stored motion of the range */
	size_t n_ids = motion_ids(input, n, ids);
	prefetch f = {st, ids, n_ids, &range, &m, &i, &b, {{0}}, 0, PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0};
	pthread_t reader;
	int started = n_ids && pthread_create(&reader, NULL, run_prefetch, &f) == 0;
	int bad = collect(st, input, n, &ms, items, &n_items, out_valid, &err);
	/* the rows collect() took, in the order of ids (the same motions: motion_ids takes the rows it takes) */
	qsort(items, n_items, sizeof *items, by_motion);
	if (started && !bad) {
		early = early_runs(st, &f, items, &early_failed, &early_err);
	}
	if (started) {
		pthread_join(reader, NULL);
	} else if (n_ids && !bad) {
		run_prefetch(&f); /* no thread to spare: after the model */
	}
	if (bad) {
		goto done; /* the arguments' error, before any the reads may have met */
	}
	if (f.rc) {
		err = f.err;
		goto done;
	}
	if (early_failed) {
		err = early_err;
		goto done;
	}
	size_t first = 0; /* the batch's first item; the first batch, items 0 .. i-1, is read */
	while (first < n_items) {
		if (first > 0 && mdb_read_batch(st, &range, &m, ids, n_items, &i, MDB_BATCH_FRAMES, &b, &err)) {
			goto done;
		}
		int preselect = 0;
		for (size_t q = first; q < i; q++) {
			preselect |= items[q].preselect;
		}
		mdb_release_runs(st, batch);
		batch = NULL;
		if (first == 0 && early) { /* read beside the first batch's words */
			batch = early;
			early = NULL;
		} else if (preselect && b.n && !(batch = mdb_acquire_runs(st, b.id[0], b.id[b.n - 1], &err))) {
			goto done;
		}
		for (size_t q = 0; q < i - first; q++) {
			out[q].n = 0;
			stored[q] = 0;
		}
		batch_work bw = {items, first, i, first, &ms, &b, batch ? &batch->runs : NULL, out, stored, fps, 0};
		if (annotate_batch(&bw, jobs, n_jobs, &err)) {
			goto done;
		}
		for (size_t q = first; q < i; q++) {
			const item *it = &items[q];
			if (!stored[q - first]) {
				duckdb_validity_set_row_invalid(out_valid, it->row); /* not stored: NULL */
				continue;
			}
			entries[it->row].offset = total;
			entries[it->row].length = out[q - first].n;
			if (write_segments(output, ms.at[it->model].m, &out[q - first], fps[q - first], &total)) {
				snprintf(err.text, sizeof err.text, WHAT ": out of memory");
				goto done;
			}
		}
		first = i;
	}
	failed = 0;
done:
	mdb_release_runs(st, batch);
	mdb_release_runs(st, early);
	models_free(st, &ms);
	for (size_t t = 0; t < MAX_THREADS; t++) {
		work_free(&jobs[t].w);
	}
	for (size_t q = 0; out && q < n; q++) {
		mdb_segments_free(&out[q]);
	}
	mdb_motions_free(&range);
	mdb_words_batch_free(&b);
	free(items);
	free(ids);
	free(out);
	free(stored);
	free(fps);
	if (failed) {
		duckdb_scalar_function_set_error(info, err.text);
	}
}

static duckdb_logical_type segment_type(void) {
	const char *names[] = {"label", "start_frame", "end_frame", "cost", "start_s", "end_s", "confidence"};
	duckdb_type ids[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_DOUBLE,
	                     DUCKDB_TYPE_DOUBLE,  DUCKDB_TYPE_DOUBLE,  DUCKDB_TYPE_DOUBLE};
	return mdb_struct_list_type(names, ids, 7);
}

static duckdb_scalar_function annotate_function(mdb_state *st, int n_args) {
	duckdb_scalar_function f = duckdb_create_scalar_function();
	duckdb_scalar_function_set_name(f, "annotate");
	duckdb_type args[] = {DUCKDB_TYPE_BIGINT, DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_BOOLEAN};
	for (int i = 0; i < n_args; i++) {
		duckdb_logical_type t = duckdb_create_logical_type(args[i]);
		duckdb_scalar_function_add_parameter(f, t);
		duckdb_destroy_logical_type(&t);
	}
	duckdb_logical_type ret = segment_type();
	duckdb_scalar_function_set_return_type(f, ret);
	duckdb_destroy_logical_type(&ret);
	/* NULLs come in: a NULL motion is a NULL answer, a NULL tau or keyframes the default */
	duckdb_scalar_function_set_special_handling(f);
	duckdb_scalar_function_set_volatile(f);
	duckdb_scalar_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_scalar_function_set_function(f, annotate_fn);
	return f;
}

int mdb_register_annotate(duckdb_connection con, mdb_state *st) {
	duckdb_scalar_function_set set = duckdb_create_scalar_function_set("annotate");
	int rc = 0;
	for (int n_args = 1; n_args <= 4; n_args++) {
		duckdb_scalar_function f = annotate_function(st, n_args);
		rc |= duckdb_add_scalar_function_to_set(set, f) == DuckDBError;
		duckdb_destroy_scalar_function(&f);
	}
	rc |= duckdb_register_scalar_function_set(con, set) == DuckDBError;
	duckdb_destroy_scalar_function_set(&set);
	return rc ? -1 : 0;
}
