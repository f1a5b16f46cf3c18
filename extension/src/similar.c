/* similar_to(motion, first_frame, last_frame, k): query by example, the stretches of every motion most
 * like frames first_frame .. last_frame of a motion (1-based inclusive at 30 Hz; NULL: its first or
 * last frame), k of them, as LIST(STRUCT(rank, motion_id, start_frame, end_frame, cost)), ranked by
 * cost, none overlapping another or the query: what the Python UDF (mocapdb.storage.retrieval.
 * search_archive) returns, bit for bit (similar_plan.c, similar_rank.c say why).
 *
 * The motion is an id (any integer type) or a name (text; all digits: an id), the argument declared
 * ANY so that no cast turns '86_09' into 8609 or 3.7 into 4. The query stretch and an archive sample
 * (every step-th frame, step = frames // 16384) come from `features`, the archive's words from the
 * keyframe index's `full` runs, a batch of motions (≤ 10⁶ frames) at a time, as the Python side
 * reads them: memory follows the batch. An archive too large to rank whole within the cell budget
 * is preselected with keyframes taken from the query (similar_plan.c), each batch within its share. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"
#include "functions.h"
#include "similar_plan.h"
#include "similar_rank.h"

DUCKDB_EXTENSION_EXTERN

#define WHAT "similar_to"
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

typedef struct {
	int32_t *id;
	int64_t *len;
	size_t n, cap;
} id_list;

static void ids_free(id_list *l) {
	free(l->id);
	free(l->len);
	memset(l, 0, sizeof *l);
}

static int ids_push(id_list *l, int32_t id, int64_t len) {
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

static int oom(mdb_error *err) {
	snprintf(err->text, sizeof err->text, WHAT ": out of memory");
	return -1;
}

static int ids_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	int32_t *id = duckdb_vector_get_data(duckdb_data_chunk_get_vector(chunk, 0));
	for (idx_t i = 0; i < n; i++) {
		if (ids_push(p, id[i], 0)) {
			return oom(err);
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
			return oom(err);
		}
	}
	return 0;
}

typedef struct {
	uint64_t *w;
	size_t n, cap;
} words;

static int words_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	words *w = p;
	duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
	uint64_t *x = duckdb_vector_get_data(v);
	uint64_t *valid = duckdb_vector_get_validity(v);
	if (w->n + n > w->cap) {
		size_t cap = 2 * (w->n + n);
		if (mdb_grow(&w->w, sizeof *w->w, cap)) {
			return oom(err);
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
	return m->name ? 0 : oom(err);
}

static int version_sink(void *p, duckdb_data_chunk chunk, idx_t n, mdb_error *err) {
	(void)err;
	duckdb_vector v = duckdb_data_chunk_get_vector(chunk, 0);
	if (n >= 1 && duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), 0)) {
		*(int *)p = 1;
	}
	return 0;
}

/* ---------------------------------------------------------------------------------------------
 * the query */

/* an integer id beyond int64: no motion has it */
#define BEYOND INT64_MIN

/* the motion argument of a row: an id (*id, 1; BEYOND for an integer beyond int64), a
 * name (*name, 2), NULL (0), another type (-1) */
