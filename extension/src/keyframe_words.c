/* keyframe_search_words(masks, vals, gap_min, gap_max, extend_left := 0, extend_right := 0):
 * a table function with the rows (motion_id, start_frame, end_frame), 1-based inclusive
 * 30 Hz frames, of every stored motion whose frames hold the keyframe chain (sql/macros.sql
 * describes the arguments; mocapdb.extension.udfs.inline_query is the Python twin of the
 * checks, with the same limits and messages).
 *
 * The query is checked at bind. The search runs a batch of motions at a time (at most
 * BATCH_FRAMES frames of runs read, then searched), so memory stays flat in archive size;
 * rows left over when the output chunk is full wait for the next call. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"
#include "chain.h"
#include "functions.h"

DUCKDB_EXTENSION_EXTERN

#define WHAT "keyframe_search_words"
#define FULL_BITS ((((uint64_t)1) << 40) - 1)

typedef mdb_query query_bind;

typedef struct {
	mdb_motions motions;
	size_t next_motion;   /* first motion of the next batch */
	mdb_batch *batch;     /* the current batch's runs (held from the cache) */
	int32_t *out_motion;  /* rows found in the current batch, not yet emitted */
	mdb_spans out;
	size_t out_cap, emitted;
	int loaded;
	mdb_state *state;
} query_scan;

static void bind_destroy(void *p) {
	free(p);
}

static void scan_destroy(void *p) {
	query_scan *s = p;
	mdb_motions_free(&s->motions);
	mdb_release_runs(s->state, s->batch);
	mdb_spans_free(&s->out);
	free(s->out_motion);
	free(s);
}

/* One integer of a list argument, whatever its integer type: as uint64 (negative: UINT64_MAX,
 * never a 40-bit word) and as int64 (past INT64_MAX: INT64_MAX, never a gap bound). 0 when it is
 * an integer, -1 otherwise. */
static int integer_of(duckdb_value x, uint64_t *as_unsigned, int64_t *as_signed) {
	duckdb_logical_type t = duckdb_get_value_type(x);
	duckdb_type id = duckdb_get_type_id(t);
	switch (id) {
	case DUCKDB_TYPE_TINYINT:
	case DUCKDB_TYPE_SMALLINT:
	case DUCKDB_TYPE_INTEGER:
	case DUCKDB_TYPE_BIGINT:
		*as_signed = duckdb_get_int64(x);
		*as_unsigned = *as_signed < 0 ? UINT64_MAX : (uint64_t)*as_signed;
		return 0;
	case DUCKDB_TYPE_UTINYINT:
	case DUCKDB_TYPE_USMALLINT:
	case DUCKDB_TYPE_UINTEGER:
	case DUCKDB_TYPE_UBIGINT:
		*as_unsigned = duckdb_get_uint64(x);
		*as_signed = *as_unsigned > (uint64_t)INT64_MAX ? INT64_MAX : (int64_t)*as_unsigned;
		return 0;
	default:
		return -1;
	}
}

/* The elements of a list argument (a NULL list: n = -1). The arguments are declared ANY so
 * that integer lists of any type bind (DuckDB casts no list to UBIGINT[] implicitly); anything
 * but a list of integers is an error naming the argument. */
static int list_values(duckdb_bind_info info, idx_t arg, const char *name, uint64_t *as_unsigned, int64_t *as_signed,
                       char *null_at, long *n) {
	char msg[200];
	duckdb_value list = duckdb_bind_get_parameter(info, arg);
	int rc = 0;
	*n = -1;
	if (!list || duckdb_is_null_value(list)) {
		goto done;
	}
	duckdb_logical_type t = duckdb_get_value_type(list);
	if (duckdb_get_type_id(t) != DUCKDB_TYPE_LIST) {
		rc = -1;
		goto done;
	}
	idx_t size = duckdb_get_list_size(list);
	*n = size > (idx_t)LONG_MAX ? LONG_MAX : (long)size;
	for (idx_t i = 0; i < size && i < MDB_MAX_KEYFRAMES; i++) {
		duckdb_value x = duckdb_get_list_child(list, i);
		null_at[i] = !x || duckdb_is_null_value(x);
		if (!null_at[i] && integer_of(x, &as_unsigned[i], &as_signed[i])) {
			rc = -1;
		}
		duckdb_destroy_value(&x);
	}
done:
	duckdb_destroy_value(&list);
	if (rc) {
		snprintf(msg, sizeof msg, WHAT ": %s must be a list of integers", name);
		duckdb_bind_set_error(info, msg);
	}
	return rc;
}

