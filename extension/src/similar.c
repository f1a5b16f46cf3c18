/* similar_to(motion, first_frame, last_frame, k): query by example, the stretches of every motion most
 * like frames first_frame .. last_frame of a motion (1-based inclusive at 30 Hz; NULL: its first or
 * last frame), k of them, as LIST(STRUCT(rank, motion_id, start_frame, end_frame, cost)), ranked by
 * cost, none overlapping another or the query: what the Python UDF (mocapdb.storage.retrieval.
 * search_archive) returns, bit for bit (similar_plan.c, similar_rank.c say why).
 *
 * The motion is an id (any integer type) or a name (text; all digits: an id), the argument declared
 * ANY so that no cast turns '86_09' into 8609 or 3.7 into 4. The query stretch and an archive sample
 * (every step-th frame, step = frames // 16384) come from `features` (similar_read.c), the archive's
 * words from the keyframe index's `full` runs, a batch of motions (≤ 10⁶ frames) at a time, as the
 * Python side reads them: memory follows the batch (similar_search.c). An archive too large to rank
 * whole within the cell budget is preselected with keyframes taken from the query (similar_plan.c),
 * each batch within its share. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"
#include "functions.h"
#include "similar_read.h"
#include "similar_search.h"

DUCKDB_EXTENSION_EXTERN

/* the motion argument of a row: an id (*id, 1; MDB_SIM_BEYOND for an integer beyond int64), a
 * name (*name, 2), NULL (0), another type (-1) */
static int motion_arg(duckdb_vector v, duckdb_type type, idx_t row, int64_t *id, char **name) {
	if (!duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), row)) {
		return 0;
	}
	void *d = duckdb_vector_get_data(v);
	switch (type) {
	case DUCKDB_TYPE_TINYINT: *id = ((int8_t *)d)[row]; return 1;
	case DUCKDB_TYPE_SMALLINT: *id = ((int16_t *)d)[row]; return 1;
	case DUCKDB_TYPE_INTEGER: *id = ((int32_t *)d)[row]; return 1;
	case DUCKDB_TYPE_BIGINT: *id = ((int64_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UTINYINT: *id = ((uint8_t *)d)[row]; return 1;
	case DUCKDB_TYPE_USMALLINT: *id = ((uint16_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UINTEGER: *id = ((uint32_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UBIGINT: {
		uint64_t x = ((uint64_t *)d)[row];
		*id = x > INT64_MAX ? MDB_SIM_BEYOND : (int64_t)x;
		return 1;
	}
	case DUCKDB_TYPE_HUGEINT: {
		duckdb_hugeint x = ((duckdb_hugeint *)d)[row];
		if (x.upper == 0 && x.lower <= INT64_MAX) {
			*id = (int64_t)x.lower;
		} else if (x.upper == -1 && x.lower > INT64_MAX) {
			*id = (int64_t)x.lower; /* a negative int64 */
		} else {
			*id = MDB_SIM_BEYOND;
		}
		return 1;
	}
	case DUCKDB_TYPE_UHUGEINT: {
		duckdb_uhugeint x = ((duckdb_uhugeint *)d)[row];
		*id = (x.upper == 0 && x.lower <= INT64_MAX) ? (int64_t)x.lower : MDB_SIM_BEYOND;
		return 1;
	}
	case DUCKDB_TYPE_VARCHAR: *name = mdb_string_at(v, row); return *name ? 2 : -2;
	default: return -1;
	}
}

/* ---------------------------------------------------------------------------------------------
 * the SQL function */

static const char *type_name(duckdb_type t) {
	switch (t) {
	case DUCKDB_TYPE_BOOLEAN: return "BOOLEAN";
	case DUCKDB_TYPE_FLOAT: return "FLOAT";
	case DUCKDB_TYPE_DOUBLE: return "DOUBLE";
	case DUCKDB_TYPE_DECIMAL: return "DECIMAL";
	case DUCKDB_TYPE_DATE: return "DATE";
	case DUCKDB_TYPE_TIMESTAMP: return "TIMESTAMP";
	case DUCKDB_TYPE_BLOB: return "BLOB";
	case DUCKDB_TYPE_LIST: return "a LIST";
	case DUCKDB_TYPE_STRUCT: return "a STRUCT";
	default: return "another type";
	}
}

static int write_hits(duckdb_vector output, const mdb_sim_hits *h, idx_t row, size_t *total) {
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	duckdb_vector child = duckdb_list_vector_get_child(output);
	if (duckdb_list_vector_reserve(output, *total + h->n) == DuckDBError) {
		return -1;
	}
	int32_t *rank = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 0));
	int32_t *motion = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 1));
	int32_t *start = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 2));
	int32_t *end = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 3));
	double *cost = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 4));
	for (size_t i = 0; i < h->n; i++) {
		size_t o = *total + i;
		rank[o] = (int32_t)(i + 1);
		motion[o] = (int32_t)h->at[i].doc;
		start[o] = (int32_t)(h->at[i].start + 1);
		end[o] = (int32_t)(h->at[i].end + 1);
		cost[o] = h->at[i].cost;
	}
	entries[row].offset = *total;
	entries[row].length = h->n;
	*total += h->n;
	duckdb_list_vector_set_size(output, *total);
	return 0;
}

