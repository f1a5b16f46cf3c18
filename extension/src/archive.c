/* The archive's tables as the native functions read them. Every read is one query
 * on the extension's connection under its lock, reading committed data only (as
 * the Python UDFs' cursors do). A table that is missing is an error naming it and
 * the command that creates it. This file holds the motions, their words and the index; the models
 * are read in model_read.c, with the query plumbing of archive_rows.h. */
#include "archive.h"
#include "archive_rows.h"

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
/* no ORDER BY: the rows come in insertion order, ascending ids unless the table was rewritten (then
 * sorted here: order_motions), and DuckDB's sort costs about a third of the query */
#define RANGE_SQL "SELECT motion_id, n_frames, fps FROM motions WHERE motion_id BETWEEN $1 AND $2"
#define NAME_SQL "SELECT name FROM motions WHERE motion_id = $1"
/* no ORDER BY: each row has its slot (words_sink) */
#define WORDS_SQL "SELECT motion_id, frame, bits FROM features WHERE motion_id BETWEEN $1 AND $2"
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
int mdb_run_query(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
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
int mdb_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
             const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink, void *ctx,
             mdb_error *err) {
	return query_rows_on(st, &st->main, sql, table, texts, n_texts, ints, n_ints, want, n_cols, sink, ctx, err);
}

int mdb_out_of_memory(mdb_error *err, const char *what) {
	snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading %s", what);
	return -1;
}

/* The first row's VARCHAR of a one-column result into buf ("" when NULL or none). */
void mdb_first_text(duckdb_result *res, char *buf, size_t size) {
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
			return mdb_out_of_memory(err, "motions");
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
			return mdb_out_of_memory(err, "the keyframe index");
		}
	}
	if (runs_reserve(r, r->n + n)) {
		return mdb_out_of_memory(err, "the keyframe index");
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
	int rc = mdb_rows(st, RUNS_SQL, "mocap_index.postings", NULL, 0, range, 2, want, 5, runs_sink, &ctx, err);
	if (rc == 0 && order_runs(out, ctx.seg)) {
		rc = mdb_out_of_memory(err, "the keyframe index");
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
	if (mdb_rows(st, VERSION_SQL, "mocap_index.state", NULL, 0, NULL, 0, want, 1, version_sink, version, err)) {
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
		rc = mdb_out_of_memory(err, "motions");
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
		return mdb_out_of_memory(err, "motions");
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
			mdb_first_text(&res, name, sizeof name);
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
			return mdb_out_of_memory(err, "motions");
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
		return mdb_out_of_memory(err, "features");
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

int mdb_grow(void *pp, size_t elem, size_t cap) {
	return grow(pp, elem, cap);
}

int mdb_query_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                   const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink,
                   void *ctx, mdb_error *err) {
	pthread_mutex_lock(&st->lock);
	int rc = mdb_rows(st, sql, table, texts, n_texts, ints, n_ints, want, n_cols, sink, ctx, err);
	pthread_mutex_unlock(&st->lock);
	return rc;
}

int mdb_query_rows_locked(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                          const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink, void *ctx, mdb_error *err) {
	return mdb_rows(st, sql, table, texts, n_texts, NULL, 0, want, n_cols, sink, ctx, err);
}