/* the rows of both searches: (motion_id, start_frame, end_frame) */
static void add_hit_columns(duckdb_bind_info info) {
	duckdb_logical_type t = duckdb_create_logical_type(DUCKDB_TYPE_INTEGER);
	duckdb_bind_add_result_column(info, "motion_id", t);
	duckdb_bind_add_result_column(info, "start_frame", t);
	duckdb_bind_add_result_column(info, "end_frame", t);
	duckdb_destroy_logical_type(&t);
}

static void bind_fail(duckdb_bind_info info, const char *msg) {
	duckdb_bind_set_error(info, msg);
}

/* extend_left / extend_right: absent is 0; NULL or out of 0..MDB_MAX_GAP an error. */
static int bind_margin(duckdb_bind_info info, const char *name, int64_t *out) {
	duckdb_value v = duckdb_bind_get_named_parameter(info, name);
	char msg[160];
	*out = 0;
	if (!v) {
		return 0;
	}
	int is_null = duckdb_is_null_value(v);
	int64_t x = is_null ? 0 : duckdb_get_int64(v);
	duckdb_destroy_value(&v);
	if (is_null || x < 0 || x > MDB_MAX_GAP) {
		if (is_null) {
			snprintf(msg, sizeof msg, WHAT ": %s must be in 0..%d frames, got NULL", name, MDB_MAX_GAP);
		} else {
			snprintf(msg, sizeof msg, WHAT ": %s must be in 0..%d frames, got %lld", name, MDB_MAX_GAP,
			         (long long)x);
		}
		bind_fail(info, msg);
		return -1;
	}
	*out = x;
	return 0;
}

