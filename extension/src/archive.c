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
/* no ORDER BY: the rows come in insertion order, which is (motion, run) order unless the table was
 * rewritten; sorting here only when they do not costs less than DuckDB's sort every time */
#define RUNS_SQL                                                                                                       \
	"SELECT motion_id, word, start_frame - 1, n_frames, seg FROM mocap_index.postings "                                \
	"WHERE feature_set = 'full' AND motion_id BETWEEN $1 AND $2"
#define VERSION_SQL "SELECT version FROM mocap_index.state"
/* as mocapdb.storage.cache.INDEX_CACHE_BYTES: the index batches kept between queries */
#define CACHE_BYTES ((size_t)256 << 20)

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

/* (motion, run) order of row i and j of the runs read, for the rare table not in that order */
static const mdb_runs *sort_runs;
static const int32_t *sort_seg;

static int run_order(const void *a, const void *b) {
	size_t i = *(const size_t *)a, j = *(const size_t *)b;
	if (sort_runs->motion[i] != sort_runs->motion[j]) {
		return sort_runs->motion[i] < sort_runs->motion[j] ? -1 : 1;
	}
	return (sort_seg[i] > sort_seg[j]) - (sort_seg[i] < sort_seg[j]);
}

/* Put the runs into (motion, run) order (called under the state's lock: the comparison's
 * statics are shared). */
static int order_runs(mdb_runs *r, const int32_t *seg) {
	int sorted = 1;
	for (size_t i = 1; i < r->n && sorted; i++) {
		sorted = r->motion[i - 1] < r->motion[i] || (r->motion[i - 1] == r->motion[i] && seg[i - 1] < seg[i]);
	}
	if (sorted) {
		return 0;
	}
	size_t *idx = malloc(r->n * sizeof *idx);
	mdb_runs out = {0};
	if (!idx || runs_reserve(&out, r->n)) {
		free(idx);
		mdb_runs_free(&out);
		return -1;
	}
	for (size_t i = 0; i < r->n; i++) {
		idx[i] = i;
	}
	sort_runs = r;
	sort_seg = seg;
	qsort(idx, r->n, sizeof *idx, run_order);
	for (size_t i = 0; i < r->n; i++) {
		out.motion[i] = r->motion[idx[i]];
		out.word[i] = r->word[idx[i]];
		out.start[i] = r->start[idx[i]];
		out.len[i] = r->len[idx[i]];
	}
	out.n = r->n;
	free(idx);
	mdb_runs_free(r);
	*r = out;
	return 0;
}

/* Read the runs of motions lo .. hi (the caller holds the lock). */
static int read_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_runs *out, mdb_error *err) {
	out->n = 0;
	duckdb_prepared_statement stmt = NULL;
	duckdb_result res;
	int have_result = 0, rc = -1;
	int32_t *seg = NULL;
	size_t seg_cap = 0;
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
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER,
	                      DUCKDB_TYPE_INTEGER};
	if (!column_types_ok(&res, want, 5)) {
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
		if (out->n + n > seg_cap) {
			seg_cap = 2 * (out->n + n);
			int32_t *grown = realloc(seg, seg_cap * sizeof *grown);
			if (grown) {
				seg = grown;
			}
		}
		if (runs_reserve(out, out->n + n) || out->n + n > seg_cap) {
			duckdb_destroy_data_chunk(&chunk);
			snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading the keyframe index");
			goto done;
		}
		duckdb_vector v[5];
		uint64_t *valid[5];
		for (idx_t c = 0; c < 5; c++) {
			v[c] = duckdb_data_chunk_get_vector(chunk, c);
			valid[c] = duckdb_vector_get_validity(v[c]);
		}
		int32_t *mid = duckdb_vector_get_data(v[0]);
		uint64_t *word = duckdb_vector_get_data(v[1]);
		int32_t *start = duckdb_vector_get_data(v[2]);
		int32_t *len = duckdb_vector_get_data(v[3]);
		int32_t *sg = duckdb_vector_get_data(v[4]);
		for (idx_t i = 0; i < n; i++) {
			int ok = 1;
			for (idx_t c = 0; c < 5; c++) {
				ok &= duckdb_validity_row_is_valid(valid[c], i);
			}
			if (!ok || len[i] <= 0 || start[i] < 0) {
				continue; /* NOT NULL and positive in the schema; never trusted */
			}
			out->motion[out->n] = mid[i];
			out->word[out->n] = word[i];
			out->start[out->n] = start[i];
			out->len[out->n] = len[i];
			seg[out->n] = sg[i];
			out->n++;
		}
		duckdb_destroy_data_chunk(&chunk);
	}
	if (order_runs(out, seg)) {
		snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading the keyframe index");
		goto done;
	}
	rc = 0;
