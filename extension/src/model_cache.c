/* The models annotate reads, kept between calls while their rows are unchanged.
 *
 * A model is five queries and its templates' set-up (about 7 ms, the largest fixed cost of a call
 * with keyframes); whether its rows changed is one query (KEY_SQL, about a third of that): per
 * model table the count and the sum of DuckDB's hash of every column the read uses, over the
 * model's rows. A kept model is used only while that key is the one read with it; any write to a
 * model table, through mocapdb or plain SQL, committed by any connection, changes the key of the
 * models it touches (but for a 64-bit hash collision of the changed rows; DuckDB hashes +0.0 and
 * -0.0 alike, hence each double's sign bit beside it). A model is read in one transaction with its
 * key (one snapshot: a write between the key and the read cannot pair a new model with an old key
 * or the other way round). What the key does not see is a column's type changed with its values
 * kept: the read's rows, and so the model, are the same. Where the key query fails (a database
 * from before confidence maps has no table confidence_maps, one from before the length entered their
 * score no column length_weight, one from before the length multiplied the match no column
 * length_product) or the read in one transaction does,
 * the model is read as before, every call, and errors are the read's. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"

DUCKDB_EXTENSION_EXTERN

/* as many as the model tables the read uses */
#define N_KEYED 6
#define KEY_SQL                                                                                                        \
	"SELECT 0, count(*), sum(hash(margin, signbit(margin), concurrent_labels)) FROM models WHERE model = $1 "          \
	"UNION ALL SELECT 1, count(*), sum(hash(class, class_id, label, label_id, tau, signbit(tau), min_frames)) "      \
	"FROM classes WHERE model = $1 "                                                                                   \
	"UNION ALL SELECT 2, count(*), sum(hash(class, col, mask, value, weight, signbit(weight))) FROM templates "       \
	"WHERE model = $1 "                                                                                                \
	"UNION ALL SELECT 3, count(*), sum(hash(class, template_length)) FROM keyframe_queries WHERE model = $1 "         \
	"UNION ALL SELECT 4, count(*), sum(hash(class, k, mask, value, position, d_min, d_max)) FROM keyframes "         \
	"WHERE model = $1 "                                                                                                \
	"UNION ALL SELECT 5, count(*), sum(hash(label, min_length, k, cut, signbit(cut), value, signbit(value), "          \
	"length_weight, full_length, length_product)) FROM confidence_maps WHERE model = $1"
/* models kept per database (a call uses one or a few; each is a few MB at most) */
#define MAX_KEPT 8

typedef struct {
	int64_t rows[N_KEYED];
	duckdb_hugeint sum[N_KEYED];
	unsigned char seen[N_KEYED], has_sum[N_KEYED];
} model_key;

struct mdb_model_entry {
	char *name;
	model_key key;
	mdb_model m;
	int refs;     /* calls using it */
	int detached; /* not kept (or no longer): freed by its last release */
	struct mdb_model_entry *next;
};

static int key_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	model_key *k = p;
	(void)err;
	duckdb_vector tag_v = duckdb_data_chunk_get_vector(chunk, 0), rows_v = duckdb_data_chunk_get_vector(chunk, 1),
	              sum_v = duckdb_data_chunk_get_vector(chunk, 2);
	int32_t *tag = duckdb_vector_get_data(tag_v);
	int64_t *rows = duckdb_vector_get_data(rows_v);
	duckdb_hugeint *sum = duckdb_vector_get_data(sum_v);
	uint64_t *valid = duckdb_vector_get_validity(sum_v);
	for (idx_t i = 0; i < n; i++) {
		if (tag[i] < 0 || tag[i] >= N_KEYED) {
			continue; /* not from KEY_SQL */
		}
		size_t t = (size_t)tag[i];
		k->seen[t] = 1;
		k->rows[t] = rows[i];
		k->has_sum[t] = duckdb_validity_row_is_valid(valid, i); /* NULL: no rows */
		if (k->has_sum[t]) {
			k->sum[t] = sum[i];
		}
	}
	return 0;
}