static void query_bind_fn(duckdb_bind_info info) {
	char msg[256];
	query_bind *q = calloc(1, sizeof *q);
	if (!q) {
		bind_fail(info, WHAT ": out of memory");
		return;
	}
	long n[4];
	char null_at[4][MDB_MAX_KEYFRAMES];
	uint64_t unsigned_of[4][MDB_MAX_KEYFRAMES];
	int64_t signed_of[4][MDB_MAX_KEYFRAMES];
	static const char *names[4] = {"masks", "vals", "gap_min", "gap_max"};
	for (idx_t i = 0; i < 4; i++) {
		if (list_values(info, i, names[i], unsigned_of[i], signed_of[i], null_at[i], &n[i])) {
			goto fail;
		}
	}
	if (n[0] < 0 || n[1] < 0) {
		bind_fail(info, WHAT ": masks and values must not be NULL");
		goto fail;
	}
	long K = n[0];
	if (K < 1 || K > MDB_MAX_KEYFRAMES) {
		snprintf(msg, sizeof msg, WHAT ": a query has 1..%d keyframes, got %ld", MDB_MAX_KEYFRAMES, K);
		bind_fail(info, msg);
		goto fail;
	}
	if (n[1] != K) {
		snprintf(msg, sizeof msg, WHAT ": %ld masks but %ld values; give one value per mask", K, n[1]);
		bind_fail(info, msg);
		goto fail;
	}
	long n_lo = n[2] < 0 ? 0 : n[2], n_hi = n[3] < 0 ? 0 : n[3];
	if (n_lo != K - 1 || n_hi != K - 1) {
		snprintf(msg, sizeof msg, WHAT ": a query of %ld keyframes needs %ld gap bounds, got %ld d_min and %ld d_max",
		         K, K - 1, n_lo, n_hi);
		bind_fail(info, msg);
		goto fail;
	}
	for (long k = 0; k < K; k++) {
		if (null_at[0][k] || null_at[1][k] || (unsigned_of[0][k] & ~FULL_BITS) ||
		    (unsigned_of[1][k] & ~unsigned_of[0][k])) {
			snprintf(msg, sizeof msg,
			         WHAT ": keyframe %ld must be 40-bit words with value bits only where the mask has bits", k + 1);
			bind_fail(info, msg);
			goto fail;
		}
		q->mask[k] = unsigned_of[0][k];
		q->value[k] = unsigned_of[1][k];
	}
	for (long g = 0; g < K - 1; g++) {
		int lo_ok = !null_at[2][g] && signed_of[2][g] >= 0 && signed_of[2][g] <= MDB_MAX_GAP;
		int hi_ok = null_at[3][g] || (signed_of[3][g] >= (lo_ok ? signed_of[2][g] : 0) && signed_of[3][g] <= MDB_MAX_GAP);
		if (!lo_ok || !hi_ok) {
			snprintf(msg, sizeof msg,
			         WHAT ": gap %ld must have 0 <= d_min <= d_max <= %d frames (d_max NULL = unbounded)", g + 1,
			         MDB_MAX_GAP);
			bind_fail(info, msg);
			goto fail;
		}
		q->d_min[g] = signed_of[2][g];
		q->d_max[g] = null_at[3][g] ? MDB_UNBOUNDED : signed_of[3][g];
	}
	q->K = (size_t)K;
	if (bind_margin(info, "extend_left", &q->ext_l) || bind_margin(info, "extend_right", &q->ext_r)) {
		goto fail;
	}
	add_hit_columns(info);
	duckdb_bind_set_bind_data(info, q, bind_destroy);
	return;
fail:
	free(q);
}

/* keyframe_search(class [, model := 'default'] [, extend := false]): a class's stored query */
static void class_bind_fn(duckdb_bind_info info) {
	mdb_state *st = duckdb_bind_get_extra_info(info);
	duckdb_value v_cls = duckdb_bind_get_parameter(info, 0);
	duckdb_value v_model = duckdb_bind_get_named_parameter(info, "model");
	duckdb_value v_extend = duckdb_bind_get_named_parameter(info, "extend");
	char *cls = v_cls && !duckdb_is_null_value(v_cls) ? duckdb_get_varchar(v_cls) : NULL;
	int model_null = v_model && duckdb_is_null_value(v_model);
	char *model = v_model && !model_null ? duckdb_get_varchar(v_model) : NULL;
	int extend = v_extend && !duckdb_is_null_value(v_extend) && duckdb_get_bool(v_extend);
	const char *model_name = model ? model : "default";
	query_bind *q = calloc(1, sizeof *q);
	mdb_error err = {{0}};
	if (!q) {
		snprintf(err.text, sizeof err.text, "keyframe_search: out of memory");
	} else if (model_null) {
		snprintf(err.text, sizeof err.text, "keyframe_search: model is NULL; give a model name (default: 'default')");
	} else if (!cls) {
		snprintf(err.text, sizeof err.text, "keyframe_search: class is NULL; give one of model '%s''s classes",
		         model_name);
	} else if (mdb_read_keyframe_query(st, model_name, cls, extend, q, &err) == 0) {
		add_hit_columns(info);
		duckdb_bind_set_bind_data(info, q, bind_destroy);
		q = NULL;
	}
	if (q) {
		duckdb_bind_set_error(info, err.text);
		free(q);
	}
	duckdb_free(cls);
	duckdb_free(model);
	duckdb_destroy_value(&v_cls);
	duckdb_destroy_value(&v_model);
	duckdb_destroy_value(&v_extend);
}

static void query_init_fn(duckdb_init_info info) {
	query_scan *s = calloc(1, sizeof *s);
	if (!s) {
		duckdb_init_set_error(info, WHAT ": out of memory");
		return;
	}
	s->state = duckdb_init_get_extra_info(info);
	duckdb_init_set_init_data(info, s, scan_destroy);
	duckdb_init_set_max_threads(info, 1);
}