done:
	free(seg);
	if (have_result) {
		duckdb_destroy_result(&res);
	}
	duckdb_destroy_prepare(&stmt);
	return rc;
}

/* The index version (NULL: -1; no index built), the caller holding the lock. */
static int index_version(mdb_state *st, int64_t *version, mdb_error *err) {
	duckdb_result res;
	int rc = -1;
	if (duckdb_query(st->con, VERSION_SQL, &res) == DuckDBError) {
		query_error("mocapdb", "mocap_index.state", duckdb_result_error(&res), err);
		duckdb_destroy_result(&res);
		return -1;
	}
	duckdb_type want[] = {DUCKDB_TYPE_BIGINT};
	duckdb_data_chunk chunk = column_types_ok(&res, want, 1) ? duckdb_fetch_chunk(res) : NULL;
	if (chunk && duckdb_data_chunk_get_size(chunk) == 1) {
		duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
		int64_t *x = duckdb_vector_get_data(v);
		*version = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), 0) ? x[0] : -1;
		rc = 0;
	} else {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table mocap_index.state must have one BIGINT row; `mocapdb ingest` writes it");
	}
	if (chunk) {
		duckdb_destroy_data_chunk(&chunk);
	}
	duckdb_destroy_result(&res);
	return rc;
}

static void batch_free(mdb_batch *b) {
	mdb_runs_free(&b->runs);
	free(b);
}

static size_t batch_bytes(const mdb_batch *b) {
	return sizeof *b + b->runs.cap * (sizeof(int32_t) + sizeof(uint64_t) + 2 * sizeof(int64_t));
}

/* Drop the cached batches of other versions (those in use go when released). */
static void drop_stale(mdb_state *st, int64_t version) {
	mdb_batch **p = &st->cache;
	while (*p) {
		mdb_batch *b = *p;
		if (b->version == version) {
			p = &b->next;
			continue;
		}
		*p = b->next;
		st->cache_bytes -= batch_bytes(b);
		b->detached = 1;
		if (b->refs == 0) {
			batch_free(b);
		}
	}
}

mdb_batch *mdb_acquire_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_error *err) {
	int64_t version;
	mdb_batch *b = NULL;
	pthread_mutex_lock(&st->lock);
	if (index_version(st, &version, err)) {
		goto done;
	}
	drop_stale(st, version);
	for (b = st->cache; b; b = b->next) {
		if (b->lo == lo && b->hi == hi) {
			b->refs++;
			goto done;
		}
	}
	b = calloc(1, sizeof *b);
	if (!b) {
		snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading the keyframe index");
		goto done;
	}
	if (read_runs(st, lo, hi, &b->runs, err)) {
		batch_free(b);
		b = NULL;
		goto done;
	}
	b->version = version;
	b->lo = lo;
	b->hi = hi;
	b->refs = 1;
	/* Archive-wide passes read the batches in the same order every time: keeping the first
	 * ones that fit (never evicting for the one read last) lets the next pass reuse them, as
	 * mocapdb.storage.cache does. No index built (version NULL): nothing is kept. */
	if (version >= 0 && st->cache_bytes + batch_bytes(b) <= CACHE_BYTES) {
		b->next = st->cache;
		st->cache = b;
		st->cache_bytes += batch_bytes(b);
	} else {
		b->detached = 1;
	}
done:
	pthread_mutex_unlock(&st->lock);
	return b;
}