static int motion_arg(duckdb_vector v, duckdb_type type, idx_t row, int64_t *id, char **name) {
	if (!duckdb_validity_row_is_valid(duckdb_vector_get_validity(v), row)) {
		return 0;
	}
	void *d = duckdb_vector_get_data(v);
	switch (type) {
	case DUCKDB_TYPE_TINYINT: *id = ((int8_t *)d)[row]; return 1;
	case DUCKDB_TYPE_SMALLINT: *id = ((int16_t *)d)[row]; return 1;
	case DUCKDB_TYPE_INTEGER: *id = ((int32_t *)d)[row]; return 1;
	case DUCKDB_TYPE_BIGINT: *id = ((int64_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UTINYINT: *id = ((uint8_t *)d)[row]; return 1;
	case DUCKDB_TYPE_USMALLINT: *id = ((uint16_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UINTEGER: *id = ((uint32_t *)d)[row]; return 1;
	case DUCKDB_TYPE_UBIGINT: {
		uint64_t x = ((uint64_t *)d)[row];
		*id = x > INT64_MAX ? BEYOND : (int64_t)x;
		return 1;
	}
	case DUCKDB_TYPE_HUGEINT: {
		duckdb_hugeint x = ((duckdb_hugeint *)d)[row];
		if (x.upper == 0 && x.lower <= INT64_MAX) {
			*id = (int64_t)x.lower;
		} else if (x.upper == -1 && x.lower > INT64_MAX) {
			*id = (int64_t)x.lower; /* a negative int64 */
		} else {
			*id = BEYOND;
		}
		return 1;
	}
	case DUCKDB_TYPE_UHUGEINT: {
		duckdb_uhugeint x = ((duckdb_uhugeint *)d)[row];
		*id = (x.upper == 0 && x.lower <= INT64_MAX) ? (int64_t)x.lower : BEYOND;
		return 1;
	}
	case DUCKDB_TYPE_VARCHAR: *name = mdb_string_at(v, row); return *name ? 2 : -2;
	default: return -1;
	}
}

/* one_motion: a name's one motion (all digits: an id) */
static int resolve_name(mdb_state *st, const char *name, int64_t *id, mdb_error *err) {
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
	id_list found = {0};
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
	ids_free(&found);
	return rc;
}

/* query_stretch and check_range: the motion's words first .. last (0-based inclusive) */
static int query_stretch(mdb_state *st, int64_t id, int has_first, int32_t first_frame, int has_last,
                         int32_t last_frame, int64_t *first, int64_t *last, words *w, mdb_error *err) {
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
		if (id == BEYOND) {
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
		         "motion %" PRId64 " has feature rows that are not its frames 1…n_frames: ingest or import it again to "
		         "repair it", id);
		goto done;
	}
	rc = 0;
done:
	free(m.name);
	return rc;
}

/* A batch of motions' words, rebuilt from the index's full runs. */
typedef struct {
	const uint64_t *words;
	const int64_t *off; /* batch motion k at words + off[k] */
} batch_words;

static int fetch_words(void *p, const int64_t *doc, const int64_t *start, const int64_t *stop, size_t n, uint64_t *out) {
	const batch_words *b = p;
	for (size_t k = 0; k < n; k++) {
		size_t len = (size_t)(stop[k] - start[k]);
		if (len) {
			memcpy(out, b->words + b->off[doc[k]] + start[k], len * sizeof *out);
			out += len;
		}
	}
	return 0;
}

typedef struct {
	int64_t *doc, *start, *stop;
	size_t n, cap;
} segments;

static void segments_free(segments *s) {
	free(s->doc);
	free(s->start);
	free(s->stop);
	memset(s, 0, sizeof *s);
}

static int segments_reserve(segments *s, size_t n) {
	if (n <= s->cap) {
		return 0;
	}
	if (mdb_grow(&s->doc, sizeof *s->doc, n) || mdb_grow(&s->start, sizeof *s->start, n) ||
	    mdb_grow(&s->stop, sizeof *s->stop, n)) {
		return -1;
	}
	s->cap = n;
	return 0;
}

/* keyframe_search of one level on the batch's motions (runs ra[k] .. ra[k+1] each): merged,
 * widened segments in (doc, start) order; its frames in *frames */
static int level_segments(const mdb_query *q, const mdb_runs *runs, const size_t *ra, const int64_t *len, size_t m,
                          segments *out, int64_t *frames, mdb_error *err) {
	mdb_spans iv = {0}, hits = {0};
	size_t off[MDB_MAX_KEYFRAMES + 1];
	int rc = 0;
	out->n = 0;
	*frames = 0;
	for (size_t k = 0; k < m && rc == 0; k++) {
		if (ra[k] == ra[k + 1] || len[k] <= 0) {
			continue;
		}
		iv.n = 0;
		hits.n = 0;
		off[0] = 0;
		int absent = 0;
		for (size_t j = 0; j < q->K && rc == 0 && !absent; j++) {
			rc = mdb_keyframe_intervals(runs, ra[k], ra[k + 1], q->mask[j], q->value[j], &iv);
			off[j + 1] = iv.n;
			absent = off[j + 1] == off[j];
		}
		if (rc == 0 && !absent) {
			rc = mdb_chain_document(q->K, iv.start, iv.end, off, q->d_min, q->d_max, len[k], q->ext_l, q->ext_r, &hits);
		}
		if (rc == 0 && segments_reserve(out, out->n + hits.n)) {
			rc = -1;
		}
		for (size_t i = 0; rc == 0 && i < hits.n; i++) {
			out->doc[out->n] = (int64_t)k;
			out->start[out->n] = hits.start[i];
			out->stop[out->n++] = hits.end[i] + 1;
			*frames += hits.end[i] - hits.start[i] + 1;
		}
	}
	mdb_spans_free(&iv);
	mdb_spans_free(&hits);
	if (rc == -2) {
		snprintf(err->text, sizeof err->text, WHAT ": illegal interval in the reconstruction of a keyframe hit");
	} else if (rc) {
		oom(err);
	}
	return rc;
}

/* One batch of motions ids[a .. b): its words from the index, preselected or whole, ranked. */
static int search_batch(mdb_state *st, const id_list *motions, size_t a, size_t b, int64_t n_frames,
                        int64_t budget, const mdb_sim_ranker *r, const mdb_query *levels, int n_levels, int64_t q_id, int64_t q_first,
                        int64_t q_last, int64_t limit, mdb_sim_hits *found, mdb_error *err) {
	size_t m = b - a;
	int rc = -1;
	mdb_batch *batch = mdb_acquire_runs(st, motions->id[a], motions->id[b - 1], err);
	int64_t *off = malloc((m + 1) * sizeof *off);
	size_t *ra = malloc((m + 1) * sizeof *ra);
	uint64_t *w = NULL;
	segments segs = {0};
	mdb_sim_hits hits = {0};
	if (!batch) {
		goto done;
	}
	if (!off || !ra) {
		oom(err);
		goto done;
	}
	const mdb_runs *runs = &batch->runs;
	off[0] = 0;
	for (size_t k = 0; k < m; k++) {
		off[k + 1] = off[k] + motions->len[a + k];
	}
	w = malloc((size_t)(off[m] ? off[m] : 1) * sizeof *w);
	if (!w) {
		oom(err);
		goto done;
	}
	/* each motion's words from its runs, which tile it */
	size_t i = 0;
	for (size_t k = 0; k < m; k++) {
		int32_t id = motions->id[a + k];
		while (i < runs->n && runs->motion[i] < id) {
			i++; /* a motion not ranked (no complete feature rows) */
		}
		ra[k] = i;
		int64_t f = 0;
		while (i < runs->n && runs->motion[i] == id) {
			if (runs->start[i] != f || f + runs->len[i] > motions->len[a + k]) {
				break;
			}
			for (int64_t j = 0; j < runs->len[i]; j++) {
				w[off[k] + f + j] = runs->word[i];
			}
			f += runs->len[i];
			i++;
		}
		if (f != motions->len[a + k] || (i < runs->n && runs->motion[i] == id)) {
			snprintf(err->text, sizeof err->text,
			         WHAT ": the keyframe index does not hold motion %d as its features do; rebuild it with `mocapdb "
			              "create-index`",
			         id);
			goto done;
		}
	}
	ra[m] = i;
	int64_t batch_frames = off[m];
	if (n_levels == 0) {
		if (segments_reserve(&segs, m)) {
			oom(err);
			goto done;
		}
		for (size_t k = 0; k < m; k++) {
			segs.doc[k] = (int64_t)k;
			segs.start[k] = 0;
			segs.stop[k] = motions->len[a + k];
		}
		segs.n = m;
	} else {
		/* preselect(force=True): the most lenient level within the batch's share of the budget, else
		 * the strictest; the share int(CELL_BUDGET · frames / n_frames), a correctly rounded quotient
		 * (exact operands below 2^53) truncated as Python's int() does */
		int64_t share = (int64_t)((double)(budget * batch_frames) / (double)n_frames);
		for (int l = 0; l < n_levels; l++) {
			int64_t frames;
			if (level_segments(&levels[l], runs, ra, motions->len + a, m, &segs, &frames, err)) {
				goto done;
			}
			if (mdb_sim_rank_cells(frames, r->t->K) <= share) {
				break;
			}
		}
	}
	int64_t ex_doc = -1;
	for (size_t k = 0; k < m; k++) {
		if (motions->id[a + k] == q_id) {
			ex_doc = (int64_t)k;
		}
	}
	batch_words bw = {w, off};
	int s = mdb_sim_search_segments(r, fetch_words, &bw, segs.doc, segs.start, segs.stop, segs.n, ex_doc, q_first,
	                                q_last, limit, &hits);
	if (s) {
		oom(err);
		goto done;
	}
	for (size_t h = 0; h < hits.n; h++) {
		mdb_sim_hit x = hits.at[h];
		x.doc = motions->id[a + (size_t)x.doc];
		if (mdb_sim_hits_push(found, x)) {
			oom(err);
			goto done;
		}
	}
	mdb_sim_hits_best(found, limit);
	rc = 0;
done:
	if (batch) {
		mdb_release_runs(st, batch);
	}
	free(off);
	free(ra);
	free(w);
	segments_free(&segs);
	mdb_sim_hits_free(&hits);
	return rc;
}

/* CELL_BUDGET: MOCAPDB_CELL_BUDGET when a positive integer below 2^31 (as mocapdb.retrieval.search
 * reads it) */
static int64_t cell_budget(void) {
	const char *text = getenv("MOCAPDB_CELL_BUDGET");
	if (!text) {
		return MDB_SIM_CELL_BUDGET;
	}
	while (*text == ' ' || *text == '\t' || *text == '\n') {
		text++;
	}
	int64_t v = 0;
	const char *p = text;
	for (; *p >= '0' && *p <= '9' && v <= INT32_MAX; p++) {
		v = 10 * v + (*p - '0');
	}
	while (*p == ' ' || *p == '\t' || *p == '\n') {
		p++;
	}
	/* below 2^31: budget · frames stays below 2^53 for batches of up to 2^22 frames (exact) */
	return *text == 0 ? MDB_SIM_CELL_BUDGET : (*p == 0 && p > text && v > 0 && v <= INT32_MAX ? v : MDB_SIM_CELL_BUDGET);
}

/* search_archive for one query stretch: the best limit hits of the archive, doc = motion id */
static int search_archive(mdb_state *st, int64_t q_id, int64_t q_first, const uint64_t *q_words, size_t K,
                          int64_t limit, mdb_sim_hits *found, mdb_error *err) {
	id_list motions = {0};
	words sample = {0};
	mdb_sim_template t = {0}, sparse = {0};
	mdb_query levels[MDB_SIM_LEVELS];
	int n_levels = 0, has_version = 0, rc = -1;
	int64_t budget = cell_budget();
	duckdb_type vtype[] = {DUCKDB_TYPE_BIGINT};
	if (mdb_query_rows(st, VERSION_SQL, "mocap_index.state", NULL, 0, NULL, 0, vtype, 1, version_sink, &has_version,
	                   err)) {
		goto done;
	}
	if (!has_version) {
		snprintf(err->text, sizeof err->text, "%s", NO_INDEX);
		goto done;
	}
	duckdb_type ltypes[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_BOOLEAN};
	if (mdb_query_rows(st, LENGTHS_SQL, "motions", NULL, 0, NULL, 0, ltypes, 3, lengths_sink, &motions, err)) {
		goto done;
	}
	int64_t n_frames = 0;
	for (size_t k = 0; k < motions.n; k++) {
		n_frames += motions.len[k];
	}
	if (n_frames == 0) {
		snprintf(err->text, sizeof err->text, WHAT ": the archive is empty: ingest motions first");
		goto done;
	}
	int64_t step = n_frames / MDB_SIM_SAMPLE_FRAMES;
	int32_t step32 = (int32_t)(step > 1 ? step : 1);
	duckdb_type wtype[] = {DUCKDB_TYPE_UBIGINT};
	if (mdb_query_rows(st, SAMPLE_SQL, "features", NULL, 0, &step32, 1, wtype, 1, words_sink, &sample, err)) {
		goto done;
	}
	if (sample.n == 0) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": the archive sample must be a non-empty 1-D array of words (an empty archive?)");
		goto done;
	}
	int64_t counts[MDB_SIM_FEATURES] = {0};
	for (size_t j = 0; j < sample.n; j++) {
		for (int f = 0; f < MDB_SIM_FEATURES; f++) {
			counts[f] += (int64_t)((sample.w[j] >> f) & 1);
		}
	}
	double p_on[MDB_SIM_FEATURES];
	mdb_sim_frequencies(counts, (int64_t)sample.n, p_on);
	if (mdb_sim_clip_template(q_words, K, p_on, &t)) {
		oom(err);
		goto done;
	}
	double chance = mdb_sim_chance(&t, p_on);
	mdb_sim_ranker r = {&t, NULL, mdb_sim_coarse_step(K), MDB_SIM_TAU_FACTOR * chance};
	if (r.step > 1) {
		if (mdb_sim_sparse_template(&t, r.step, &sparse)) {
			oom(err);
			goto done;
		}
		r.sparse = &sparse;
	}
	/* the archive within the budget: no preselection, and no keyframes to take from the query */
	if (mdb_sim_rank_cells(n_frames, K) > budget) {
		n_levels = mdb_sim_keyframes(&t, sample.w, sample.n, levels);
		if (n_levels < 0) {
			oom(err);
			goto done;
		}
	}
	/* frame_batches: consecutive motions of at most MDB_BATCH_FRAMES frames (a longer one alone) */
	size_t a = 0;
	while (a < motions.n) {
		size_t b = a + 1;
		int64_t frames = motions.len[a];
		while (b < motions.n && frames + motions.len[b] <= MDB_BATCH_FRAMES) {
			frames += motions.len[b++];
		}
		if (search_batch(st, &motions, a, b, n_frames, budget, &r, levels, n_levels, q_id, q_first,
		                 q_first + (int64_t)K - 1, limit, found, err)) {
			goto done;
		}
		a = b;
	}
	rc = 0;
done:
	ids_free(&motions);
	free(sample.w);
	mdb_sim_template_free(&t);
	mdb_sim_template_free(&sparse);
	return rc;
}

/* ---------------------------------------------------------------------------------------------
 * the SQL function */

static const char *type_name(duckdb_type t) {
	switch (t) {
	case DUCKDB_TYPE_BOOLEAN: return "BOOLEAN";
	case DUCKDB_TYPE_FLOAT: return "FLOAT";
	case DUCKDB_TYPE_DOUBLE: return "DOUBLE";
	case DUCKDB_TYPE_DECIMAL: return "DECIMAL";
	case DUCKDB_TYPE_DATE: return "DATE";
	case DUCKDB_TYPE_TIMESTAMP: return "TIMESTAMP";
	case DUCKDB_TYPE_BLOB: return "BLOB";
	case DUCKDB_TYPE_LIST: return "a LIST";
	case DUCKDB_TYPE_STRUCT: return "a STRUCT";
	default: return "another type";
	}
}

static int write_hits(duckdb_vector output, const mdb_sim_hits *h, idx_t row, size_t *total) {
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	duckdb_vector child = duckdb_list_vector_get_child(output);
	if (duckdb_list_vector_reserve(output, *total + h->n) == DuckDBError) {
		return -1;
	}
	int32_t *rank = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 0));
	int32_t *motion = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 1));
	int32_t *start = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 2));
	int32_t *end = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 3));
	double *cost = duckdb_vector_get_data(duckdb_struct_vector_get_child(child, 4));
	for (size_t i = 0; i < h->n; i++) {
		size_t o = *total + i;
		rank[o] = (int32_t)(i + 1);
		motion[o] = (int32_t)h->at[i].doc;
		start[o] = (int32_t)(h->at[i].start + 1);
		end[o] = (int32_t)(h->at[i].end + 1);
		cost[o] = h->at[i].cost;
	}
	entries[row].offset = *total;
	entries[row].length = h->n;
	*total += h->n;
	duckdb_list_vector_set_size(output, *total);
	return 0;
}

