/* The query plumbing archive.c keeps and model_read.c shares: queries on the main connection, the
 * caller holding st->lock. Internal to those two files (archive.h is the extension's interface). */
#ifndef MOCAPDB_ARCHIVE_ROWS_H
#define MOCAPDB_ARCHIVE_ROWS_H

#include "archive.h"

/* Column c of a chunk: its data and validity. */
#define COLUMN(chunk, c, type, data, valid)                                                                            \
	duckdb_vector data##_v = duckdb_data_chunk_get_vector(chunk, c);                                                   \
	type *data = duckdb_vector_get_data(data##_v);                                                                     \
	uint64_t *valid = duckdb_vector_get_validity(data##_v)

/* Run a query with text then integer parameters into res; 0, or -1 with err set (the table named
 * when it is missing). */
int mdb_run_query(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                  const int32_t *ints, idx_t n_ints, duckdb_result *res, mdb_error *err);
/* Run a query and hand its rows to sink after checking its columns' types; 0 or -1. */
int mdb_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
             const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink, void *ctx,
             mdb_error *err);
/* The error of an allocation that failed while reading what; -1. */
int mdb_out_of_memory(mdb_error *err, const char *what);
/* The first row's VARCHAR of a one-column result into buf ("" when NULL or none). */
void mdb_first_text(duckdb_result *res, char *buf, size_t size);

#endif