void mdb_release_runs(mdb_state *st, mdb_batch *b) {
	if (!b) {
		return;
	}
	pthread_mutex_lock(&st->lock);
	if (--b->refs == 0 && b->detached) {
		batch_free(b);
	}
	pthread_mutex_unlock(&st->lock);
}

/* ---------------------------------------------------------------------------------------------
 * models and motions */

#define TEMPLATE_SQL "SELECT mask, value, weight FROM templates WHERE model = $1 AND class = $2 ORDER BY col"
#define CLASSES_SQL "SELECT string_agg(class, ', ' ORDER BY class_id) FROM classes WHERE model = $1"
#define MODELS_SQL "SELECT string_agg(model, ', ' ORDER BY model) FROM models"
#define LENGTH_SQL "SELECT n_frames, name FROM motions WHERE motion_id = $1"
#define WORDS_SQL "SELECT frame, bits FROM features WHERE motion_id = $1 ORDER BY frame"
/* 41 feature bits (40 + the heading feature): a template column may fix no other */
#define FEATURE_BITS ((((uint64_t)1) << (MDB_N_COST - 1)) - 1)
/* more expanded columns than any template has (the longest are a few hundred) */
#define MAX_COLUMNS ((size_t)1 << 16)

/* A prepared statement with up to two text parameters or one integer, executed; 0 or -1
 * (err names the table). */
static int run_prepared(mdb_state *st, const char *sql, const char *table, const char *p1, const char *p2,
                        const int32_t *i1, duckdb_result *res, mdb_error *err) {
	duckdb_prepared_statement stmt = NULL;
	int rc = -1;
	if (duckdb_prepare(st->con, sql, &stmt) == DuckDBError) {
		query_error("mocapdb", table, duckdb_prepare_error(stmt), err);
		duckdb_destroy_prepare(&stmt);
		return -1;
	}
	if (p1) {
		duckdb_bind_varchar(stmt, 1, p1);
	}
	if (p2) {
		duckdb_bind_varchar(stmt, 2, p2);
	}
	if (i1) {
		duckdb_bind_int32(stmt, 1, *i1);
	}
	if (duckdb_execute_prepared(stmt, res) == DuckDBError) {
		query_error("mocapdb", table, duckdb_result_error(res), err);
		duckdb_destroy_result(res);
	} else {
		rc = 0;
	}
	duckdb_destroy_prepare(&stmt);
	return rc;
}

/* The first row's VARCHAR of a one-column result into buf ("" when NULL or none). */
static void first_text(duckdb_result *res, char *buf, size_t size) {
	buf[0] = 0;
	duckdb_data_chunk chunk = duckdb_column_type(res, 0) == DUCKDB_TYPE_VARCHAR ? duckdb_fetch_chunk(*res) : NULL;
	if (!chunk) {
		return;
	}
	duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
	if (duckdb_data_chunk_get_size(chunk) > 0 && duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), 0)) {
		duckdb_string_t *x = duckdb_vector_get_data(v);
		uint32_t len = duckdb_string_t_length(x[0]);
		if (len >= size) {
			len = (uint32_t)size - 1;
		}
		memcpy(buf, duckdb_string_t_data(&x[0]), len);
		buf[len] = 0;
	}
	duckdb_destroy_data_chunk(&chunk);
}

