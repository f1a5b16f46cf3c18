/* The archive's tables as the native functions read them. Every read is one query
 * on the extension's connection under its lock, reading committed data only (as
 * the Python UDFs' cursors do). A table that is missing is an error naming it and
 * the command that creates it. */
#include "archive.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

DUCKDB_EXTENSION_EXTERN

/* no ORDER BY: the rows come in insertion order, which is (motion, run) order unless the table was
 * rewritten; sorting here only when they do not costs less than DuckDB's sort every time */
#define RUNS_SQL                                                                                                       \
	"SELECT motion_id, word, start_frame - 1, n_frames, seg FROM mocap_index.postings "                                \
	"WHERE feature_set = 'full' AND motion_id BETWEEN $1 AND $2"
#define VERSION_SQL "SELECT version FROM mocap_index.state"
#define TEMPLATE_SQL "SELECT mask, value, weight FROM templates WHERE model = $1 AND class = $2 ORDER BY col"
#define CLASSES_SQL "SELECT string_agg(class, ', ' ORDER BY class_id) FROM classes WHERE model = $1"
#define MODELS_SQL "SELECT string_agg(model, ', ' ORDER BY model) FROM models"
#define QUERY_SQL                                                                                                      \
	"SELECT k.mask, k.value, k.position, k.d_min, k.d_max, q.template_length FROM keyframes k "                        \
	"JOIN keyframe_queries q USING (model, class) WHERE k.model = $1 AND k.class = $2 ORDER BY k.k"
/* the same of all of a model's classes, grouped by class (mdb_read_model) */
#define MODEL_TEMPLATES_SQL "SELECT class, mask, value, weight FROM templates WHERE model = $1 ORDER BY class, col"
#define MODEL_QUERIES_SQL                                                                                              \
	"SELECT k.class, k.mask, k.value, k.position, k.d_min, k.d_max, q.template_length FROM keyframes k "               \
	"JOIN keyframe_queries q USING (model, class) WHERE k.model = $1 ORDER BY k.class, k.k"
#define HAS_CLASS_SQL "SELECT count(*) FROM classes WHERE model = $1 AND class = $2"
/* no ORDER BY: the rows come in insertion order, ascending ids unless the table was rewritten (then
 * sorted here: order_motions), and DuckDB's sort costs about a third of the query */
#define RANGE_SQL "SELECT motion_id, n_frames, fps FROM motions WHERE motion_id BETWEEN $1 AND $2"
#define NAME_SQL "SELECT name FROM motions WHERE motion_id = $1"
/* no ORDER BY: each row has its slot (words_sink) */
#define WORDS_SQL "SELECT motion_id, frame, bits FROM features WHERE motion_id BETWEEN $1 AND $2"
/* 41 feature bits (40 + the heading feature): a template column may fix no other */
#define FEATURE_BITS ((((uint64_t)1) << (MDB_N_COST - 1)) - 1)
/* more expanded columns than any template has (the longest are a few hundred) */
#define MAX_COLUMNS ((size_t)1 << 16)
/* as mocapdb.storage.cache.INDEX_CACHE_BYTES: the index batches kept between queries */
#define CACHE_BYTES ((size_t)256 << 20)