/* one row: its arguments checked, the query stretch read, the archive searched */
static int similar_row(mdb_state *st, duckdb_data_chunk input, idx_t row, mdb_sim_hits *hits, mdb_error *err) {
	duckdb_vector v_motion = duckdb_data_chunk_get_vector(input, 0);
	duckdb_vector v_first = duckdb_data_chunk_get_vector(input, 1), v_last = duckdb_data_chunk_get_vector(input, 2);
	duckdb_vector v_k = duckdb_data_chunk_get_vector(input, 3);
	duckdb_logical_type lt = duckdb_vector_get_column_type(v_motion);
	duckdb_type type = duckdb_get_type_id(lt);
	duckdb_destroy_logical_type(&lt);
	int k_valid = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_k), row);
	int32_t k = k_valid ? ((int32_t *)duckdb_vector_get_data(v_k))[row] : 0;
	if (!k_valid || k < 1) {
		if (k_valid) {
			snprintf(err->text, sizeof err->text, WHAT ": k must be a positive integer, got %d", k);
		} else {
			snprintf(err->text, sizeof err->text, WHAT ": k must be a positive integer, got NULL");
		}
		return -1;
	}
	int64_t id = -1;
	char *name = NULL;
	int kind = motion_arg(v_motion, type, row, &id, &name);
	if (kind == 0) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": no motion with id NULL (see: SELECT motion_id, name FROM motions)");
		return -1;
	}
	if (kind == -2) {
		return oom(err);
	}
	if (kind == -1) {
		snprintf(err->text, sizeof err->text,
		         WHAT ": motion must be a motion id (an integer) or a name, got %s (cast it to one)", type_name(type));
		return -1;
	}
	if (kind == 2) {
		int rc = resolve_name(st, name, &id, err);
		free(name);
		if (rc) {
			return -1;
		}
	}
	int has_first = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_first), row);
	int has_last = duckdb_validity_row_is_valid(duckdb_vector_get_validity(v_last), row);
	int32_t first_frame = has_first ? ((int32_t *)duckdb_vector_get_data(v_first))[row] : 0;
	int32_t last_frame = has_last ? ((int32_t *)duckdb_vector_get_data(v_last))[row] : 0;
	int64_t first, last;
	words w = {0};
	int rc = query_stretch(st, id, has_first, first_frame, has_last, last_frame, &first, &last, &w, err);
	if (rc == 0) {
		hits->n = 0;
		rc = search_archive(st, id, first, w.w + first, (size_t)(last - first + 1), k, hits, err);
	}
	free(w.w);
	return rc;
}

