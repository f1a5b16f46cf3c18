/* The archive's tables as the native functions read them. Every read is one query
 * on the extension's connection under its lock, reading committed data only (as
 * the Python UDFs' cursors do). A table that is missing is an error naming it and
 * the command that creates it. */
#include "archive.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

DUCKDB_EXTENSION_EXTERN

#define MOTIONS_SQL "SELECT motion_id, n_frames FROM motions ORDER BY motion_id"
#define RUNS_SQL                                                                                                       \
	"SELECT motion_id, word, start_frame - 1, n_frames FROM mocap_index.postings "                                     \
	"WHERE feature_set = 'full' AND motion_id BETWEEN $1 AND $2 ORDER BY motion_id, seg"

/* The error of a failed query, with the table it needed named when it is missing. */
static void query_error(const char *what, const char *table, const char *detail, mdb_error *err) {
	if (detail && strstr(detail, "does not exist")) {
		snprintf(err->text, sizeof err->text,
		         "%s: table %s does not exist in this database: `mocapdb ingest` creates it (an archive whose "
		         "keyframe index was dropped gets it back with `mocapdb create-index`)",
		         what, table);
	} else {
		snprintf(err->text, sizeof err->text, "%s: reading %s failed: %s", what, table, detail ? detail : "?");
	}
}

static int column_types_ok(duckdb_result *res, const duckdb_type *want, idx_t n) {
	if (duckdb_column_count(res) != n) {
		return 0;
	}
	for (idx_t i = 0; i < n; i++) {
		if (duckdb_column_type(res, i) != want[i]) {
			return 0;
		}
	}
	return 1;
}

void mdb_motions_free(mdb_motions *m) {
	free(m->id);
	free(m->n_frames);
	memset(m, 0, sizeof *m);
}

int mdb_read_motions(mdb_state *st, mdb_motions *out, mdb_error *err) {
	memset(out, 0, sizeof *out);
	duckdb_result res;
	int rc = -1;
	size_t cap = 0;
	pthread_mutex_lock(&st->lock);
	if (duckdb_query(st->con, MOTIONS_SQL, &res) == DuckDBError) {
		query_error("mocapdb", "motions", duckdb_result_error(&res), err);
		goto done;
	}
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER};
	if (!column_types_ok(&res, want, 2)) {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table motions has unexpected column types; was it written by `mocapdb ingest`?");
		goto done;
	}
	for (;;) {
		duckdb_data_chunk chunk = duckdb_fetch_chunk(res);
		if (!chunk) {
			break;
		}
		idx_t n = duckdb_data_chunk_get_size(chunk);
		duckdb_vector v_id = duckdb_data_chunk_get_vector(chunk, 0);
		duckdb_vector v_len = duckdb_data_chunk_get_vector(chunk, 1);
		int32_t *ids = duckdb_vector_get_data(v_id);
		int32_t *lens = duckdb_vector_get_data(v_len);
		uint64_t *ok_id = duckdb_vector_get_validity(v_id), *ok_len = duckdb_vector_get_validity(v_len);
		if (out->n + n > cap) {
			cap = 2 * (out->n + n);
			int32_t *a = realloc(out->id, cap * sizeof *a);
			if (a) {
				out->id = a;
			}
			int64_t *b = realloc(out->n_frames, cap * sizeof *b);
			if (b) {
				out->n_frames = b;
			}
			if (!a || !b) {
				duckdb_destroy_data_chunk(&chunk);
				snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading motions");
				goto done;
			}
		}
		for (idx_t i = 0; i < n; i++) {
			if (!duckdb_validity_row_is_valid(ok_id, i)) {
				continue; /* NOT NULL in the schema; a foreign table may differ: skip */
			}
			out->id[out->n] = ids[i];
			out->n_frames[out->n] = duckdb_validity_row_is_valid(ok_len, i) && lens[i] > 0 ? lens[i] : 0;
			out->n++;
		}
		duckdb_destroy_data_chunk(&chunk);
	}
	rc = 0;