/* The error of a failed query, with the table it needed named when it is missing. */
static void query_error(const char *what, const char *table, const char *detail, mdb_error *err) {
	if (detail && strstr(detail, "does not exist") && strncmp(table, "mocap_index.", 12) == 0) {
		/* the words of mocapdb.storage.cache.NO_INDEX, with the table named */
		snprintf(err->text, sizeof err->text,
		         "%s: this database has no keyframe index (table %s does not exist); build it with `mocapdb "
		         "create-index` (mocapdb.api.create_index), or annotate without keyframes (keyframes := false)",
		         what, table);
	} else if (detail && strstr(detail, "does not exist")) {
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

char *mdb_string_at(duckdb_vector v, idx_t row) {
	duckdb_string_t *x = duckdb_vector_get_data(v);
	uint32_t len = duckdb_string_t_length(x[row]);
	char *s = malloc((size_t)len + 1);
	if (s) {
		memcpy(s, duckdb_string_t_data(&x[row]), len);
		s[len] = 0;
	}
	return s;
}

/* Grow the array *pp to cap elements of elem bytes; 0, or -1 leaving it as it was. */
static int grow(void *pp, size_t elem, size_t cap) {
	void **p = pp;
	void *q = realloc(*p, cap * elem);
	if (!q) {
		return -1;
	}
	*p = q;
	return 0;
}

/* Whether the extension still holds its connection (mocapdb_release() lets it go: state.c); the
 * liveness belongs here, with the reads that need the connection. */
#define RELEASED_ERROR                                                                                                 \
	"mocapdb: the extension was released on this database (mocapdb_release()); open the database again to use " \
	"its functions"

int mdb_state_live(mdb_state *st, mdb_error *err) {
	if (!st->released && st->main.con && st->data.con) {
		return 0;
	}
	snprintf(err->text, sizeof err->text, "%s", RELEASED_ERROR);
	return -1;
}

int mdb_check_live(mdb_state *st, mdb_error *err) {
	pthread_mutex_lock(&st->lock);
	int rc = mdb_state_live(st, err);
	pthread_mutex_unlock(&st->lock);
	return rc;
}

void mdb_drop_prepared(mdb_session *s) {
	for (size_t k = 0; k < s->n_prepared; k++) {
		duckdb_destroy_prepare(&s->stmt[k]);
	}
	s->n_prepared = 0;
}

/* sql's statement on the extension's connection: the kept one (fresh: prepared again), or a new
 * one kept while there is room; NULL with err set when it does not prepare. *made: prepared now;
 * *owned: the caller destroys it (not kept). */
static duckdb_prepared_statement prepared(mdb_session *st, const char *sql, const char *table, int fresh,
                                          int *made, int *owned, mdb_error *err) {
	size_t k = 0;
	while (k < st->n_prepared && st->sql[k] != sql) {
		k++;
	}
	if (k < st->n_prepared && !fresh) {
		*made = 0;
		*owned = 0;
		duckdb_clear_bindings(st->stmt[k]);
		return st->stmt[k];
	}
	duckdb_prepared_statement stmt = NULL;
	if (duckdb_prepare(st->con, sql, &stmt) == DuckDBError) {
		query_error("mocapdb", table, duckdb_prepare_error(stmt), err);
		duckdb_destroy_prepare(&stmt);
		return NULL;
	}
	*made = 1;
	if (k < st->n_prepared) { /* replaces the kept one */
		duckdb_destroy_prepare(&st->stmt[k]);
		st->stmt[k] = stmt;
		*owned = 0;
	} else if (st->n_prepared < MDB_MAX_PREPARED) {
		st->sql[st->n_prepared] = sql;
		st->stmt[st->n_prepared++] = stmt;
		*owned = 0;
	} else {
		*owned = 1;
	}
	return stmt;
}

/* A query with text parameters, then integer ones ($1, $2, … in that order), executed on the
 * extension's connection (the caller holds the lock); 0, or -1 with err naming the table. A kept
 * statement that fails is prepared and executed once more, so that a kept plan never turns into an
 * error a fresh one would not give. */
static int run_query_on(mdb_state *st, mdb_session *on, const char *sql, const char *table, const char *const *texts,
                        idx_t n_texts, const int32_t *ints, idx_t n_ints, duckdb_result *res, mdb_error *err) {
	if (mdb_state_live(st, err)) {
		return -1;
	}
	for (int fresh = 0; fresh < 2; fresh++) {
		int made = 0, owned = 0;
		duckdb_prepared_statement stmt = prepared(on, sql, table, fresh, &made, &owned, err);
		if (!stmt) {
			return -1;
		}
		for (idx_t i = 0; i < n_texts; i++) {
			duckdb_bind_varchar(stmt, i + 1, texts[i]);
		}
		for (idx_t i = 0; i < n_ints; i++) {
			duckdb_bind_int32(stmt, n_texts + i + 1, ints[i]);
		}
		int failed = duckdb_execute_prepared(stmt, res) == DuckDBError;
		if (failed) {
			query_error("mocapdb", table, duckdb_result_error(res), err);
			duckdb_destroy_result(res);
		}
		if (owned) {
			duckdb_destroy_prepare(&stmt);
		}
		if (!failed || made) {
			return failed ? -1 : 0; /* a statement prepared just now fails as it is */
		}
	}
	return -1;
}

/* run_query_on the main connection (the caller holds lock) */
static int run_query(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                     const int32_t *ints, idx_t n_ints, duckdb_result *res, mdb_error *err) {
	return run_query_on(st, &st->main, sql, table, texts, n_texts, ints, n_ints, res, err);
}

/* Where a query's rows go, a chunk of n at a time: 0 to go on, non-zero to stop (err set). */
typedef int (*chunk_sink)(void *ctx, duckdb_data_chunk chunk, idx_t n, mdb_error *err);

/* Run a query and hand its rows to sink, after checking that its columns have the types
 * mocapdb writes; 0 or -1. The result is destroyed. */
static int query_rows_on(mdb_state *st, mdb_session *on, const char *sql, const char *table, const char *const *texts,
                         idx_t n_texts, const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols,
                         chunk_sink sink, void *ctx, mdb_error *err) {
	duckdb_result res;
	if (run_query_on(st, on, sql, table, texts, n_texts, ints, n_ints, &res, err)) {
		return -1;
	}
	int rc = 0;
	if (!column_types_ok(&res, want, n_cols)) {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table %s has unexpected column types; was it written by `mocapdb ingest`?", table);
		rc = -1;
	}
	while (rc == 0) {
		duckdb_data_chunk chunk = duckdb_fetch_chunk(res);
		if (!chunk) {
			break;
		}
		rc = sink(ctx, chunk, duckdb_data_chunk_get_size(chunk), err) ? -1 : 0;
		duckdb_destroy_data_chunk(&chunk);
	}
	duckdb_destroy_result(&res);
	return rc;
}

/* query_rows_on the main connection (the caller holds lock) */
static int query_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                      const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, chunk_sink sink,
                      void *ctx, mdb_error *err) {
	return query_rows_on(st, &st->main, sql, table, texts, n_texts, ints, n_ints, want, n_cols, sink, ctx, err);
}

/* Column c of a chunk: its data and validity. */
#define COLUMN(chunk, c, type, data, valid)                                                                            \
	duckdb_vector data##_v = duckdb_data_chunk_get_vector(chunk, c);                                                   \
	type *data = duckdb_vector_get_data(data##_v);                                                                     \
	uint64_t *valid = duckdb_vector_get_validity(data##_v)

static int out_of_memory(mdb_error *err, const char *what) {
	snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading %s", what);
	return -1;
}

/* ---------------------------------------------------------------------------------------------
 * motions */

typedef struct {
	mdb_motions *m;
	size_t cap;
} motions_ctx;

static int motions_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	motions_ctx *c = p;
	mdb_motions *m = c->m;
	if (m->n + n > c->cap) {
		c->cap = 2 * (m->n + n);
		if (grow(&m->id, sizeof *m->id, c->cap) || grow(&m->n_frames, sizeof *m->n_frames, c->cap) ||
		    grow(&m->fps, sizeof *m->fps, c->cap)) {
			return out_of_memory(err, "motions");
		}
	}
	COLUMN(chunk, 0, int32_t, ids, ok_id);
	COLUMN(chunk, 1, int32_t, lens, ok_len);
	COLUMN(chunk, 2, double, fps, ok_fps);
	for (idx_t i = 0; i < n; i++) {
		if (!duckdb_validity_row_is_valid(ok_id, i)) {
			continue; /* NOT NULL in the schema; never trusted */
		}
		m->id[m->n] = ids[i];
		m->n_frames[m->n] = duckdb_validity_row_is_valid(ok_len, i) && lens[i] > 0 ? lens[i] : 0;
		m->fps[m->n] = duckdb_validity_row_is_valid(ok_fps, i) ? fps[i] : 0.0;
		m->n++;
	}
	return 0;
}

typedef struct {
	int32_t id;
	int64_t n_frames;
	double fps;
} motion_row;

static int by_motion_id(const void *a, const void *b) {
	const motion_row *x = a, *y = b;
	return (x->id > y->id) - (x->id < y->id);
}

/* Put the motions into ascending id order; 0 or -1 (out of memory). */
static int order_motions(mdb_motions *m) {
	size_t k = 1;
	while (k < m->n && m->id[k - 1] < m->id[k]) {
		k++;
	}
	if (k >= m->n) {
		return 0;
	}
	motion_row *r = malloc(m->n * sizeof *r);
	if (!r) {
		return -1;
	}
	for (size_t i = 0; i < m->n; i++) {
		r[i] = (motion_row){m->id[i], m->n_frames[i], m->fps[i]};
	}
	qsort(r, m->n, sizeof *r, by_motion_id);
	for (size_t i = 0; i < m->n; i++) {
		m->id[i] = r[i].id;
		m->n_frames[i] = r[i].n_frames;
		m->fps[i] = r[i].fps;
	}
	free(r);
	return 0;
}

void mdb_motions_free(mdb_motions *m) {
	free(m->id);
	free(m->n_frames);
	free(m->fps);
	memset(m, 0, sizeof *m);
}

/* ---------------------------------------------------------------------------------------------
 * the keyframe index */

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
	if (grow(&r->motion, sizeof *r->motion, cap) || grow(&r->word, sizeof *r->word, cap) ||
	    grow(&r->start, sizeof *r->start, cap) || grow(&r->len, sizeof *r->len, cap)) {
		return -1;
	}
	r->cap = cap;
	return 0;
}

/* A run's place in (motion, run) order, for the rare table not stored in that order. */
typedef struct {
	int32_t motion, seg;
	size_t row;
} run_key;

static int run_order(const void *a, const void *b) {
	const run_key *x = a, *y = b;
	if (x->motion != y->motion) {
		return x->motion < y->motion ? -1 : 1;
	}
	return (x->seg > y->seg) - (x->seg < y->seg);
}

/* Put the runs into (motion, run) order. */
static int order_runs(mdb_runs *r, const int32_t *seg) {
	int sorted = 1;
	for (size_t i = 1; i < r->n && sorted; i++) {
		sorted = r->motion[i - 1] < r->motion[i] || (r->motion[i - 1] == r->motion[i] && seg[i - 1] < seg[i]);
	}
	if (sorted) {
		return 0;
	}
	run_key *key = malloc(r->n * sizeof *key);
	mdb_runs out = {0};
	if (!key || runs_reserve(&out, r->n)) {
		free(key);
		mdb_runs_free(&out);
		return -1;
	}
	for (size_t i = 0; i < r->n; i++) {
		key[i] = (run_key){r->motion[i], seg[i], i};
	}
	qsort(key, r->n, sizeof *key, run_order);
	for (size_t i = 0; i < r->n; i++) {
		size_t j = key[i].row;
		out.motion[i] = r->motion[j];
		out.word[i] = r->word[j];
		out.start[i] = r->start[j];
		out.len[i] = r->len[j];
	}
	out.n = r->n;
	free(key);
	mdb_runs_free(r);
	*r = out;
	return 0;
}

typedef struct {
	mdb_runs *r;
	int32_t *seg;
	size_t seg_cap;
} runs_ctx;

static int runs_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	runs_ctx *c = p;
	mdb_runs *r = c->r;
	if (r->n + n > c->seg_cap) {
		c->seg_cap = 2 * (r->n + n);
		if (grow(&c->seg, sizeof *c->seg, c->seg_cap)) {
			return out_of_memory(err, "the keyframe index");
		}
	}
	if (runs_reserve(r, r->n + n)) {
		return out_of_memory(err, "the keyframe index");
	}
	COLUMN(chunk, 0, int32_t, mid, v0);
	COLUMN(chunk, 1, uint64_t, word, v1);
	COLUMN(chunk, 2, int32_t, start, v2);
	COLUMN(chunk, 3, int32_t, len, v3);
	COLUMN(chunk, 4, int32_t, seg, v4);
	for (idx_t i = 0; i < n; i++) {
		int ok = duckdb_validity_row_is_valid(v0, i) && duckdb_validity_row_is_valid(v1, i) &&
		         duckdb_validity_row_is_valid(v2, i) && duckdb_validity_row_is_valid(v3, i) &&
		         duckdb_validity_row_is_valid(v4, i);
		if (!ok || len[i] <= 0 || start[i] < 0) {
			continue; /* NOT NULL and positive in the schema; never trusted */
		}
		r->motion[r->n] = mid[i];
		r->word[r->n] = word[i];
		r->start[r->n] = start[i];
		r->len[r->n] = len[i];
		c->seg[r->n] = seg[i];
		r->n++;
	}
	return 0;
}