/* Why a model has no template for a class: the model or the class is unknown. */
static void unknown_class(mdb_state *st, const char *model, const char *cls, mdb_error *err) {
	duckdb_result res;
	char known[300];
	if (run_prepared(st, CLASSES_SQL, "classes", model, NULL, NULL, &res, err)) {
		return;
	}
	first_text(&res, known, sizeof known);
	duckdb_destroy_result(&res);
	if (known[0]) {
		snprintf(err->text, sizeof err->text, "model '%s' has no class '%s'; its classes: %s", model, cls, known);
		return;
	}
	if (run_prepared(st, MODELS_SQL, "models", NULL, NULL, NULL, &res, err)) {
		return;
	}
	first_text(&res, known, sizeof known);
	duckdb_destroy_result(&res);
	snprintf(err->text, sizeof err->text,
	         "no model '%s' in the database (stored models: %s); a database that mocapdb opened read-write once "
	         "has the shipped ones",
	         model, known[0] ? known : "none");
}

int mdb_read_template(mdb_state *st, const char *model, const char *cls, mdb_template *out, mdb_error *err) {
	duckdb_result res;
	uint64_t *mask = NULL, *value = NULL;
	double *weight = NULL;
	size_t n = 0, cap = 0;
	int rc = -1, bad = 0;
	memset(out, 0, sizeof *out);
	pthread_mutex_lock(&st->lock);
	if (run_prepared(st, TEMPLATE_SQL, "templates", model, cls, NULL, &res, err)) {
		goto unlock;
	}
	duckdb_type want[] = {DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_DOUBLE};
	if (!column_types_ok(&res, want, 3)) {
		snprintf(err->text, sizeof err->text, "mocapdb: table templates has unexpected column types");
		goto done;
	}
	for (;;) {
		duckdb_data_chunk chunk = duckdb_fetch_chunk(res);
		if (!chunk) {
			break;
		}
		idx_t m = duckdb_data_chunk_get_size(chunk);
		if (n + m > cap) {
			cap = 2 * (n + m);
			uint64_t *a = realloc(mask, cap * sizeof *a);
			if (a) {
				mask = a;
			}
			uint64_t *b = realloc(value, cap * sizeof *b);
			if (b) {
				value = b;
			}
			double *c = realloc(weight, cap * sizeof *c);
			if (c) {
				weight = c;
			}
			if (!a || !b || !c) {
				duckdb_destroy_data_chunk(&chunk);
				snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading a template");
				goto done;
			}
		}
		duckdb_vector v[3];
		for (idx_t c = 0; c < 3; c++) {
			v[c] = duckdb_data_chunk_get_vector(chunk, c);
		}
		uint64_t *vm = duckdb_vector_get_data(v[0]), *vv = duckdb_vector_get_data(v[1]);
		double *vw = duckdb_vector_get_data(v[2]);
		for (idx_t i = 0; i < m; i++) {
			for (idx_t c = 0; c < 3; c++) {
				bad |= !duckdb_validity_row_is_valid(duckdb_vector_get_validity(v[c]), i);
			}
			mask[n] = vm[i];
			value[n] = vv[i];
			weight[n] = vw[i];
			bad |= (vm[i] & ~FEATURE_BITS) != 0;
			n++;
		}
		duckdb_destroy_data_chunk(&chunk);
	}
	if (n == 0) {
		unknown_class(st, model, cls, err);
		goto done;
	}
	int prep = bad ? -2 : mdb_template_prepare(mask, value, weight, n, MAX_COLUMNS, out);
	if (prep == -2) {
		snprintf(err->text, sizeof err->text,
		         "model '%s', class '%s': the stored template is damaged (NULLs, bits past feature 41 or "
		         "weights not in 0 < w <= %zu); train or install the model again",
		         model, cls, MAX_COLUMNS);
		goto done;
	}
	if (prep) {
		snprintf(err->text, sizeof err->text, "mocapdb: out of memory preparing a template");
		goto done;
	}
	rc = 0;
done:
	duckdb_destroy_result(&res);
unlock:
	pthread_mutex_unlock(&st->lock);
	free(mask);
	free(value);
	free(weight);
	return rc;
}