/* Intervals of matching frames of one keyframe in one motion's runs r[a..b): runs of
 * matching words, merged when adjacent (KEYFRAMES.md §3). Annotation asks this of every keyframe
 * of every class of every motion: the scan for a matching run is a tight loop over the words, and
 * an interval is pushed once it ends. */
int mdb_keyframe_intervals(const mdb_runs *r, size_t a, size_t b, uint64_t mask, uint64_t value, mdb_spans *iv) {
	const uint64_t *word = r->word;
	const int64_t *start = r->start, *len = r->len;
	size_t i = a;
	for (;;) {
		while (i < b && (word[i] & mask) != value) {
			i++;
		}
		if (i >= b) {
			return 0;
		}
		int64_t s = start[i], e = start[i] + len[i] - 1;
		for (i++; i < b && (word[i] & mask) == value; i++) {
			if (start[i] != e + 1) { /* not adjacent: an interval of its own */
				if (mdb_spans_push(iv, s, e)) {
					return -1;
				}
				s = start[i];
			}
			e = start[i] + len[i] - 1;
		}
		if (mdb_spans_push(iv, s, e)) {
			return -1;
		}
	}
}

/* Search the next batch of motions into s->out / s->out_motion. */
static int search_batch(mdb_state *st, const query_bind *q, query_scan *s, mdb_error *err) {
	size_t first = s->next_motion, last = first;
	int64_t frames = 0;
	while (last < s->motions.n && (last == first || frames + s->motions.n_frames[last] <= MDB_BATCH_FRAMES)) {
		frames += s->motions.n_frames[last++];
	}
	s->next_motion = last;
	s->out.n = 0;
	s->emitted = 0;
	mdb_release_runs(st, s->batch);
	s->batch = mdb_acquire_runs(st, s->motions.id[first], s->motions.id[last - 1], err);
	if (!s->batch) {
		return -1;
	}
	const mdb_runs *runs = &s->batch->runs;
	mdb_spans iv = {0};
	size_t off[MDB_MAX_KEYFRAMES + 1];
	size_t r = 0;
	int rc = 0;
	for (size_t m = first; m < last && rc == 0; m++) {
		int32_t id = s->motions.id[m];
		while (r < runs->n && runs->motion[r] < id) {
			r++; /* runs of a motion id the motions table lacks */
		}
		size_t a = r;
		while (r < runs->n && runs->motion[r] == id) {
			r++;
		}
		if (a == r || s->motions.n_frames[m] <= 0) {
			continue;
		}
		iv.n = 0;
		off[0] = 0;
		int absent = 0; /* a keyframe that never matches here: no chain, the other keyframes unread */
		for (size_t k = 0; k < q->K && rc == 0 && !absent; k++) {
			rc = mdb_keyframe_intervals(runs, a, r, q->mask[k], q->value[k], &iv);
			off[k + 1] = iv.n;
			absent = off[k + 1] == off[k];
		}
		size_t before = s->out.n;
		if (rc == 0 && !absent) {
			rc = mdb_chain_document(q->K, iv.start, iv.end, off, q->d_min, q->d_max, s->motions.n_frames[m], q->ext_l,
			                        q->ext_r, &s->out);
		}
		if (rc == 0 && s->out.n > s->out_cap) {
			int32_t *grown = realloc(s->out_motion, s->out.cap * sizeof *grown);
			if (!grown) {
				rc = -1;
			} else {
				s->out_motion = grown;
				s->out_cap = s->out.cap;
			}
		}
		for (size_t i = before; rc == 0 && i < s->out.n; i++) {
			s->out_motion[i] = id;
		}
	}
	mdb_spans_free(&iv);
	if (rc == -2) {
		snprintf(err->text, sizeof err->text, WHAT ": illegal interval in the reconstruction of a hit");
	} else if (rc) {
		snprintf(err->text, sizeof err->text, WHAT ": out of memory");
	}
	return rc;
}

