/* mt_distance(motion, class [, model]): Δ of a class's template against a motion, one DOUBLE per
 * 30 Hz frame (+inf where no match can end), as the Python UDF returns it (bit for bit: distance.c).
 * A NULL or unknown motion gives NULL; a NULL or unknown class or model is an error naming it.
 * Each row reads its motion's words only (memory flat in archive size); the template of the
 * (model, class) of the previous row is kept for the next. */
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
	duckdb_string_t *x = duckdb_vector_get_data(v);
	uint32_t len = duckdb_string_t_length(x[row]);
	char *s = malloc((size_t)len + 1);
	if (s) {
		memcpy(s, duckdb_string_t_data(&x[row]), len);
		s[len] = 0;
	}
	return s;
}

static int same(const char *a, const char *b) {
	return a && b && strcmp(a, b) == 0;
}

static void mt_distance_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	int has_model = duckdb_data_chunk_get_column_count(input) > 2;
	duckdb_vector v_motion = duckdb_data_chunk_get_vector(input, 0), v_cls = duckdb_data_chunk_get_vector(input, 1);
	duckdb_vector v_model = has_model ? duckdb_data_chunk_get_vector(input, 2) : NULL;
	int64_t *motion = duckdb_vector_get_data(v_motion);
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	duckdb_vector child = duckdb_list_vector_get_child(output);
	duckdb_vector_ensure_validity_writable(output);
	uint64_t *out_valid = duckdb_vector_get_validity(output);
	mdb_template t = {0};
	char *t_model = NULL, *t_cls = NULL, *model = NULL, *cls = NULL;
	mdb_error err = {{0}};
	idx_t total = 0;
	int failed = 0;
	for (idx_t row = 0; row < n && !failed; row++) {
		free(model);
		free(cls);
		model = has_model ? text_of(v_model, row) : strdup("default");
		cls = text_of(v_cls, row);
		if (has_model && !model) {
			snprintf(err.text, sizeof err.text, "mt_distance: model is NULL; give a model name (default: 'default')");
			failed = 1;
			break;
		}
		if (!model || (!cls && duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_cls), row))) {
			snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
			failed = 1;
			break;
		}
		if (!cls) {
			snprintf(err.text, sizeof err.text, "mt_distance: class is NULL; give one of model '%s''s classes",
			         model);
			failed = 1;
			break;
		}
		if (!duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_motion), row) || motion[row] < INT32_MIN ||
		    motion[row] > INT32_MAX) {
			duckdb_validity_set_row_invalid(out_valid, row); /* no such motion: NULL */
			entries[row].offset = total;
			entries[row].length = 0;
			continue;
		}
		if (!same(model, t_model) || !same(cls, t_cls)) {
			mdb_template_free(&t);
			free(t_model);
			free(t_cls);
			t_model = t_cls = NULL;
			if (mdb_read_template(st, model, cls, &t, &err)) {
				failed = 1;
				break;
			}
			t_model = strdup(model);
			t_cls = strdup(cls);
		}
		uint64_t *words = NULL;
		size_t n_frames = 0;
		int known = 0;
		if (mdb_read_words(st, (int32_t)motion[row], &words, &n_frames, &known, &err)) {
			failed = 1;
			break;
		}
		entries[row].offset = total;
		entries[row].length = n_frames;
		if (!known) {
			duckdb_validity_set_row_invalid(out_valid, row);
			continue;
		}
		if (duckdb_list_vector_reserve(output, total + n_frames) == DuckDBError) {
			free(words);
			snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
			failed = 1;
			break;
		}
		double *delta = (double *)duckdb_vector_get_data(child) + total;
		if (n_frames && mdb_mt_distance(&t, words, n_frames, delta)) {
			free(words);
			snprintf(err.text, sizeof err.text, "mt_distance: out of memory");
			failed = 1;
			break;
		}
		free(words);
		total += n_frames;
		duckdb_list_vector_set_size(output, total);
	}
	free(model);
	free(cls);
	free(t_model);
	free(t_cls);
	mdb_template_free(&t);
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
	duckdb_scalar_function_set_extra_info(f, st, NULL);
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