/* Read the runs of motions lo .. hi (the caller holds lock). */
static int read_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_runs *out, mdb_error *err) {
	runs_ctx ctx = {out, NULL, 0};
	int32_t range[2] = {lo, hi};
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER,
	                      DUCKDB_TYPE_INTEGER};
	out->n = 0;
	int rc = query_rows(st, RUNS_SQL, "mocap_index.postings", NULL, 0, range, 2, want, 5, runs_sink, &ctx, err);
	if (rc == 0 && order_runs(out, ctx.seg)) {
		rc = out_of_memory(err, "the keyframe index");
	}
	free(ctx.seg);
	return rc;
}

/* The index version (NULL: -1; no index built), the caller holding lock. */
static int version_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	int64_t *version = p;
	COLUMN(chunk, 0, int64_t, x, valid);
	if (n != 1 || *version != -2) {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table mocap_index.state must have one row; `mocapdb ingest` writes it");
		return -1;
	}
	*version = duckdb_validity_row_is_valid(valid, 0) ? x[0] : -1;
	return 0;
}

static int index_version(mdb_state *st, int64_t *version, mdb_error *err) {
	duckdb_type want[] = {DUCKDB_TYPE_BIGINT};
	*version = -2; /* no row yet */
	if (query_rows(st, VERSION_SQL, "mocap_index.state", NULL, 0, NULL, 0, want, 1, version_sink, version, err)) {
		return -1;
	}
	if (*version == -2) {
		snprintf(err->text, sizeof err->text,
		         "mocapdb: table mocap_index.state must have one row; `mocapdb ingest` writes it");
		return -1;
	}
	return 0;
}

static void batch_free(mdb_batch *b) {
	mdb_runs_free(&b->runs);
	free(b);
}

static size_t batch_bytes(const mdb_batch *b) {
	return sizeof *b + b->runs.cap * (sizeof(int32_t) + sizeof(uint64_t) + 2 * sizeof(int64_t));
}

/* Drop the cached batches of other versions, or all of them (every = 1); those in use go when
 * released. */