static void query_fn(duckdb_function_info info, duckdb_data_chunk output) {
	mdb_state *st = duckdb_function_get_extra_info(info);
	const query_bind *q = duckdb_function_get_bind_data(info);
	query_scan *s = duckdb_function_get_init_data(info);
	mdb_error err = {{0}};
	if (!s->loaded) {
		if (mdb_check_live(st, &err) || mdb_read_motion_range(st, INT32_MIN, INT32_MAX, &s->motions, &err)) {
			duckdb_function_set_error(info, err.text);
			return;
		}
		s->loaded = 1;
	}
	int32_t *o_id = duckdb_vector_get_data(duckdb_data_chunk_get_vector(output, 0));
	int32_t *o_s = duckdb_vector_get_data(duckdb_data_chunk_get_vector(output, 1));
	int32_t *o_e = duckdb_vector_get_data(duckdb_data_chunk_get_vector(output, 2));
	idx_t cap = duckdb_vector_size(), n = 0;
	while (n < cap) {
		if (s->emitted == s->out.n) {
			if (s->next_motion >= s->motions.n) {
				break;
			}
			if (search_batch(st, q, s, &err)) {
				duckdb_function_set_error(info, err.text);
				return;
			}
			continue;
		}
		size_t i = s->emitted++;
		o_id[n] = s->out_motion[i];
		o_s[n] = (int32_t)(s->out.start[i] + 1);
		o_e[n] = (int32_t)(s->out.end[i] + 1);
		n++;
	}
	duckdb_data_chunk_set_size(output, n);
}

/* A search table function: positional parameters of the types `positional` (n_positional of them),
 * named ones `names` of the types `named`; the rows of query_fn from the query `bind` makes. */
static int register_search(duckdb_connection con, mdb_state *st, const char *name, duckdb_table_function_bind_t bind,
                           const duckdb_type *positional, int n_positional, const char *const *names,
                           const duckdb_type *named, int n_named) {
	duckdb_table_function f = duckdb_create_table_function();
	duckdb_table_function_set_name(f, name);
	for (int i = 0; i < n_positional + n_named; i++) {
		duckdb_logical_type t = duckdb_create_logical_type(i < n_positional ? positional[i] : named[i - n_positional]);
		if (i < n_positional) {
			duckdb_table_function_add_parameter(f, t);
		} else {
			duckdb_table_function_add_named_parameter(f, names[i - n_positional], t);
		}
		duckdb_destroy_logical_type(&t);
	}
	duckdb_table_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_table_function_set_bind(f, bind);
	duckdb_table_function_set_init(f, query_init_fn);
	duckdb_table_function_set_function(f, query_fn);
	duckdb_state rc = duckdb_register_table_function(con, f);
	duckdb_destroy_table_function(&f);
	return rc == DuckDBSuccess ? 0 : -1;
}

int mdb_register_keyframe_words(duckdb_connection con, mdb_state *st) {
	/* the lists are ANY: integer lists of every type bind (list_values reads them) */
	static const duckdb_type lists[] = {DUCKDB_TYPE_ANY, DUCKDB_TYPE_ANY, DUCKDB_TYPE_ANY, DUCKDB_TYPE_ANY};
	static const char *const names[] = {"extend_left", "extend_right"};
	static const duckdb_type margins[] = {DUCKDB_TYPE_BIGINT, DUCKDB_TYPE_BIGINT};
	return register_search(con, st, "keyframe_search_words", query_bind_fn, lists, 4, names, margins, 2);
}

int mdb_register_keyframe_search(duckdb_connection con, mdb_state *st) {
	static const duckdb_type cls[] = {DUCKDB_TYPE_VARCHAR};
	static const char *const names[] = {"model", "extend"};
	static const duckdb_type options[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_BOOLEAN};
	return register_search(con, st, "keyframe_search", class_bind_fn, cls, 1, names, options, 2);
}
