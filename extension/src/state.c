/* The extension's state of one database instance, and its release.
 *
 * LOAD's connection holds the database instance: while it is open, closing every user
 * connection does not close the file. `SELECT mocapdb_release()` disconnects it and frees the
 * index cache, so the file closes with its last user connection (mocapdb.connect calls it when
 * its last connection of the instance goes). The functions stay registered with the database
 * (DuckDB cannot unregister them): after the release each call is an error saying to open the
 * database again. The state is freed by the destroy callback of the last function holding it,
 * when DuckDB drops the database's catalog. */
#include <stdlib.h>

#include "archive.h"
#include "functions.h"

DUCKDB_EXTENSION_EXTERN

mdb_state *mdb_state_new(void) {
	mdb_state *st = calloc(1, sizeof *st);
	if (!st) {
		return NULL;
	}
	if (pthread_mutex_init(&st->lock, NULL)) {
		free(st);
		return NULL;
	}
	if (pthread_mutex_init(&st->data_lock, NULL)) {
		pthread_mutex_destroy(&st->lock);
		free(st);
		return NULL;
	}
	if (pthread_mutex_init(&st->cache_lock, NULL)) {
		pthread_mutex_destroy(&st->data_lock);
		pthread_mutex_destroy(&st->lock);
		free(st);
		return NULL;
	}
	st->refs = 1;
	return st;
}

mdb_state *mdb_state_ref(mdb_state *st) {
	__atomic_add_fetch(&st->refs, 1, __ATOMIC_SEQ_CST);
	return st;
}

void mdb_state_unref(void *p) {
	mdb_state *st = p;
	if (__atomic_sub_fetch(&st->refs, 1, __ATOMIC_SEQ_CST) > 0) {
		return;
	}
	/* no function can run any more: nothing else holds the lock or a batch */
	mdb_state_release(st);
	pthread_mutex_destroy(&st->cache_lock);
	pthread_mutex_destroy(&st->data_lock);
	pthread_mutex_destroy(&st->lock);
	free(st);
}

int mdb_state_release(mdb_state *st) {
	pthread_mutex_lock(&st->lock);
	pthread_mutex_lock(&st->data_lock);
	int was_live = !st->released;
	if (was_live) {
		mdb_session *both[2] = {&st->main, &st->data};
		for (int k = 0; k < 2; k++) {
			mdb_drop_prepared(both[k]);
			if (both[k]->con) {
				duckdb_disconnect(&both[k]->con);
			}
		}
		pthread_mutex_lock(&st->cache_lock);
		mdb_drop_cache(st);
		pthread_mutex_unlock(&st->cache_lock);
		mdb_drop_models(st);
		st->released = 1;
	}
	pthread_mutex_unlock(&st->data_lock);
	pthread_mutex_unlock(&st->lock);
	return was_live;
}

/* mocapdb_release() → BOOLEAN: true when this call released the extension, false when it was
 * released before (a second call is harmless). */
static void release_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	bool *out = duckdb_vector_get_data(output);
	for (idx_t row = 0; row < n; row++) {
		out[row] = row == 0 && mdb_state_release(st);
	}
}

int mdb_register_release(duckdb_connection con, mdb_state *st) {
	duckdb_scalar_function f = duckdb_create_scalar_function();
	duckdb_scalar_function_set_name(f, "mocapdb_release");
	duckdb_logical_type b = duckdb_create_logical_type(DUCKDB_TYPE_BOOLEAN);
	duckdb_scalar_function_set_return_type(f, b);
	/* it changes the extension's state: run at execution, once per row, never folded at planning */
	duckdb_scalar_function_set_volatile(f);
	duckdb_scalar_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_scalar_function_set_function(f, release_fn);
	int rc = duckdb_register_scalar_function(con, f) == DuckDBError ? -1 : 0;
	duckdb_destroy_logical_type(&b);
	duckdb_destroy_scalar_function(&f);
	return rc;
}
