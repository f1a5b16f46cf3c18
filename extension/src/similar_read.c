/* The archive's rows a query by example reads (similar_read.h), each with one query through the
 * extension's connection (archive.c's mdb_query_rows: under its lock, a missing table named with the
 * command that creates it). */
#include "similar_read.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "similar_plan.h"

DUCKDB_EXTENSION_EXTERN

#define WHAT MDB_SIM_WHAT
#define META_SQL "SELECT name, fps, n_frames FROM motions WHERE motion_id = $1"
#define BY_NAME_SQL "SELECT motion_id FROM motions WHERE name = $1 ORDER BY motion_id"
#define QUERY_WORDS_SQL "SELECT bits FROM features WHERE motion_id = $1 ORDER BY frame"
#define SAMPLE_SQL "SELECT bits FROM features WHERE frame % $1 = 0 ORDER BY motion_id, frame"
#define VERSION_SQL "SELECT version FROM mocap_index.state"
/* every motion's frames, and whether its feature rows are its frames 1 … n (one without them is not
 * ranked): mocapdb/sql/retrieval.sql's motion_lengths */
#define LENGTHS_SQL                                                                                                    \
	"SELECT m.motion_id, m.n_frames, coalesce(f.n = m.n_frames AND f.lo = 1 AND f.hi = m.n_frames, m.n_frames = 0) " \
	"FROM motions m LEFT JOIN (SELECT motion_id, count(*) AS n, min(frame) AS lo, max(frame) AS hi FROM features "    \
	"GROUP BY motion_id) f USING (motion_id) ORDER BY m.motion_id"
#define NO_INDEX                                                                                                       \
	WHAT ": this database has no keyframe index (mocap_index.postings); build it with `mocapdb create-index` "         \
	     "(mocapdb.api.create_index)"

/* ---------------------------------------------------------------------------------------------
 * reading */

void mdb_sim_motions_free(mdb_sim_motions *l) {
	free(l->id);
	free(l->len);
	memset(l, 0, sizeof *l);
}

static int ids_push(mdb_sim_motions *l, int32_t id, int64_t len) {
	if (l->n == l->cap) {
		size_t cap = l->cap ? 2 * l->cap : 256;
		if (mdb_grow(&l->id, sizeof *l->id, cap) || mdb_grow(&l->len, sizeof *l->len, cap)) {
			return -1;
		}
		l->cap = cap;
	}
	l->id[l->n] = id;
	l->len[l->n++] = len;
	return 0;
}

int mdb_sim_oom(mdb_error *err) {
	snprintf(err->text, sizeof err->text, WHAT ": out of memory");
	return -1;
}

static int ids_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	int32_t *id = duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 0));
	for (idx_t i = 0; i < n; i++) {
		if (ids_push(p, id[i], 0)) {
			return mdb_sim_oom(err);
		}
	}
	return 0;
}

/* the complete motions (LENGTHS_SQL), ascending */
static int lengths_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	duckdb_vector vc = duckdb_data_chunk_get_vector(chunk, 2);
	int32_t *id = duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 0));
	int32_t *len = duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 1));
	bool *complete = duckdb_vector_get_data(vc);
	uint64_t *valid = duckdb_vector_get_validity(vc);
	for (idx_t i = 0; i < n; i++) {
		if (duckdb_validity_row_is_valid(valid, i) && complete[i] && ids_push(p, id[i], len[i])) {
			return mdb_sim_oom(err);
		}
	}
	return 0;
}

static int words_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	mdb_sim_words *w = p;
	duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
	uint64_t *x = duckdb_vector_get_data(v);
	uint64_t *valid = duckdb_vector_get_validity(v);
	if (w->n + n > w->cap) {
		size_t cap = 2 * (w->n + n);
		if (mdb_grow(&w->w, sizeof *w->w, cap)) {
			return mdb_sim_oom(err);
		}
		w->cap = cap;
	}
	for (idx_t i = 0; i < n; i++) {
		w->w[w->n++] = duckdb_validity_row_is_valid(valid, i) ? x[i] : 0;
	}
	return 0;
}

typedef struct {
	char *name;
	double fps;
	int64_t n_frames;
	int found;
} meta;

static int meta_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	meta *m = p;
	if (n == 0 || m->found) {
		return 0;
	}
	m->name = mdb_string_at(duckdb_data_chunk_get_vector(chunk, 0), 0);
	m->fps = ((double *)duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 1)))[0];
	m->n_frames = ((int32_t *)duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 2)))[0];
	m->found = 1;
	return m->name ? 0 : mdb_sim_oom(err);
}

static int version_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	(void)err;
	duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
	if (n >= 1 && duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), 0)) {
		*(int *)p = 1;
	}
	return 0;
}

int mdb_sim_read_motions(mdb_state *st, mdb_sim_motions *out, mdb_error *err) {
	duckdb_type ltypes[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_BOOLEAN};
	return mdb_query_rows(st, LENGTHS_SQL, "motions", NULL, 0, NULL, 0, ltypes, 3, lengths_sink, out, err);
}

int mdb_sim_read_sample(mdb_state *st, int32_t step, mdb_sim_words *out, mdb_error *err) {
	duckdb_type wtype[] = {DUCKDB_TYPE_UBIGINT};
	return mdb_query_rows(st, SAMPLE_SQL, "features", NULL, 0, &step, 1, wtype, 1, words_sink, out, err);
}