done:
	duckdb_destroy_result(&res);
	pthread_mutex_unlock(&st->lock);
	if (rc) {
		mdb_motions_free(out);
	}
	return rc;
}

void mdb_runs_free(mdb_runs *r) {
	free(r->motion);
	free(r->word);
	free(r->start);
	free(r->len);
	memset(r, 0, sizeof *r);
}

static int runs_reserve(mdb_runs *r, size_t need) {
	if (need <= r->cap) {
		return 0;
	}
	size_t cap = need > 2 * r->cap ? need : 2 * r->cap;
	int32_t *m = realloc(r->motion, cap * sizeof *m);
	if (m) {
		r->motion = m;
	}
	uint64_t *w = realloc(r->word, cap * sizeof *w);
	if (w) {
		r->word = w;
	}
	int64_t *s = realloc(r->start, cap * sizeof *s);
	if (s) {
		r->start = s;
	}
	int64_t *l = realloc(r->len, cap * sizeof *l);
	if (l) {
		r->len = l;
	}
	if (!m || !w || !s || !l) {
		return -1;
	}
	r->cap = cap;
	return 0;
}

int mdb_read_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_runs *out, mdb_error *err) {
	out->n = 0;
	duckdb_prepared_statement stmt = NULL;
	duckdb_result res;
	int have_result = 0, rc = -1;
	pthread_mutex_lock(&st->lock);
	if (duckdb_prepare(st->con, RUNS_SQL, &stmt) == DuckDBError) {
		query_error("mocapdb", "mocap_index.postings", duckdb_prepare_error(stmt), err);
		goto done;
	}
	duckdb_bind_int32(stmt, 1, lo);
	duckdb_bind_int32(stmt, 2, hi);
	have_result = 1;
	if (duckdb_execute_prepared(stmt, &res) == DuckDBError) {
		query_error("mocapdb", "mocap_index.postings", duckdb_result_error(&res), err);
		goto done;
	}
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER};
	if (!column_types_ok(&res, want, 4)) {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table mocap_index.postings has unexpected column types; rebuild it with "
		         "`mocapdb create-index`");
		goto done;
	}
	for (;;) {
		duckdb_data_chunk chunk = duckdb_fetch_chunk(res);
		if (!chunk) {
			break;
		}
		idx_t n = duckdb_data_chunk_get_size(chunk);
		if (runs_reserve(out, out->n + n)) {
			duckdb_destroy_data_chunk(&chunk);
			snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading the keyframe index");
			goto done;
		}
		duckdb_vector v[4];
		uint64_t *valid[4];
		for (idx_t c = 0; c < 4; c++) {
			v[c] = duckdb_data_chunk_get_vector(chunk, c);
			valid[c] = duckdb_vector_get_validity(v[c]);
		}
		int32_t *mid = duckdb_vector_get_data(v[0]);
		uint64_t *word = duckdb_vector_get_data(v[1]);
		int32_t *start = duckdb_vector_get_data(v[2]);
		int32_t *len = duckdb_vector_get_data(v[3]);
		for (idx_t i = 0; i < n; i++) {
			int ok = 1;
			for (idx_t c = 0; c < 4; c++) {
				ok &= duckdb_validity_row_is_valid(valid[c], i);
			}
			if (!ok || len[i] <= 0 || start[i] < 0) {
				continue; /* NOT NULL and positive in the schema; never trusted */
			}
			out->motion[out->n] = mid[i];
			out->word[out->n] = word[i];
			out->start[out->n] = start[i];
			out->len[out->n] = len[i];
			out->n++;
		}
		duckdb_destroy_data_chunk(&chunk);
	}
	rc = 0;
done:
	if (have_result) {
		duckdb_destroy_result(&res);
	}
	duckdb_destroy_prepare(&stmt);
	pthread_mutex_unlock(&st->lock);
	return rc;
}