/* one row: its arguments checked, the query stretch read, the archive searched */
static int similar_row(mdb_state *st, duckdb_data_chunk input, idx_t row, mdb_sim_hits *hits, mdb_error *err) {
	duckdb_vector v_motion = duckdb_data_chunk_get_vector(input, 0);
	duckdb_vector v_first = duckdb_data_chunk_get_vector(input, 1), v_last = duckdb_data_chunk_get_vector(input, 2);
	duckdb_vector v_k = duckdb_data_chunk_get_vector(input, 3);
	duckdb_logical_type lt = duckdb_vector_get_column_type(v_motion);
	duckdb_type type = duckdb_get_type_id(lt);
	duckdb_destroy_logical_type(&lt);
	int k_valid = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_k), row);
	int32_t k = k_valid ? ((int32_t *)duckdb_vector_get_data(v_k))[row] : 0;
	if (!k_valid || k < 1) {
		if (k_valid) {
			snprintf(err->text, sizeof err->text, MDB_SIM_WHAT ": k must be a positive integer, got %d", k);
		} else {
			snprintf(err->text, sizeof err->text, MDB_SIM_WHAT ": k must be a positive integer, got NULL");
		}
		return -1;
	}
	int64_t id = -1;
	char *name = NULL;
	int kind = motion_arg(v_motion, type, row, &id, &name);
	if (kind == 0) {
		snprintf(err->text, sizeof err->text,
		         MDB_SIM_WHAT ": no motion with id NULL (see: SELECT motion_id, name FROM motions)");
		return -1;
	}
	if (kind == -2) {
		return mdb_sim_oom(err);
	}
	if (kind == -1) {
		snprintf(err->text, sizeof err->text,
		         MDB_SIM_WHAT ": motion must be a motion id (an integer) or a name, got %s (cast it to one)", type_name(type));
		return -1;
	}
	if (kind == 2) {
		int rc = mdb_sim_resolve_name(st, name, &id, err);
		free(name);
		if (rc) {
			return -1;
		}
	}
	int has_first = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_first), row);
	int has_last = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_last), row);
	int32_t first_frame = has_first ? ((int32_t *)duckdb_vector_get_data(v_first))[row] : 0;
	int32_t last_frame = has_last ? ((int32_t *)duckdb_vector_get_data(v_last))[row] : 0;
	int64_t first, last;
	mdb_sim_words w = {0};
	int rc = mdb_sim_query_stretch(st, id, has_first, first_frame, has_last, last_frame, &first, &last, &w, err);
	if (rc == 0) {
		hits->n = 0;
		rc = mdb_sim_search_archive(st, id, first, w.w + first, (size_t)(last - first + 1), k, hits, err);
	}
	free(w.w);
	return rc;
}

static void similar_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	mdb_error err = {{0}};
	mdb_sim_hits hits = {0};
	size_t total = 0;
	int failed = mdb_check_live(st, &err);
	for (idx_t row = 0; row < n; row++) {
		entries[row].offset = 0;
		entries[row].length = 0;
	}
	for (idx_t row = 0; row < n && !failed; row++) {
		failed = similar_row(st, input, row, &hits, &err);
		if (!failed && write_hits(output, &hits, row, &total)) {
			failed = mdb_sim_oom(&err);
		}
	}
	mdb_sim_hits_free(&hits);
	if (failed) {
		duckdb_scalar_function_set_error(info, err.text);
	}
}

static duckdb_logical_type result_type(void) {
	const char *names[] = {"rank", "motion_id", "start_frame", "end_frame", "cost"};
	duckdb_type ids[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER,
	                     DUCKDB_TYPE_DOUBLE};
	return mdb_struct_list_type(names, ids, 5);
}

int mdb_register_similar(duckdb_connection con, mdb_state *st) {
	duckdb_scalar_function f = duckdb_create_scalar_function();
	duckdb_scalar_function_set_name(f, "similar_to");
	duckdb_logical_type any = duckdb_create_logical_type(DUCKDB_TYPE_ANY);
	duckdb_logical_type i32 = duckdb_create_logical_type(DUCKDB_TYPE_INTEGER);
	duckdb_logical_type list = result_type();
	duckdb_scalar_function_add_parameter(f, any);
	for (int i = 0; i < 3; i++) {
		duckdb_scalar_function_add_parameter(f, i32);
	}
	duckdb_scalar_function_set_return_type(f, list);
	/* NULLs come in: a NULL range is the whole motion, a NULL motion or k an error */
	duckdb_scalar_function_set_special_handling(f);
	/* it reads the database: never folded into a constant at planning */
	duckdb_scalar_function_set_volatile(f);
	duckdb_scalar_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_scalar_function_set_function(f, similar_fn);
	int rc = duckdb_register_scalar_function(con, f) == DuckDBError ? -1 : 0;
	duckdb_destroy_logical_type(&any);
	duckdb_destroy_logical_type(&i32);
	duckdb_destroy_logical_type(&list);
	duckdb_destroy_scalar_function(&f);
	return rc;
}