static void similar_fn(duckdb_function_info info, duckdb_data_chunk input, duckdb_vector output) {
	mdb_state *st = duckdb_scalar_function_get_extra_info(info);
	idx_t n = duckdb_data_chunk_get_size(input);
	duckdb_list_entry *entries = duckdb_vector_get_data(output);
	mdb_error err = {{0}};
	mdb_sim_hits hits = {0};
	size_t total = 0;
	int failed = mdb_check_live(st, &err);
	for (idx_t row = 0; row < n; row++) {
		entries[row].offset = 0;
		entries[row].length = 0;
	}
	for (idx_t row = 0; row < n && !failed; row++) {
		failed = similar_row(st, input, row, &hits, &err);
		if (!failed && write_hits(output, &hits, row, &total)) {
			failed = oom(&err);
		}
	}
	mdb_sim_hits_free(&hits);
	if (failed) {
		duckdb_scalar_function_set_error(info, err.text);
	}
}

static duckdb_logical_type result_type(void) {
	const char *names[] = {"rank", "motion_id", "start_frame", "end_frame", "cost"};
	duckdb_type ids[] = {DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_INTEGER,
	                     DUCKDB_TYPE_DOUBLE};
	duckdb_logical_type members[5];
	for (size_t i = 0; i < 5; i++) {
		members[i] = duckdb_create_logical_type(ids[i]);
	}
	duckdb_logical_type s = duckdb_create_struct_type(members, names, 5);
	for (size_t i = 0; i < 5; i++) {
		duckdb_destroy_logical_type(&members[i]);
	}
	duckdb_logical_type list = duckdb_create_list_type(s);
	duckdb_destroy_logical_type(&s);
	return list;
}