/* The key of model name's rows (the caller holds lock); 0 or -1. */
static int read_key(mdb_state *st, const char *name, model_key *k, mdb_error *err) {
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_BIGINT, DUCKDB_TYPE_HUGEINT};
	memset(k, 0, sizeof *k); /* compared with memcmp */
	if (mdb_query_rows_locked(st, KEY_SQL, "models", &name, 1, want, 3, key_sink, k, err)) {
		return -1;
	}
	for (size_t t = 0; t < N_KEYED; t++) {
		if (!k->seen[t]) {
			return -1;
		}
	}
	return 0;
}

/* A statement without rows on the extension's main connection (the caller holds lock); 0 or -1. */
static int run(mdb_state *st, const char *sql) {
	duckdb_result res;
	int rc = duckdb_query(st->main.con, sql, &res) == DuckDBError ? -1 : 0;
	duckdb_destroy_result(&res);
	return rc;
}

/* The model and its key in one snapshot (the caller holds lock); 0, or -1 with nothing read. */
static int read_keyed(mdb_state *st, const char *name, mdb_model_entry *e) {
	mdb_error ignored;
	if (run(st, "BEGIN TRANSACTION")) {
		return -1;
	}
	if (read_key(st, name, &e->key, &ignored) || mdb_read_model_locked(st, name, &e->m, &ignored)) {
		run(st, "ROLLBACK");
		return -1;
	}
	if (run(st, "COMMIT")) {
		mdb_model_free(&e->m);
		return -1;
	}
	return 0;
}

static void entry_free(mdb_model_entry *e) {
	free(e->name);
	mdb_model_free(&e->m);
	free(e);
}

/* Take *p out of the kept list (the caller holds lock). */
static void detach(mdb_model_entry **p) {
	mdb_model_entry *e = *p;
	*p = e->next;
	e->next = NULL;
	e->detached = 1;
	if (e->refs == 0) {
		entry_free(e);
	}
}

/* Keep e, newest first, dropping a kept model of its name and the oldest past MAX_KEPT. */
static void keep(mdb_state *st, mdb_model_entry *e) {
	for (mdb_model_entry **p = &st->models; *p;) {
		if (strcmp((*p)->name, e->name) == 0) {
			detach(p);
		} else {
			p = &(*p)->next;
		}
	}
	e->next = st->models;
	st->models = e;
	size_t n = 0;
	for (mdb_model_entry **p = &st->models; *p;) {
		if (++n > MAX_KEPT) {
			detach(p);
		} else {
			p = &(*p)->next;
		}
	}
}

int mdb_acquire_model(mdb_state *st, const char *name, mdb_model_entry **out, mdb_error *err) {
	*out = NULL;
	mdb_model_entry *e = calloc(1, sizeof *e);
	if (e) {
		e->name = strdup(name);
	}
	if (!e || !e->name) {
		free(e);
		snprintf(err->text, sizeof err->text, "mocapdb: out of memory reading a model");
		return -1;
	}
	e->refs = 1;
	pthread_mutex_lock(&st->lock);
	if (mdb_state_live(st, err)) {
		pthread_mutex_unlock(&st->lock);
		entry_free(e);
		return -1;
	}
	model_key key;
	mdb_error ignored;
	int keyed = read_key(st, name, &key, &ignored) == 0;
	for (mdb_model_entry *k = st->models; keyed && k; k = k->next) {
		if (strcmp(k->name, name) == 0 && memcmp(&k->key, &key, sizeof key) == 0) {
			k->refs++;
			pthread_mutex_unlock(&st->lock);
			entry_free(e);
			*out = k;
			return 0;
		}
	}
	int rc = 0;
	if (keyed && read_keyed(st, name, e) == 0) {
		keep(st, e);
	} else {
		e->detached = 1; /* read as before: its errors, nothing kept */
		rc = mdb_read_model_locked(st, name, &e->m, err);
	}
	pthread_mutex_unlock(&st->lock);
	if (rc) {
		entry_free(e);
		return -1;
	}
	*out = e;
	return 0;
}

const mdb_model *mdb_entry_model(const mdb_model_entry *e) {
	return &e->m;
}

void mdb_release_model(mdb_state *st, mdb_model_entry *e) {
	if (!e) {
		return;
	}
	pthread_mutex_lock(&st->lock);
	if (--e->refs == 0 && e->detached) {
		entry_free(e);
	}
	pthread_mutex_unlock(&st->lock);
}

void mdb_drop_models(mdb_state *st) {
	while (st->models) {
		detach(&st->models);
	}
}