static void drop_batches(mdb_state *st, int64_t version, int every) {
	mdb_batch **p = &st->cache;
	while (*p) {
		mdb_batch *b = *p;
		if (!every && b->version == version) {
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

void mdb_drop_cache(mdb_state *st) {
	drop_batches(st, 0, 1);
}

/* The index's queries go to the main connection (lock), so that annotate gets a batch's runs while
 * the data connection reads its words; the cache has a lock of its own (cache_lock, taken after
 * lock). */
mdb_batch *mdb_acquire_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_error *err) {
	int64_t version;
	mdb_batch *b = NULL;
	pthread_mutex_lock(&st->lock);
	if (index_version(st, &version, err)) {
		goto done;
	}
	pthread_mutex_lock(&st->cache_lock);
	drop_batches(st, version, 0);
	for (b = st->cache; b; b = b->next) {
		if (b->lo == lo && b->hi == hi) {
			b->refs++;
			break;
		}
	}
	pthread_mutex_unlock(&st->cache_lock);
	if (b) {
		goto done;
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
	pthread_mutex_lock(&st->cache_lock);
	if (version >= 0 && st->cache_bytes + batch_bytes(b) <= CACHE_BYTES) {
		b->next = st->cache;
		st->cache = b;
		st->cache_bytes += batch_bytes(b);
	} else {
		b->detached = 1;
	}
	pthread_mutex_unlock(&st->cache_lock);
done:
	pthread_mutex_unlock(&st->lock);
	return b;
}

void mdb_release_runs(mdb_state *st, mdb_batch *b) {
	if (!b) {
		return;
	}
	pthread_mutex_lock(&st->cache_lock);
	if (--b->refs == 0 && b->detached) {
		batch_free(b);
	}
	pthread_mutex_unlock(&st->cache_lock);
}

/* ---------------------------------------------------------------------------------------------
 * models and motions */

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
	if (run_query(st, CLASSES_SQL, "classes", &model, 1, NULL, 0, &res, err)) {
		return;
	}
	first_text(&res, known, sizeof known);
	duckdb_destroy_result(&res);
	if (known[0]) {
		snprintf(err->text, sizeof err->text, "model '%s' has no class '%s'; its classes: %s", model, cls, known);
		return;
	}
	if (run_query(st, MODELS_SQL, "models", NULL, 0, NULL, 0, &res, err)) {
		return;
	}
	first_text(&res, known, sizeof known);
	duckdb_destroy_result(&res);
	snprintf(err->text, sizeof err->text,
	         "no model '%s' in the database (stored models: %s); a database that mocapdb opened read-write once "
	         "has the shipped ones",
	         model, known[0] ? known : "none");
}

typedef struct {
	uint64_t *mask, *value;
	double *weight;
	size_t n, cap;
	int bad;
} template_ctx;

/* Where a query's rows go one at a time: row i of a chunk whose columns start at c0. */
typedef int (*row_sink)(void *ctx, duckdb_data_chunk chunk, idx_t c0, idx_t i, mdb_error *err);

static int template_row(void *p, duckdb_data_chunk chunk, idx_t c0, idx_t i, mdb_error *err) {
	template_ctx *c = p;
	if (c->n == c->cap) {
		c->cap = 2 * c->n + 64;
		if (grow(&c->mask, sizeof *c->mask, c->cap) || grow(&c->value, sizeof *c->value, c->cap) ||
		    grow(&c->weight, sizeof *c->weight, c->cap)) {
			return out_of_memory(err, "a template");
		}
	}
	COLUMN(chunk, c0, uint64_t, mask, v0);
	COLUMN(chunk, c0 + 1, uint64_t, value, v1);
	COLUMN(chunk, c0 + 2, double, weight, v2);
	c->bad |= !duckdb_validity_row_is_valid(v0, i) || !duckdb_validity_row_is_valid(v1, i) ||
	          !duckdb_validity_row_is_valid(v2, i) || (mask[i] & ~FEATURE_BITS) != 0;
	c->mask[c->n] = mask[i];
	c->value[c->n] = value[i];
	c->weight[c->n] = weight[i];
	c->n++;
	return 0;
}

static int template_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	for (idx_t i = 0; i < n; i++) {
		if (template_row(p, chunk, 0, i, err)) {
			return -1;
		}
	}
	return 0;
}

static void template_ctx_free(template_ctx *c) {
	free(c->mask);
	free(c->value);
	free(c->weight);
}

/* The rows of several classes of a model in one query, whose first column is the class: each row
 * goes to the context of its class (ctx + k * size for cls[k]); rows of other classes are skipped.
 * A model's classes are read so, not one query each: a query costs about a millisecond. */
typedef struct {
	char *const *cls;
	size_t n;
	char *ctx;
	size_t size;
	row_sink row;
	char *last; /* the class of the previous row, and its place (n: not one of cls) */
	size_t k;
} by_class;

static int by_class_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	by_class *b = p;
	duckdb_vector names = duckdb_data_chunk_get_vector(chunk, 0);
	uint64_t *valid = duckdb_vector_get_validity(names);
	for (idx_t i = 0; i < n; i++) {
		if (!duckdb_validity_row_is_valid(valid, i)) {
			continue;
		}
		duckdb_string_t *x = (duckdb_string_t *)duckdb_vector_get_data(names) + i;
		uint32_t len = duckdb_string_t_length(*x);
		const char *name = duckdb_string_t_data(x);
		if (!b->last || strlen(b->last) != len || memcmp(b->last, name, len) != 0) {
			free(b->last);
			b->last = mdb_string_at(names, i);
			if (!b->last) {
				return out_of_memory(err, "a model");
			}
			for (b->k = 0; b->k < b->n && strcmp(b->cls[b->k], b->last) != 0; b->k++) {
			}
		}
		if (b->k < b->n && b->row(b->ctx + b->k * b->size, chunk, 1, i, err)) {
			return -1;
		}
	}
	return 0;
}

/* A class's template from its rows (the caller holds the lock). */
static int template_from_rows(mdb_state *st, const char *model, const char *cls, const template_ctx *c,
                              mdb_template *out, mdb_error *err) {
	if (c->n == 0) {
		unknown_class(st, model, cls, err);
		return -1;
	}
	int prep = c->bad ? -2 : mdb_template_prepare(c->mask, c->value, c->weight, c->n, MAX_COLUMNS, out);
	if (prep == -2) {
		snprintf(err->text, sizeof err->text,
		         "model '%s', class '%s': the stored template is damaged (NULLs, bits past feature 41 or "
		         "weights not in 0 < w <= %zu); train or install the model again",
		         model, cls, MAX_COLUMNS);
	} else if (prep) {
		out_of_memory(err, "a template");
	}
	return prep ? -1 : 0;
}

int mdb_read_template(mdb_state *st, const char *model, const char *cls, mdb_template *out, mdb_error *err) {
	template_ctx c = {0};
	const char *key[2] = {model, cls};
	duckdb_type want[] = {DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_DOUBLE};
	int rc = -1;
	memset(out, 0, sizeof *out);
	pthread_mutex_lock(&st->lock);
	if (query_rows(st, TEMPLATE_SQL, "templates", key, 2, NULL, 0, want, 3, template_sink, &c, err) == 0) {
		rc = template_from_rows(st, model, cls, &c, out, err);
	}
	pthread_mutex_unlock(&st->lock);
	template_ctx_free(&c);
	return rc;
}

/* Where the words query's rows go. No ORDER BY: DuckDB's sort of every row cost about as much as
 * the DP with keyframes (`perf`); a row's (motion, frame) is its slot, off[k] + frame - 1, and a
 * bit per slot proves each slot filled exactly once, so the order of the rows does not matter. */
typedef struct {
	const int32_t *want; /* ascending */
	const int64_t *n_frames;
	const size_t *off;
	size_t n_want, k;    /* k: the last row's motion, tried first (rows come in insertion order) */
	size_t *count;       /* rows stored per wanted motion */
	uint64_t *filled;    /* a bit per slot of words */
	uint64_t *words;
	int32_t bad;         /* a motion whose rows are not its frames 1, 2, …; 0: none */
} words_ctx;

size_t mdb_lower_bound(const int32_t *a, size_t n, int32_t x) {
	size_t lo = 0, hi = n;
	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (a[mid] < x) {
			lo = mid + 1;
		} else {
			hi = mid;
		}
	}
	return lo;
}

