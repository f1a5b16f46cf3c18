/* Reading an archive written by `mocapdb ingest` through the extension's own
 * connection: the motions' lengths and a batch of motions' keyframe-index runs. */
#ifndef MOCAPDB_ARCHIVE_H
#define MOCAPDB_ARCHIVE_H

#include <pthread.h>
#include <stdint.h>

#include "chain.h"
#include "distance.h"
#include "duckdb_extension.h"

/* What a loaded extension keeps per database instance (the functions' extra info, never a
 * global: two databases of one process may each load it): connections of its own (opened at
 * LOAD; the C API hands the database out only then), the locks that serialise their use (a DuckDB
 * connection runs one query at a time) and the index cache. mocapdb_release() disconnects and
 * frees the cache (state.c); the struct itself goes with the last function holding it. */
/* Error text of the archive functions (set when they return non-zero). */
typedef struct {
	char text[512];
} mdb_error;

struct mdb_batch;
struct mdb_model_entry;

/* more than the distinct queries of archive.c */
#define MDB_MAX_PREPARED 24

/* A connection of the extension's own with its kept statements: each query of archive.c prepared
 * once on it (parsing and planning cost more than reading a model's rows) and kept by its text's
 * address; DuckDB re-binds a kept statement itself when the catalog changed, and a statement that
 * fails is prepared afresh once (run_query). A connection runs one query at a time: each has its
 * lock. */
typedef struct {
	duckdb_connection con;
	const char *sql[MDB_MAX_PREPARED];
	duckdb_prepared_statement stmt[MDB_MAX_PREPARED];
	size_t n_prepared;
} mdb_session;

typedef struct {
	/* two connections (opened at LOAD; the C API hands the database out only then), so that a call
	 * reads a batch's words while it reads its model: `main` (under lock) the models and whatever
	 * else (the index's runs among it), `data` (under data_lock) the motions and their words. A
	 * thread holding lock may take data_lock or cache_lock, never the other way round. */
	mdb_session main, data;
	pthread_mutex_t lock, data_lock;
	pthread_mutex_t cache_lock; /* the index cache's list and references (taken after lock) */
	struct mdb_batch *cache; /* index batches read, newest first (see mdb_acquire_runs) */
	struct mdb_model_entry *models; /* models read, newest first, under lock (model_cache.c) */
	size_t cache_bytes;
	int released;            /* mocapdb_release() ran (under both locks): the connections are gone */
	int refs;                /* the registered functions holding it (and LOAD while it runs) */
} mdb_state;

/* A new state holding one reference (LOAD's), or NULL when out of memory. */
mdb_state *mdb_state_new(void);
/* Another reference, for a function's extra info; mdb_state_unref is its destroy callback. */
mdb_state *mdb_state_ref(mdb_state *st);
void mdb_state_unref(void *st);
/* Destroy a session's kept prepared statements (the caller holds its lock). */
void mdb_drop_prepared(mdb_session *s);
/* Disconnect the extension's connection and free the cache; 1 when it did, 0 when done before. */
int mdb_state_release(mdb_state *st);
/* 0 while the extension's connections are open, else -1 with the error a released function gives
 * (the caller holds one of the locks). */
int mdb_state_live(mdb_state *st, mdb_error *err);
/* The same, taking the lock: for the functions' entry points. */
int mdb_check_live(mdb_state *st, mdb_error *err);
int mdb_register_release(duckdb_connection con, mdb_state *st);

/* The stored motions, ascending ids, with their 30 Hz frame counts. */
typedef struct {
	int32_t *id;
	int64_t *n_frames;
	double *fps; /* the rate of the frames (30) */
	size_t n;
} mdb_motions;

/* The 40-bit-word runs of a batch of motions, in (motion, run) order. */
typedef struct {
	int32_t *motion;
	uint64_t *word;
	int64_t *start; /* 0-based first frame */
	int64_t *len;
	size_t n;
	size_t cap;
} mdb_runs;

/* A batch of motions' runs as read at one index version, shared by the queries using it. */
typedef struct mdb_batch {
	int64_t version;
	int32_t lo, hi;
	mdb_runs runs;
	int refs;     /* queries holding it */
	int detached; /* no longer in the cache: freed by its last release */
	struct mdb_batch *next;
} mdb_batch;

/* A VARCHAR of a flat vector's row as a NUL-terminated copy (NULL when out of memory). */
char *mdb_string_at(duckdb_vector v, idx_t row);

void mdb_motions_free(mdb_motions *m);
/* The runs of motions lo .. hi (ids, inclusive) of the 'full' part of the index, in (motion,
 * run) order: from the cache while the index version is the same (a bounded number of bytes,
 * so memory stays flat in archive size), else read. NULL after an error. Give it back with
 * mdb_release_runs. */
mdb_batch *mdb_acquire_runs(mdb_state *st, int32_t lo, int32_t hi, mdb_error *err);
void mdb_release_runs(mdb_state *st, mdb_batch *b);
/* Drop every cached batch (the caller holds cache_lock; those in use go when released). */
void mdb_drop_cache(mdb_state *st);
void mdb_runs_free(mdb_runs *r);

/* A class's quantized template of a model, prepared for mdb_mt_distance. An unknown model or
 * class is an error naming it and what the database has. */
int mdb_read_template(mdb_state *st, const char *model, const char *cls, mdb_template *out, mdb_error *err);
/* A class's stored keyframe query (keyframes, keyframe_queries), widened by the annotation margins
 * 2·(pos_1 - 1) and 2·(L - pos_K) when extend. An unknown model or class, or a class without a
 * query, is an error naming it. */