int mdb_sim_check_index(mdb_state *st, mdb_error *err) {
	int has_version = 0;
	duckdb_type vtype[] = {DUCKDB_TYPE_BIGINT};
	if (mdb_query_rows(st, VERSION_SQL, "mocap_index.state", NULL, 0, NULL, 0, vtype, 1, version_sink, &has_version,
	                   err)) {
		return -1;
	}
	if (!has_version) {
		snprintf(err->text, sizeof err->text, "%s", NO_INDEX);
		return -1;
	}
	return 0;
}

/* one_motion: a name's one motion (all digits: an id) */
int mdb_sim_resolve_name(mdb_state *st, const char *name, int64_t *id, mdb_error *err) {
	size_t len = strlen(name);
	int digits = len > 0;
	for (size_t i = 0; i < len && digits; i++) {
		digits = name[i] >= '0' && name[i] <= '9';
	}
	if (digits) {
		*id = len > 10 ? -1 : strtoll(name, NULL, 10);
		if (*id < 0 || *id >= ((int64_t)1 << 31)) {
			snprintf(err->text, sizeof err->text, WHAT ": no motion '%s' in the database (see: SELECT motion_id, name "
			         "FROM motions)", name);
			return -1;
		}
		return 0;
	}
	mdb_sim_motions found = {0};
	duckdb_type want[] = {DUCKDB_TYPE_INTEGER};
	if (mdb_query_rows(st, BY_NAME_SQL, "motions", &name, 1, NULL, 0, want, 1, ids_sink, &found, err)) {
		return -1;
	}
	int rc = 0;
	if (found.n == 0) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": no motion '%s' in the database (see: SELECT motion_id, name FROM motions)", name);
		rc = -1;
	} else if (found.n > 1) {
		snprintf(err->text, sizeof err->text, WHAT ": '%s' names %zu motions (ids %d, %d%s); give the id", name,
		         found.n, found.id[0], found.id[1], found.n > 2 ? ", …" : "");
		rc = -1;
	} else {
		*id = found.id[0];
	}
	mdb_sim_motions_free(&found);
	return rc;
}

/* query_stretch and check_range: the motion's words first .. last (0-based inclusive) */
int mdb_sim_query_stretch(mdb_state *st, int64_t id, int has_first, int32_t first_frame, int has_last,
                          int32_t last_frame, int64_t *first, int64_t *last, mdb_sim_words *w, mdb_error *err) {
	meta m = {0};
	duckdb_type want[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_INTEGER};
	int32_t id32 = (int32_t)id;
	int rc = -1;
	if (id < 0 || id > INT32_MAX) {
		m.found = 0;
	} else if (mdb_query_rows(st, META_SQL, "motions", NULL, 0, &id32, 1, want, 3, meta_sink, &m, err)) {
		return -1;
	}
	if (!m.found) {
		if (id == MDB_SIM_BEYOND) {
			snprintf(err->text, sizeof err->text, WHAT ": no motion has that id (ids are 32-bit; see: SELECT "
			         "motion_id, name FROM motions)");
		} else {
			snprintf(err->text, sizeof err->text, WHAT ": no motion with id %" PRId64 " (see: SELECT motion_id, name "
			         "FROM motions)", id);
		}
		goto done;
	}
	int64_t n = m.n_frames;
	char where[300];
	snprintf(where, sizeof where, "motion %" PRId64 " ('%s') (%" PRId64 " frames at %g Hz, %.2f s)", id, m.name, n,
	         m.fps, (double)n / m.fps);
	*first = has_first ? (int64_t)first_frame - 1 : 0;
	*last = has_last ? (int64_t)last_frame - 1 : n - 1;
	if (*first < 0 || *last > n - 1) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": the range %" PRId64 "–%" PRId64 " lies outside %s; frames are 1-based, 1–%" PRId64, *first + 1,
		         *last + 1, where, n);
		goto done;
	}
	if (*last < *first) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": the range %" PRId64 "–%" PRId64 " of %s is empty; give start_frame <= end_frame", *first + 1,
		         *last + 1, where);
		goto done;
	}
	double seconds = (double)(*last - *first + 1) / m.fps;
	if (seconds < MDB_SIM_MIN_QUERY_S - 1e-9) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": the query stretch %" PRId64 "–%" PRId64 " of motion %" PRId64 " ('%s') is %" PRId64
		              " frame(s), %.2f s; a query needs at least %g s (%.0f frames at %g Hz): a shorter one is a few "
		              "words found everywhere, and every match would be as short",
		         *first + 1, *last + 1, id, m.name, *last - *first + 1, seconds, MDB_SIM_MIN_QUERY_S,
		         ceil(MDB_SIM_MIN_QUERY_S * m.fps - 1e-9), m.fps);
		goto done;
	}
	duckdb_type wtype[] = {DUCKDB_TYPE_UBIGINT};
	if (mdb_query_rows(st, QUERY_WORDS_SQL, "features", NULL, 0, &id32, 1, wtype, 1, words_sink, w, err)) {
		goto done;
	}
	if ((int64_t)w->n < *last + 1) {
		snprintf(err->text, sizeof err->text,
		         "motion %" PRId64 " (%s) has feature rows that are not its frames 1…n_frames: ingest or import it "
		         "again to repair it", id, m.name);
		goto done;
	}
	rc = 0;
done:
	free(m.name);
	return rc;
}
