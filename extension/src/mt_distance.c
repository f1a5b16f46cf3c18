/* mt_distance(motion, class [, model]): Δ of a class's template against a motion, one DOUBLE per
 * 30 Hz frame (+inf where no match can end), as the Python UDF returns it (bit for bit: distance.c).
 * A NULL or unknown motion gives NULL; a NULL or unknown class or model is an error naming it.
 * The rows' motions are read a batch at a time (memory flat in archive size); each (model, class)
 * template once per call. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"
#include "distance.h"
#include "functions.h"

DUCKDB_EXTENSION_EXTERN

/* a VARCHAR of a flat vector as a NUL-terminated copy (NULL when the row is NULL) */
static char *text_of(duckdb_vector v, idx_t row) {
	if (!duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), row)) {
		return NULL;
	}
	return mdb_string_at(v, row);
}

static int same(const char *a, const char *b) {
	return a && b && strcmp(a, b) == 0;
}

/* The templates of the (model, class) pairs of one call, read once each. */
typedef struct {
	char *model, *cls;
	mdb_template t;
} named_template;

typedef struct {
	named_template *at;
	size_t n;
} templates;

static void templates_free(templates *ts) {
	for (size_t i = 0; i < ts->n; i++) {
		free(ts->at[i].model);
		free(ts->at[i].cls);
		mdb_template_free(&ts->at[i].t);
	}
	free(ts->at);
}

/* The index of (model, cls) in ts, read on first use; -1 after an error. */
static long template_of(mdb_state *st, templates *ts, const char *model, const char *cls, mdb_error *err) {
	for (size_t i = 0; i < ts->n; i++) {
		if (same(ts->at[i].model, model) && same(ts->at[i].cls, cls)) {
			return (long)i;
		}
	}
	named_template *grown = realloc(ts->at, (ts->n + 1) * sizeof *grown);
	if (!grown) {
		snprintf(err->text, sizeof err->text, "mt_distance: out of memory");
		return -1;
	}
	ts->at = grown;
	named_template *x = &ts->at[ts->n];
	memset(x, 0, sizeof *x);
	if (mdb_read_template(st, model, cls, &x->t, err)) {
		return -1;
	}
	x->model = strdup(model);
	x->cls = strdup(cls);
	ts->n++;
	if (!x->model || !x->cls) {
		snprintf(err->text, sizeof err->text, "mt_distance: out of memory");
		return -1;
	}
	return (long)ts->n - 1;
}

/* A row with a motion to answer: its motion and template. */
typedef struct {
	int32_t motion;
	idx_t row;
	long tpl;
} item;

static int by_motion(const void *a, const void *b) {
	const item *x = a, *y = b;
	return (x->motion > y->motion) - (x->motion < y->motion);
}

/* Check the rows' arguments and read their templates; the rows with a motion into items. */
static int collect(mdb_state *st, duckdb_data_chunk input, idx_t n, templates *ts, item *items, size_t *n_items,
                   uint64_t *out_valid, mdb_error *err) {
	int has_model = duckdb_data_chunk_get_column_count(input) > 2;
	duckdb_vector v_motion = duckdb_data_chunk_get_vector(input, 0), v_cls = duckdb_data_chunk_get_vector(input, 1);
	duckdb_vector v_model = has_model ? duckdb_data_chunk_get_vector(input, 2) : NULL;
	int64_t *motion = duckdb_vector_get_data(v_motion);
	*n_items = 0;
	for (idx_t row = 0; row < n; row++) {
		int cls_null = !duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_cls), row);
		int model_null = has_model && !duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_model), row);
		char *model = model_null ? NULL : has_model ? text_of(v_model, row) : strdup("default");
		char *cls = cls_null ? NULL : text_of(v_cls, row);
		long tpl = -1;
		if (model_null) {
			snprintf(err->text, sizeof err->text, "mt_distance: model is NULL; give a model name (default: 'default')");
		} else if (!model || (!cls && !cls_null)) {
			snprintf(err->text, sizeof err->text, "mt_distance: out of memory");
		} else if (cls_null) {
			snprintf(err->text, sizeof err->text, "mt_distance: class is NULL; give one of model '%s''s classes",
			         model);
		} else {
			tpl = template_of(st, ts, model, cls, err);
		}
		free(model);
		free(cls);
		if (tpl < 0) {
			return -1;
		}
		if (!duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_motion), row) || motion[row] < INT32_MIN ||
		    motion[row] > INT32_MAX) {
			duckdb_validity_set_row_invalid(out_valid, row); /* no such motion: NULL */
			continue;
		}
		items[(*n_items)++] = (item){(int32_t)motion[row], row, tpl};
	}
	return 0;
}

/* Rows' motions a batch at a time (mdb_read_batch: one query per batch of motions), then Δ of
 * every row of it into the list vector. */