static int words_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	words_ctx *c = p;
	(void)err;
	COLUMN(chunk, 0, int32_t, mid, v0);
	COLUMN(chunk, 1, int32_t, frame, v1);
	COLUMN(chunk, 2, uint64_t, bits, v2);
	for (idx_t i = 0; i < n; i++) {
		if (!duckdb_validity_row_is_valid(v0, i)) {
			continue;
		}
		if (c->k == c->n_want || c->want[c->k] != mid[i]) {
			c->k = mdb_lower_bound(c->want, c->n_want, mid[i]);
			if (c->k == c->n_want || c->want[c->k] != mid[i]) {
				c->k = c->n_want;
				continue; /* a motion of the range that was not asked for */
			}
		}
		size_t k = c->k;
		if (!duckdb_validity_row_is_valid(v1, i) || !duckdb_validity_row_is_valid(v2, i) || frame[i] < 1 ||
		    frame[i] > c->n_frames[k]) {
			c->bad = mid[i];
			return 1;
		}
		size_t at = c->off[k] + (size_t)frame[i] - 1;
		uint64_t bit = (uint64_t)1 << (at & 63);
		if (c->filled[at >> 6] & bit) {
			c->bad = mid[i]; /* a frame twice */
			return 1;
		}
		c->filled[at >> 6] |= bit;
		c->words[at] = bits[i];
		c->count[k]++;
	}
	return 0;
}

int mdb_read_motion_range(mdb_state *st, int32_t lo, int32_t hi, mdb_motions *out, mdb_error *err) {
	memset(out, 0, sizeof *out);
	motions_ctx ctx = {out, 0};
	int32_t range[2] = {lo, hi};
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_DOUBLE};
	pthread_mutex_lock(&st->data_lock);
	int rc = query_rows_on(st, &st->data, RANGE_SQL, "motions", NULL, 0, range, 2, want, 3, motions_sink, &ctx, err);
	pthread_mutex_unlock(&st->data_lock);
	if (rc == 0 && order_motions(out)) {
		rc = out_of_memory(err, "motions");
	}
	if (rc) {
		mdb_motions_free(out);
	}
	return rc;
}

int mdb_read_words(mdb_state *st, int32_t lo, int32_t hi, const int32_t *want, const int64_t *n_frames,
                   const size_t *off, size_t n_want, uint64_t *words, mdb_error *err) {
	size_t slots = off[n_want];
	words_ctx c = {want,   n_frames, off,  n_want, 0, calloc(n_want ? n_want : 1, sizeof(size_t)),
	               calloc(slots / 64 + 1, sizeof(uint64_t)), words, 0};
	int32_t range[2] = {lo, hi};
	duckdb_type cols[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_UBIGINT};
	if (!c.count || !c.filled) {
		free(c.count);
		free(c.filled);
		return out_of_memory(err, "motions");
	}
	pthread_mutex_lock(&st->data_lock);
	int rc = query_rows_on(st, &st->data, WORDS_SQL, "features", NULL, 0, range, 2, cols, 3, words_sink, &c, err);
	pthread_mutex_unlock(&st->data_lock);
	/* no frame twice and none out of 1 … n_frames: n_frames rows fill every slot */
	for (size_t k = 0; k < n_want && !c.bad; k++) {
		if ((int64_t)c.count[k] != n_frames[k]) {
			c.bad = want[k];
		}
	}
	if (c.bad) {
		/* named as mocapdb.storage.motions.incomplete_reason names it: id and name (a user knows the name) */
		char name[200] = "";
		duckdb_result res;
		mdb_error ignored;
		pthread_mutex_lock(&st->data_lock);
		if (!run_query_on(st, &st->data, NAME_SQL, "motions", NULL, 0, &c.bad, 1, &res, &ignored)) {
			first_text(&res, name, sizeof name);
			duckdb_destroy_result(&res);
		}
		pthread_mutex_unlock(&st->data_lock);
		snprintf(err->text, sizeof err->text,
		         "motion %d (%s) has feature rows that are not its frames 1…n_frames: ingest or import it again to "
		         "repair it",
		         c.bad, name[0] ? name : "no name stored");
		rc = -1;
	}
	free(c.count);
	free(c.filled);
	return rc;
}

void mdb_words_batch_free(mdb_words_batch *b) {
	free(b->id);
	free(b->n_frames);
	free(b->fps);
	free(b->off);
	free(b->words);
	memset(b, 0, sizeof *b);
}

int mdb_plan_batch(const mdb_motions *range, size_t *m, const int32_t *motion, size_t n_items, size_t *i,
                   int64_t max_frames, mdb_words_batch *b, mdb_error *err) {
	if (b->cap < n_items) {
		if (grow(&b->id, sizeof *b->id, n_items) || grow(&b->n_frames, sizeof *b->n_frames, n_items) ||
		    grow(&b->fps, sizeof *b->fps, n_items) || grow(&b->off, sizeof *b->off, n_items + 1)) {
			return out_of_memory(err, "motions");
		}
		b->cap = n_items;
	}
	size_t j = *i, e = *m;
	int64_t frames = 0;
	b->n = 0;
	while (j < n_items) {
		size_t e2 = e;
		int64_t more = 0;
		while (e2 < range->n && range->id[e2] <= motion[j]) {
			more += range->n_frames[e2++];
		}
		if (j > *i && frames + more > max_frames) {
			break;
		}
		frames += more;
		e = e2;
		int32_t id = motion[j];
		if (e > 0 && range->id[e - 1] == id && (b->n == 0 || b->id[b->n - 1] != id)) {
			b->id[b->n] = id;
			b->n_frames[b->n] = range->n_frames[e - 1];
			b->fps[b->n++] = range->fps[e - 1];
		}
		for (; j < n_items && motion[j] == id; j++) {
		}
	}
	*i = j;
	*m = e;
	b->off[0] = 0;
	for (size_t k = 0; k < b->n; k++) {
		b->off[k + 1] = b->off[k] + (size_t)b->n_frames[k];
	}
	free(b->words);
	b->words = malloc((b->off[b->n] ? b->off[b->n] : 1) * sizeof *b->words);
	if (!b->words) {
		return out_of_memory(err, "features");
	}
	return 0;
}

int mdb_read_batch_words(mdb_state *st, mdb_words_batch *b, mdb_error *err) {
	return b->n ? mdb_read_words(st, b->id[0], b->id[b->n - 1], b->id, b->n_frames, b->off, b->n, b->words, err) : 0;
}

int mdb_read_batch(mdb_state *st, const mdb_motions *range, size_t *m, const int32_t *motion, size_t n_items,
                   size_t *i, int64_t max_frames, mdb_words_batch *b, mdb_error *err) {
	return mdb_plan_batch(range, m, motion, n_items, i, max_frames, b, err) || mdb_read_batch_words(st, b, err) ? -1 : 0;
}

typedef struct {
	mdb_query *q;
	int64_t first_pos, last_pos, length;
	size_t rows;
	int bad;
} query_ctx;