int mdb_read_keyframe_query(mdb_state *st, const char *model, const char *cls, int extend, mdb_query *out,
                            mdb_error *err);
/* the first index of the ascending a[0 .. n) that is >= x */
size_t mdb_lower_bound(const int32_t *a, size_t n, int32_t x);
/* The stored motions with ids lo .. hi, ascending, with their frame counts. */
int mdb_read_motion_range(mdb_state *st, int32_t lo, int32_t hi, mdb_motions *out, mdb_error *err);
/* The packed 30 Hz words of the motions want[0 .. n_want) (ascending ids within lo .. hi, each of
 * n_frames[i] frames) into words + off[i] (off[n_want]: the words in all). A motion whose features
 * are not its frames 1 .. n, each once, is an error naming it. */
int mdb_read_words(mdb_state *st, int32_t lo, int32_t hi, const int32_t *want, const int64_t *n_frames,
                   const size_t *off, size_t n_want, uint64_t *words, mdb_error *err);


/* The words of a batch of stored motions, read with one query. */
typedef struct {
	int32_t *id; /* ascending */
	int64_t *n_frames;
	double *fps;
	size_t *off; /* motion k's words at words + off[k], off[n] words in all */
	size_t n, cap;
	uint64_t *words;
} mdb_words_batch;

void mdb_words_batch_free(mdb_words_batch *b);
/* The next batch of the ascending motion ids motion[*i .. n_items) (repeats allowed): consecutive
 * ids of at most max_frames frames in all, counting the stored motions between them (one id at
 * least), and the words of those that are stored. range: the stored motions from motion[0] to
 * motion[n_items - 1]; *m its first motion not yet passed. Advances *i and *m past the batch. */
int mdb_read_batch(mdb_state *st, const mdb_motions *range, size_t *m, const int32_t *motion, size_t n_items,
                   size_t *i, int64_t max_frames, mdb_words_batch *b, mdb_error *err);
/* mdb_read_batch in two steps: which motions (b's ids, lengths and room for the words), then their words. */
int mdb_plan_batch(const mdb_motions *range, size_t *m, const int32_t *motion, size_t n_items, size_t *i,
                   int64_t max_frames, mdb_words_batch *b, mdb_error *err);
int mdb_read_batch_words(mdb_state *st, mdb_words_batch *b, mdb_error *err);

/* Grow the array *pp to cap elements of elem bytes; 0, or -1 leaving it as it was. */
int mdb_grow(void *pp, size_t elem, size_t cap);

/* Where a query's rows go, a chunk of n at a time: 0 to go on, non-zero to stop (err set). */
typedef int (*mdb_chunk_sink)(void *ctx, duckdb_data_chunk chunk, idx_t n, mdb_error *err);
/* Run a query on the extension's connection under its lock, with text parameters, then integer
 * ones ($1, $2, … in that order), and hand its rows to sink once its columns have the types want;
 * 0, or -1 with err naming the table (a missing one with the command that creates it). */
int mdb_query_rows(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                   const int32_t *ints, idx_t n_ints, const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink,
                   void *ctx, mdb_error *err);

/* A stored model as annotation needs it: classes in class_id order with their template, τ,
 * minimum length and keyframe query (K = 0: none, margins of annotation applied); labels in
 * label_id order (the Δarg tie order) with whether each is concurrent and its confidence map;
 * the margin. */
typedef struct {
	size_t n_classes, n_labels;
	char **label;         /* per label */
	char *concurrent;     /* per label */
	int64_t *label_of;    /* per class: its label's index */
	double *tau;          /* per class */
	int64_t *min_frames;  /* per class */
	mdb_template *tpl;    /* per class */
	mdb_query *query;     /* per class */
	double margin;
	size_t *conf_n;       /* per label: steps of its confidence map (0: the raw score) */
	double **conf_cut, **conf_value; /* per label: the steps (mocapdb.annotation.ConfidenceMap) */
	int64_t **conf_min_length;       /* per label and step: its map's shortest segment */
	double **conf_length_weight;     /* per label and step: its map's weight of the length in the score */
	int64_t **conf_full_length;      /* per label and step: its map's length that counts in full */
	char **conf_length_product;      /* per label and step: its map's length multiplies the raw score */
} mdb_model;

void mdb_model_free(mdb_model *m);
/* Model `name` from the tables classes, models, templates, keyframes; an unknown model is an
 * error naming it and the stored ones. */
int mdb_read_model(mdb_state *st, const char *name, mdb_model *out, mdb_error *err);
/* The same, the caller holding lock. */
int mdb_read_model_locked(mdb_state *st, const char *name, mdb_model *out, mdb_error *err);
/* mdb_query_rows with text parameters only, the caller holding lock. */
int mdb_query_rows_locked(mdb_state *st, const char *sql, const char *table, const char *const *texts, idx_t n_texts,
                          const duckdb_type *want, idx_t n_cols, mdb_chunk_sink sink, void *ctx, mdb_error *err);

/* A model as a call uses it, kept between calls while its rows are the same (model_cache.c). */
typedef struct mdb_model_entry mdb_model_entry;
/* Model `name` as mdb_read_model reads it, from the kept ones when the rows it was read from are
 * unchanged (one query, cheaper than the read), else read; *out holds it until mdb_release_model.
 * 0, or -1 with mdb_read_model's error. */
int mdb_acquire_model(mdb_state *st, const char *name, mdb_model_entry **out, mdb_error *err);
const mdb_model *mdb_entry_model(const mdb_model_entry *e);
void mdb_release_model(mdb_state *st, mdb_model_entry *e);
/* Forget every kept model (the caller holds lock; those in use go when released). */
void mdb_drop_models(mdb_state *st);

#endif