static void mt_distance_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	duckdb_vector child = duckdb_list_vector_get_child(output);
	duckdb_vector_ensure_validity_writable(output);
	uint64_t *out_valid = duckdb_vector_get_validity(output);
	templates ts = {0};
	mdb_motions range = {0};
	mdb_error err = {{0}};
	item *items = malloc((n ? n : 1) * sizeof *items);
	int32_t *ids = malloc((n ? n : 1) * sizeof *ids);
	mdb_words_batch b = {0};
	size_t n_items = 0, total = 0;
	int failed = 1;
	for (idx_t row = 0; row < n; row++) {
		entries[row].offset = 0;
		entries[row].length = 0;
	}
	if (!items || !ids) {
		snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
		goto done;
	}
	if (mdb_check_live(st, &err) || collect(st, input, n, &ts, items, &n_items, out_valid, &err)) {
		goto done;
	}
	qsort(items, n_items, sizeof *items, by_motion);
	if (n_items && mdb_read_motion_range(st, items[0].motion, items[n_items - 1].motion, &range, &err)) {
		goto done;
	}
	for (size_t k = 0; k < n_items; k++) {
		ids[k] = items[k].motion;
	}
	size_t i = 0, m = 0; /* next item; next stored motion of the range */
	while (i < n_items) {
		size_t first = i, k = 0;
		if (mdb_read_batch(st, &range, &m, ids, n_items, &i, MDB_BATCH_FRAMES, &b, &err)) {
			goto done;
		}
		for (size_t q = first; q < i; q++) {
			while (k < b.n && b.id[k] < items[q].motion) {
				k++;
			}
			idx_t row = items[q].row;
			if (k == b.n || b.id[k] != items[q].motion) {
				duckdb_validity_set_row_invalid(out_valid, row); /* not stored: NULL */
				continue;
			}
			size_t len = (size_t)b.n_frames[k];
			if (duckdb_list_vector_reserve(output, total + len) == DuckDBError) {
				snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
				goto done;
			}
			double *delta = (double *)duckdb_vector_get_data(child) + total;
			if (len && mdb_mt_distance(&ts.at[items[q].tpl].t, b.words + b.off[k], len, delta, NULL)) {
				snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
				goto done;
			}
			entries[row].offset = total;
			entries[row].length = len;
			total += len;
			duckdb_list_vector_set_size(output, total);
		}
	}
	failed = 0;
done:
	templates_free(&ts);
	mdb_motions_free(&range);
	free(items);
	free(ids);
	mdb_words_batch_free(&b);
	if (failed) {
		duckdb_scalar_function_set_error(info, err.text);
	}
}

static duckdb_scalar_function mt_distance_function(mdb_state *st, int with_model) {
	duckdb_scalar_function f = duckdb_create_scalar_function();
	duckdb_scalar_function_set_name(f, "mt_distance");
	duckdb_logical_type i64 = duckdb_create_logical_type(DUCKDB_TYPE_BIGINT);
	duckdb_logical_type text = duckdb_create_logical_type(DUCKDB_TYPE_VARCHAR);
	duckdb_logical_type dbl = duckdb_create_logical_type(DUCKDB_TYPE_DOUBLE);
	duckdb_logical_type list = duckdb_create_list_type(dbl);
	duckdb_scalar_function_add_parameter(f, i64);
	duckdb_scalar_function_add_parameter(f, text);
	if (with_model) {
		duckdb_scalar_function_add_parameter(f, text);
	}
	duckdb_scalar_function_set_return_type(f, list);
	/* NULLs come in: a NULL motion is a NULL answer, a NULL class or model an error */
	duckdb_scalar_function_set_special_handling(f);
	/* it reads the database: never folded into a constant at planning */
	duckdb_scalar_function_set_volatile(f);
	duckdb_scalar_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_scalar_function_set_function(f, mt_distance_fn);
	duckdb_destroy_logical_type(&i64);
	duckdb_destroy_logical_type(&text);
	duckdb_destroy_logical_type(&dbl);
	duckdb_destroy_logical_type(&list);
	return f;
}

int mdb_register_mt_distance(duckdb_connection con, mdb_state *st) {
	duckdb_scalar_function_set set = duckdb_create_scalar_function_set("mt_distance");
	int rc = 0;
	for (int with_model = 0; with_model < 2; with_model++) {
		duckdb_scalar_function f = mt_distance_function(st, with_model);
		rc |= duckdb_add_scalar_function_to_set(set, f) == DuckDBError;
		duckdb_destroy_scalar_function(&f);
	}
	rc |= duckdb_register_scalar_function_set(con, set) == DuckDBError;
	duckdb_destroy_scalar_function_set(&set);
	return rc ? -1 : 0;
}