static int query_row(void *p, duckdb_data_chunk chunk, idx_t c0, idx_t i, mdb_error *err) {
	query_ctx *c = p;
	(void)err;
	if (c->bad) {
		return 0; /* its other rows do not matter */
	}
	COLUMN(chunk, c0, uint64_t, mask, v0);
	COLUMN(chunk, c0 + 1, uint64_t, value, v1);
	COLUMN(chunk, c0 + 2, int32_t, pos, v2);
	COLUMN(chunk, c0 + 3, int32_t, d_min, v3);
	COLUMN(chunk, c0 + 4, int32_t, d_max, v4);
	COLUMN(chunk, c0 + 5, int32_t, length, v5);
	if (c->rows >= MDB_MAX_KEYFRAMES || !duckdb_validity_row_is_valid(v0, i) || !duckdb_validity_row_is_valid(v1, i) ||
	    !duckdb_validity_row_is_valid(v2, i) || !duckdb_validity_row_is_valid(v5, i) || (mask[i] & ~FEATURE_BITS) ||
	    (value[i] & ~mask[i])) {
		c->bad = 1;
		return 0;
	}
	size_t k = c->rows++;
	c->q->mask[k] = mask[i];
	c->q->value[k] = value[i];
	/* the gap to the next keyframe (the last row's bounds are NULL): NULL d_min is 0, NULL d_max
	 * unbounded, as mocapdb.storage.model_store reads them */
	c->q->d_min[k] = duckdb_validity_row_is_valid(v3, i) ? d_min[i] : 0;
	c->q->d_max[k] = duckdb_validity_row_is_valid(v4, i) ? d_max[i] : MDB_UNBOUNDED;
	if (k == 0) {
		c->first_pos = pos[i];
	}
	c->last_pos = pos[i];
	c->length = length[i];
	return 0;
}

static int query_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	for (idx_t i = 0; i < n && !((query_ctx *)p)->bad; i++) {
		query_row(p, chunk, 0, i, err);
	}
	return 0;
}

static int count_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	(void)err;
	COLUMN(chunk, 0, int64_t, x, valid);
	if (n > 0 && duckdb_validity_row_is_valid(valid, 0)) {
		*(int64_t *)p = x[0];
	}
	return 0;
}

/* A class's keyframe query from its rows (the caller holds the lock). */
static int query_from_rows(mdb_state *st, const char *model, const char *cls, int extend, const query_ctx *c,
                           mdb_query *out, mdb_error *err) {
	const char *key[2] = {model, cls};
	duckdb_type count_type[] = {DUCKDB_TYPE_BIGINT};
	int64_t has_class = 0;
	if (c->bad || c->first_pos < 1 || c->last_pos < c->first_pos || c->length < c->last_pos) {
		if (c->rows == 0) {
			if (query_rows(st, HAS_CLASS_SQL, "classes", key, 2, NULL, 0, count_type, 1, count_sink, &has_class,
			               err)) {
				return -1;
			}
			if (has_class) {
				snprintf(err->text, sizeof err->text,
				         "class '%s' of model '%s' has no keyframe query; learn one with `mocapdb learn-keyframes`", cls,
				         model);
			} else {
				unknown_class(st, model, cls, err);
			}
		} else {
			snprintf(err->text, sizeof err->text,
			         "model '%s', class '%s': the stored keyframe query is damaged (NULLs, more than %d keyframes, "
			         "words past feature 41 or positions outside the template); learn or install it again",
			         model, cls, MDB_MAX_KEYFRAMES);
		}
		return -1;
	}
	out->K = c->rows;
	for (size_t g = 0; g + 1 < out->K; g++) {
		if (out->d_min[g] < 0 || out->d_max[g] < out->d_min[g]) {
			snprintf(err->text, sizeof err->text,
			         "model '%s', class '%s': gap %zu of the stored keyframe query has d_max < d_min or d_min < 0", model,
			         cls, g + 1);
			return -1;
		}
	}
	if (extend) { /* mocapdb.keyframes.annot_margins, positions 1-based here */
		out->ext_l = 2 * (c->first_pos - 1);
		out->ext_r = 2 * (c->length - c->last_pos);
	}
	return 0;
}

int mdb_read_keyframe_query(mdb_state *st, const char *model, const char *cls, int extend, mdb_query *out,
                            mdb_error *err) {
	query_ctx c = {out, 0, 0, 0, 0, 0};
	const char *key[2] = {model, cls};
	duckdb_type want[] = {DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_INTEGER,
	                      DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER};
	int rc = -1;
	memset(out, 0, sizeof *out);
	pthread_mutex_lock(&st->lock);
	if (query_rows(st, QUERY_SQL, "keyframes", key, 2, NULL, 0, want, 6, query_sink, &c, err) == 0) {
		rc = query_from_rows(st, model, cls, extend, &c, out, err);
	}
	pthread_mutex_unlock(&st->lock);
	return rc;
}

/* ---------------------------------------------------------------------------------------------
 * a whole model */

/* classes in class_id order with what annotation needs of their label and model (old databases
 * without min_frames / margin have the defaults the schema upgrade writes) */
#define MODEL_SQL                                                                                                      \
	"SELECT c.class, c.label, c.label_id, c.tau, coalesce(c.min_frames, 0), "                                          \
	"coalesce(list_contains(m.concurrent_labels, c.label), false), coalesce(m.margin, 0.0), "                          \
	"EXISTS (SELECT 1 FROM keyframe_queries q WHERE q.model = c.model AND q.class = c.class) "                         \
	"FROM classes c JOIN models m ON m.model = c.model WHERE c.model = $1 ORDER BY c.class_id"

typedef struct {
	mdb_model *m;
	char **cls;
	int32_t *label_id;
	char *has_query;
	size_t cap;
	int bad;
} model_ctx;