int mdb_read_words(mdb_state *st, int32_t motion, uint64_t **words, size_t *n, int *known, mdb_error *err) {
	duckdb_result res;
	int rc = -1;
	int64_t n_frames = -1;
	char name[128] = "";
	*words = NULL;
	*n = 0;
	*known = 0;
	pthread_mutex_lock(&st->lock);
	if (run_prepared(st, LENGTH_SQL, "motions", NULL, NULL, &motion, &res, err)) {
		goto unlock;
	}
	duckdb_data_chunk chunk = duckdb_column_type(&res, 0) == DUCKDB_TYPE_INTEGER ? duckdb_fetch_chunk(res) : NULL;
	if (chunk && duckdb_data_chunk_get_size(chunk) > 0) {
		duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
		if (duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), 0)) {
			n_frames = ((int32_t *)duckdb_vector_get_data(v))[0];
		}
		duckdb_vector vn = duckdb_data_chunk_get_vector(chunk, 1);
		if (duckdb_column_type(&res, 1) == DUCKDB_TYPE_VARCHAR &&
		    duckdb_validity_row_is_valid(duckdb_vector_get_validity(vn), 0)) {
			duckdb_string_t *x = duckdb_vector_get_data(vn);
			uint32_t len = duckdb_string_t_length(x[0]);
			len = len < sizeof name - 1 ? len : (uint32_t)sizeof name - 1;
			memcpy(name, duckdb_string_t_data(&x[0]), len);
			name[len] = 0;
		}
		*known = 1;
	}
	if (chunk) {
		duckdb_destroy_data_chunk(&chunk);
	}
	duckdb_destroy_result(&res);
	if (!*known) {
		rc = 0;
		goto unlock;
	}
	if (n_frames < 0) {
		n_frames = 0; /* NOT NULL in the schema; never trusted */
	}
	if (run_prepared(st, WORDS_SQL, "features", NULL, NULL, &motion, &res, err)) {
		goto unlock;
	}
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_UBIGINT};
	size_t rows = 0;
	int in_order = column_types_ok(&res, want, 2);
	uint64_t *w = n_frames > 0 ? malloc((size_t)n_frames * sizeof *w) : NULL;
	if (n_frames > 0 && !w) {
		snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading motion %d", motion);
		duckdb_destroy_result(&res);
		goto unlock;
	}
	while (in_order && (chunk = duckdb_fetch_chunk(res)) != NULL) {
		idx_t m = duckdb_data_chunk_get_size(chunk);
		duckdb_vector vf = duckdb_data_chunk_get_vector(chunk, 0), vb = duckdb_data_chunk_get_vector(chunk, 1);
		int32_t *frame = duckdb_vector_get_data(vf);
		uint64_t *bits = duckdb_vector_get_data(vb);
		for (idx_t i = 0; i < m && in_order; i++) {
			in_order = rows < (size_t)n_frames && frame[i] == (int64_t)rows + 1 &&
			           duckdb_validity_row_is_valid(duckdb_vector_get_validity(vf), i) &&
			           duckdb_validity_row_is_valid(duckdb_vector_get_validity(vb), i);
			if (in_order) {
				w[rows] = bits[i];
			}
			rows++;
		}
		duckdb_destroy_data_chunk(&chunk);
	}
	duckdb_destroy_result(&res);
	if (!in_order || rows != (size_t)n_frames) {
		/* the words of mocapdb.storage.motions.incomplete_reason */
		snprintf(err->text, sizeof err->text,
		         "motion %d (%s) has feature rows that are not its frames 1…%lld: ingest or import it again to "
		         "repair it",
		         motion, name, (long long)n_frames);
		free(w);
		goto unlock;
	}
	*words = w;
	*n = rows;
	rc = 0;
unlock:
	pthread_mutex_unlock(&st->lock);
	return rc;
}
