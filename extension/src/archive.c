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