static int model_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	model_ctx *c = p;
	mdb_model *m = c->m;
	if (m->n_classes + n > c->cap) {
		c->cap = 2 * (m->n_classes + n);
		if (grow(&c->cls, sizeof *c->cls, c->cap) || grow(&m->label, sizeof *m->label, c->cap) ||
		    grow(&c->label_id, sizeof *c->label_id, c->cap) || grow(&m->tau, sizeof *m->tau, c->cap) ||
		    grow(&m->min_frames, sizeof *m->min_frames, c->cap) ||
		    grow(&m->concurrent, sizeof *m->concurrent, c->cap) || grow(&c->has_query, sizeof *c->has_query, c->cap)) {
			return out_of_memory(err, "a model");
		}
	}
	duckdb_vector cls_v = duckdb_data_chunk_get_vector(chunk, 0), label_v = duckdb_data_chunk_get_vector(chunk, 1);
	uint64_t *v0 = duckdb_vector_get_validity(cls_v), *v1 = duckdb_vector_get_validity(label_v);
	COLUMN(chunk, 2, int32_t, label_id, v2);
	COLUMN(chunk, 3, double, tau, v3);
	COLUMN(chunk, 4, int32_t, min_frames, v4);
	COLUMN(chunk, 5, bool, concurrent, v5);
	COLUMN(chunk, 6, double, margin, v6);
	COLUMN(chunk, 7, bool, has_query, v7);
	for (idx_t i = 0; i < n; i++) {
		size_t k = m->n_classes;
		if (!duckdb_validity_row_is_valid(v0, i) || !duckdb_validity_row_is_valid(v1, i) ||
		    !duckdb_validity_row_is_valid(v2, i) || !duckdb_validity_row_is_valid(v3, i) ||
		    !duckdb_validity_row_is_valid(v4, i) || !duckdb_validity_row_is_valid(v6, i) || !(tau[i] >= 0) || !(margin[i] >= 0) || min_frames[i] < 0) {
			c->bad = 1;
			return 1;
		}
		c->cls[k] = mdb_string_at(cls_v, i);
		m->label[k] = mdb_string_at(label_v, i);
		m->n_classes++; /* freed with the model from here on */
		if (!c->cls[k] || !m->label[k]) {
			return out_of_memory(err, "a model");
		}
		c->label_id[k] = label_id[i];
		m->tau[k] = tau[i];
		m->min_frames[k] = min_frames[i];
		m->concurrent[k] = duckdb_validity_row_is_valid(v5, i) && concurrent[i];
		c->has_query[k] = duckdb_validity_row_is_valid(v7, i) && has_query[i];
		m->margin = margin[i];
	}
	return 0;
}

/* calibrated confidence: a database from before it has no table confidence_maps (raw scores) */
#define HAS_MAPS_SQL                                                                                                   \
	"SELECT count(*) FROM duckdb_tables() WHERE table_name = 'confidence_maps' "                                      \
	"AND database_name = current_database() AND schema_name = current_schema()"
#define MAPS_SQL                                                                                                       \
	"SELECT label, cut, value, min_length FROM confidence_maps WHERE model = $1 ORDER BY label, min_length, k"

typedef struct {
	mdb_model *m;
	size_t *cap; /* per label */
	int bad;
} maps_ctx;

static int maps_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	maps_ctx *c = p;
	mdb_model *m = c->m;
	duckdb_vector label_v = duckdb_data_chunk_get_vector(chunk, 0);
	uint64_t *v0 = duckdb_vector_get_validity(label_v);
	COLUMN(chunk, 1, double, cut, v1);
	COLUMN(chunk, 2, double, value, v2);
	COLUMN(chunk, 3, int32_t, min_length, v3);
	for (idx_t i = 0; i < n; i++) {
		if (!duckdb_validity_row_is_valid(v0, i) || !duckdb_validity_row_is_valid(v1, i) ||
		    !duckdb_validity_row_is_valid(v2, i) || !duckdb_validity_row_is_valid(v3, i) || min_length[i] < 0) {
			c->bad = 1;
			return 1;
		}
		char *label = mdb_string_at(label_v, i);
		if (!label) {
			return out_of_memory(err, "a confidence map");
		}
		size_t p = 0;
		while (p < m->n_labels && strcmp(m->label[p], label) != 0) {
			p++;
		}
		free(label);
		if (p == m->n_labels) { /* a map of a label the model does not have */
			c->bad = 1;
			return 1;
		}
		size_t k = m->conf_n[p];
		if (k == c->cap[p]) {
			c->cap[p] = 2 * k + 4;
			if (grow(&m->conf_cut[p], sizeof **m->conf_cut, c->cap[p]) ||
			    grow(&m->conf_value[p], sizeof **m->conf_value, c->cap[p]) ||
			    grow(&m->conf_min_length[p], sizeof **m->conf_min_length, c->cap[p])) {
				return out_of_memory(err, "a confidence map");
			}
		}
		/* ConfidenceMap's rules, within a map (a label's steps of one min_length): finite ascending
		 * cuts, non-decreasing values in [0, 1] */
		int same = k > 0 && m->conf_min_length[p][k - 1] == min_length[i];
		if (!isfinite(cut[i]) || !(value[i] >= 0.0 && value[i] <= 1.0) ||
		    (same && !(cut[i] > m->conf_cut[p][k - 1] && value[i] >= m->conf_value[p][k - 1]))) {
			c->bad = 1;
			return 1;
		}
		m->conf_cut[p][k] = cut[i];
		m->conf_value[p][k] = value[i];
		m->conf_min_length[p][k] = min_length[i];
		m->conf_n[p] = k + 1;
	}
	return 0;
}

/* The model's confidence maps, per label (its labels read already; the caller holds the lock); 0 or -1. */
static int read_confidence_maps(mdb_state *st, const char *name, mdb_model *m, mdb_error *err) {
	size_t L = m->n_labels ? m->n_labels : 1;
	m->conf_n = calloc(L, sizeof *m->conf_n);
	m->conf_cut = calloc(L, sizeof *m->conf_cut);
	m->conf_value = calloc(L, sizeof *m->conf_value);
	m->conf_min_length = calloc(L, sizeof *m->conf_min_length);
	maps_ctx c = {m, calloc(L, sizeof(size_t)), 0};
	if (!m->conf_n || !m->conf_cut || !m->conf_value || !m->conf_min_length || !c.cap) {
		free(c.cap);
		return out_of_memory(err, "a model");
	}
	duckdb_type count_type[] = {DUCKDB_TYPE_BIGINT};
	duckdb_type want[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_INTEGER};
	int64_t has_maps = 0;
	int rc = 0;
	if (query_rows(st, HAS_MAPS_SQL, "duckdb_tables()", NULL, 0, NULL, 0, count_type, 1, count_sink, &has_maps,
	               err)) {
		rc = -1;
	} else if (has_maps) {
		rc = query_rows(st, MAPS_SQL, "confidence_maps", &name, 1, NULL, 0, want, 4, maps_sink, &c, err);
	}
	free(c.cap);
	if (c.bad) {
		snprintf(err->text, sizeof err->text,
		         "model '%s': its confidence_maps rows are damaged (NULLs, a label it lacks, cuts not ascending or "
		         "values not rising within [0, 1]); train or install the model again",
		         name);
		rc = -1;
	}
	return rc;
}

void mdb_model_free(mdb_model *m) {
	for (size_t p = 0; m->conf_n && p < m->n_labels; p++) { /* the four are allocated together */
		free(m->conf_cut ? m->conf_cut[p] : NULL);
		free(m->conf_value ? m->conf_value[p] : NULL);
		free(m->conf_min_length ? m->conf_min_length[p] : NULL);
	}
	free(m->conf_n);
	free(m->conf_cut);
	free(m->conf_value);
	free(m->conf_min_length);
	for (size_t k = 0; k < m->n_classes; k++) {
		free(m->label[k]);
		if (m->tpl) {
			mdb_template_free(&m->tpl[k]);
		}
	}
	free(m->label);
	free(m->concurrent);
	free(m->label_of);
	free(m->tau);
	free(m->min_frames);
	free(m->tpl);
	free(m->query);
	memset(m, 0, sizeof *m);
}