int mdb_register_similar(duckdb_connection con, mdb_state *st) {
	duckdb_scalar_function f = duckdb_create_scalar_function();
	duckdb_scalar_function_set_name(f, "similar_to");
	duckdb_logical_type any = duckdb_create_logical_type(DUCKDB_TYPE_ANY);
	duckdb_logical_type i32 = duckdb_create_logical_type(DUCKDB_TYPE_INTEGER);
	duckdb_logical_type list = result_type();
	duckdb_scalar_function_add_parameter(f, any);
	for (int i = 0; i < 3; i++) {
		duckdb_scalar_function_add_parameter(f, i32);
	}
	duckdb_scalar_function_set_return_type(f, list);
	/* NULLs come in: a NULL range is the whole motion, a NULL motion or k an error */
	duckdb_scalar_function_set_special_handling(f);
	/* it reads the database: never folded into a constant at planning */
	duckdb_scalar_function_set_volatile(f);
	duckdb_scalar_function_set_extra_info(f, mdb_state_ref(st), mdb_state_unref);
	duckdb_scalar_function_set_function(f, similar_fn);
	int rc = duckdb_register_scalar_function(con, f) == DuckDBError ? -1 : 0;
	duckdb_destroy_logical_type(&any);
	duckdb_destroy_logical_type(&i32);
	duckdb_destroy_logical_type(&list);
	duckdb_destroy_scalar_function(&f);
	return rc;
}