/* The templates and keyframe queries of a model's classes cls[0 .. n), one query for each kind (the
 * caller holds the lock). */
static int read_classes(mdb_state *st, const char *name, char *const *cls, const char *has_query, size_t n,
                        mdb_model *out, mdb_error *err) {
	duckdb_type want_t[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_DOUBLE};
	duckdb_type want_q[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_UBIGINT, DUCKDB_TYPE_INTEGER,
	                        DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER};
	template_ctx *tc = calloc(n, sizeof *tc);
	query_ctx *qc = calloc(n, sizeof *qc);
	int rc = -1, any_query = 0;
	if (!tc || !qc) {
		free(tc);
		free(qc);
		return out_of_memory(err, "a model");
	}
	for (size_t k = 0; k < n; k++) {
		qc[k].q = &out->query[k];
		any_query |= has_query[k];
	}
	by_class bt = {cls, n, (char *)tc, sizeof *tc, template_row, NULL, 0};
	by_class bq = {cls, n, (char *)qc, sizeof *qc, query_row, NULL, 0};
	if (query_rows(st, MODEL_TEMPLATES_SQL, "templates", &name, 1, NULL, 0, want_t, 4, by_class_sink, &bt, err) ||
	    (any_query &&
	     query_rows(st, MODEL_QUERIES_SQL, "keyframes", &name, 1, NULL, 0, want_q, 7, by_class_sink, &bq, err))) {
		goto done;
	}
	for (size_t k = 0; k < n; k++) {
		if (template_from_rows(st, name, cls[k], &tc[k], &out->tpl[k], err) ||
		    (has_query[k] && query_from_rows(st, name, cls[k], 1, &qc[k], &out->query[k], err))) {
			goto done;
		}
	}
	rc = 0;
done:
	for (size_t k = 0; k < n; k++) {
		template_ctx_free(&tc[k]);
	}
	free(tc);
	free(qc);
	free(bt.last);
	free(bq.last);
	return rc;
}

int mdb_read_model_locked(mdb_state *st, const char *name, mdb_model *out, mdb_error *err) {
	memset(out, 0, sizeof *out);
	model_ctx c = {out, NULL, NULL, NULL, 0, 0};
	duckdb_type want[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_DOUBLE,
	                      DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_BOOLEAN, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_BOOLEAN};
	int rc = -1;
	int q = query_rows(st, MODEL_SQL, "classes", &name, 1, NULL, 0, want, 8, model_sink, &c, err);
	if (q == 0 && out->n_classes == 0) {
		unknown_class(st, name, "", err);
		q = -1;
	}
	if (c.bad) {
		snprintf(err->text, sizeof err->text,
		         "model '%s': its classes rows are damaged (NULLs, a negative tau, margin or min_frames); train or "
		         "install the model again",
		         name);
	}
	size_t n = out->n_classes;
	if (q || c.bad) {
		goto done;
	}
	/* labels in label_id order, each once; per class the index of its label; a label's rows keep
	 * what is per label (concurrent) from its first class */
	char **labels = calloc(n, sizeof *labels);
	char *concurrent = calloc(n, 1);
	int32_t *ids = malloc(n * sizeof *ids);
	out->label_of = malloc(n * sizeof *out->label_of);
	out->tpl = calloc(n, sizeof *out->tpl);
	out->query = calloc(n, sizeof *out->query);
	if (!labels || !concurrent || !ids || !out->label_of || !out->tpl || !out->query) {
		free(labels);
		free(concurrent);
		free(ids);
		out_of_memory(err, "a model");
		goto done;
	}
	size_t L = 0;
	for (size_t k = 0; k < n; k++) {
		size_t p = 0;
		while (p < L && ids[p] < c.label_id[k]) {
			p++;
		}
		if (p < L && ids[p] == c.label_id[k]) {
			continue;
		}
		memmove(ids + p + 1, ids + p, (L - p) * sizeof *ids);
		memmove(labels + p + 1, labels + p, (L - p) * sizeof *labels);
		memmove(concurrent + p + 1, concurrent + p, L - p);
		ids[p] = c.label_id[k];
		labels[p] = out->label[k];
		concurrent[p] = out->concurrent[k];
		L++;
	}
	int disagree = 0;
	for (size_t k = 0; k < n; k++) {
		size_t p = 0;
		while (ids[p] != c.label_id[k]) {
			p++;
		}
		out->label_of[k] = (int64_t)p;
		disagree |= strcmp(labels[p], out->label[k]) != 0;
	}
	/* the model owns the label names in label order from here on */
	for (size_t k = 0; k < n; k++) {
		int used = 0;
		for (size_t p = 0; p < L; p++) {
			used |= labels[p] == out->label[k];
		}
		if (!used) {
			free(out->label[k]);
		}
	}
	for (size_t p = 0; p < n; p++) {
		out->label[p] = p < L ? labels[p] : NULL;
		out->concurrent[p] = p < L ? concurrent[p] : 0;
	}
	out->n_labels = L;
	free(labels);
	free(concurrent);
	free(ids);
	if (disagree) {
		snprintf(err->text, sizeof err->text, "model '%s': labels and label ids of its classes disagree", name);
		goto done;
	}
	if (read_confidence_maps(st, name, out, err)) {
		goto done;
	}
	if (read_classes(st, name, c.cls, c.has_query, n, out, err) == 0) {
		rc = 0;
	}
done:
	for (size_t k = 0; k < n; k++) {
		free(c.cls[k]);
	}
	free(c.cls);
	free(c.label_id);
	free(c.has_query);
	if (rc) {
		mdb_model_free(out);
	}
	return rc;
}

int mdb_read_model(mdb_state *st, const char *name, mdb_model *out, mdb_error *err) {
	pthread_mutex_lock(&st->lock);
	int rc = mdb_read_model_locked(st, name, out, err);
	pthread_mutex_unlock(&st->lock);
	return rc;
}

int mdb_grow(void *pp, size_t elem, size_t cap) {
	return grow(pp, elem, cap);
}

int mdb_query_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                   const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink,
                   void *ctx, mdb_error *err) {
	pthread_mutex_lock(&st->lock);
	int rc = query_rows(st, sql, table, texts, n_texts, ints, n_ints, want, n_cols, sink, ctx, err);
	pthread_mutex_unlock(&st->lock);
	return rc;
}

int mdb_query_rows_locked(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                          const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink, void *ctx, mdb_error *err) {
	return query_rows(st, sql, table, texts, n_texts, NULL, 0, want, n_cols, sink, ctx, err);
}
