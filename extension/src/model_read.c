/* The models as the native functions read them: a class's template, its keyframe query, a whole
 * model (classes, templates, queries, confidence maps) in a few queries. archive.c holds the
 * motions, their words and the index, and the query plumbing both use (archive_rows.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "archive.h"
#include "archive_rows.h"

DUCKDB_EXTENSION_EXTERN

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
/* 41 feature bits (40 + the heading feature): a template column may fix no other */
#define FEATURE_BITS ((((uint64_t)1) << (MDB_N_COST - 1)) - 1)
/* more expanded columns than any template has (the longest are a few hundred) */
#define MAX_COLUMNS ((size_t)1 << 16)

/* ---------------------------------------------------------------------------------------------
 * models */

/* Why a model has no template for a class: the model or the class is unknown. */
static void unknown_class(mdb_state *st, const char *model, const char *cls, mdb_error *err) {
	duckdb_result res;
	char known[300];
	if (mdb_run_query(st, CLASSES_SQL, "classes", &model, 1, NULL, 0, &res, err)) {
		return;
	}
	mdb_first_text(&res, known, sizeof known);
	duckdb_destroy_result(&res);
	if (known[0]) {
		snprintf(err->text, sizeof err->text, "model '%s' has no class '%s'; its classes: %s", model, cls, known);
		return;
	}
	if (mdb_run_query(st, MODELS_SQL, "models", NULL, 0, NULL, 0, &res, err)) {
		return;
	}
	mdb_first_text(&res, known, sizeof known);
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
		if (mdb_grow(&c->mask, sizeof *c->mask, c->cap) || mdb_grow(&c->value, sizeof *c->value, c->cap) ||
		    mdb_grow(&c->weight, sizeof *c->weight, c->cap)) {
			return mdb_out_of_memory(err, "a template");
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
				return mdb_out_of_memory(err, "a model");
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
		mdb_out_of_memory(err, "a template");
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
	if (mdb_rows(st, TEMPLATE_SQL, "templates", key, 2, NULL, 0, want, 3, template_sink, &c, err) == 0) {
		rc = template_from_rows(st, model, cls, &c, out, err);
	}
	pthread_mutex_unlock(&st->lock);
	template_ctx_free(&c);
	return rc;
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
			if (mdb_rows(st, HAS_CLASS_SQL, "classes", key, 2, NULL, 0, count_type, 1, count_sink, &has_class,
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
	if (mdb_rows(st, QUERY_SQL, "keyframes", key, 2, NULL, 0, want, 6, query_sink, &c, err) == 0) {
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
		if (mdb_grow(&c->cls, sizeof *c->cls, c->cap) || mdb_grow(&m->label, sizeof *m->label, c->cap) ||
		    mdb_grow(&c->label_id, sizeof *c->label_id, c->cap) || mdb_grow(&m->tau, sizeof *m->tau, c->cap) ||
		    mdb_grow(&m->min_frames, sizeof *m->min_frames, c->cap) ||
		    mdb_grow(&m->concurrent, sizeof *m->concurrent, c->cap) || mdb_grow(&c->has_query, sizeof *c->has_query, c->cap)) {
			return mdb_out_of_memory(err, "a model");
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
			return mdb_out_of_memory(err, "a model");
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

/* calibrated confidence: a database from before it has no table confidence_maps (raw scores), one from
 * before the length entered the score no columns length_weight and full_length (the raw score alone),
 * one from before the length multiplied the match no column length_product (the length added): the
 * table's columns of the label and the three, 0 without the table */
#define HAS_MAPS_SQL                                                                                                   \
	"SELECT count(*) FROM duckdb_columns() WHERE table_name = 'confidence_maps' "                                     \
	"AND column_name IN ('label', 'length_weight', 'full_length', 'length_product') "                                 \
	"AND database_name = current_database() AND schema_name = current_schema()"
#define MAPS_SQL                                                                                                       \
	"SELECT label, cut, value, min_length, length_weight, full_length, length_product FROM confidence_maps "          \
	"WHERE model = $1 ORDER BY label, min_length, k"
#define MAPS_ADDED_SQL                                                                                                 \
	"SELECT label, cut, value, min_length, length_weight, full_length, false FROM confidence_maps WHERE model = $1 " \
	"ORDER BY label, min_length, k"
#define MAPS_RAW_SQL                                                                                                   \
	"SELECT label, cut, value, min_length, 0.0::DOUBLE, 90, false FROM confidence_maps WHERE model = $1 "             \
	"ORDER BY label, min_length, k"

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
	COLUMN(chunk, 4, double, weight, v4);
	COLUMN(chunk, 5, int32_t, full, v5);
	COLUMN(chunk, 6, bool, product, v6);
	for (idx_t i = 0; i < n; i++) {
		if (!duckdb_validity_row_is_valid(v0, i) || !duckdb_validity_row_is_valid(v1, i) ||
		    !duckdb_validity_row_is_valid(v2, i) || !duckdb_validity_row_is_valid(v3, i) ||
		    !duckdb_validity_row_is_valid(v4, i) || !duckdb_validity_row_is_valid(v5, i) ||
		    !duckdb_validity_row_is_valid(v6, i) || min_length[i] < 0 ||
		    !(isfinite(weight[i]) && weight[i] >= 0.0) || full[i] < 1) {
			c->bad = 1;
			return 1;
		}
		char *label = mdb_string_at(label_v, i);
		if (!label) {
			return mdb_out_of_memory(err, "a confidence map");
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
			if (mdb_grow(&m->conf_cut[p], sizeof **m->conf_cut, c->cap[p]) ||
			    mdb_grow(&m->conf_value[p], sizeof **m->conf_value, c->cap[p]) ||
			    mdb_grow(&m->conf_min_length[p], sizeof **m->conf_min_length, c->cap[p]) ||
			    mdb_grow(&m->conf_length_weight[p], sizeof **m->conf_length_weight, c->cap[p]) ||
			    mdb_grow(&m->conf_full_length[p], sizeof **m->conf_full_length, c->cap[p]) ||
			    mdb_grow(&m->conf_length_product[p], sizeof **m->conf_length_product, c->cap[p])) {
				return mdb_out_of_memory(err, "a confidence map");
			}
		}
		/* ConfidenceMap's rules, within a map (a label's steps of one min_length): finite ascending
		 * cuts, non-decreasing values in [0, 1], one length_weight, full_length and length_product */
		int same = k > 0 && m->conf_min_length[p][k - 1] == min_length[i];
		if (!isfinite(cut[i]) || !(value[i] >= 0.0 && value[i] <= 1.0) ||
		    (same && !(cut[i] > m->conf_cut[p][k - 1] && value[i] >= m->conf_value[p][k - 1] &&
		               weight[i] == m->conf_length_weight[p][k - 1] && full[i] == m->conf_full_length[p][k - 1] &&
		               (char)product[i] == m->conf_length_product[p][k - 1]))) {
			c->bad = 1;
			return 1;
		}
		m->conf_cut[p][k] = cut[i];
		m->conf_value[p][k] = value[i];
		m->conf_min_length[p][k] = min_length[i];
		m->conf_length_weight[p][k] = weight[i] + 0.0; /* -0.0 as 0.0, as ConfidenceMap keeps it */
		m->conf_full_length[p][k] = full[i];
		m->conf_length_product[p][k] = (char)product[i];
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
	m->conf_length_weight = calloc(L, sizeof *m->conf_length_weight);
	m->conf_full_length = calloc(L, sizeof *m->conf_full_length);
	m->conf_length_product = calloc(L, sizeof *m->conf_length_product);
	maps_ctx c = {m, calloc(L, sizeof(size_t)), 0};
	if (!m->conf_n || !m->conf_cut || !m->conf_value || !m->conf_min_length || !m->conf_length_weight ||
	    !m->conf_full_length || !m->conf_length_product || !c.cap) {
		free(c.cap);
		return mdb_out_of_memory(err, "a model");
	}
	duckdb_type count_type[] = {DUCKDB_TYPE_BIGINT};
	duckdb_type want[] = {DUCKDB_TYPE_VARCHAR, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_DOUBLE, DUCKDB_TYPE_INTEGER,
	                      DUCKDB_TYPE_DOUBLE,  DUCKDB_TYPE_INTEGER, DUCKDB_TYPE_BOOLEAN};
	int64_t has_maps = 0;
	int rc = 0;
	if (mdb_rows(st, HAS_MAPS_SQL, "duckdb_columns()", NULL, 0, NULL, 0, count_type, 1, count_sink, &has_maps,
	             err)) {
		rc = -1;
	} else if (has_maps) {
		rc = mdb_rows(st, has_maps == 4 ? MAPS_SQL : has_maps == 3 ? MAPS_ADDED_SQL : MAPS_RAW_SQL,
		              "confidence_maps", &name, 1, NULL, 0, want, 7, maps_sink, &c, err);
	}
	free(c.cap);
	if (c.bad) {
		snprintf(err->text, sizeof err->text,
		         "model '%s': its confidence_maps rows are damaged (NULLs, a label it lacks, cuts not ascending, "
		         "values not rising within [0, 1], a length_weight below 0 or a full_length below 1, or steps of "
		         "a map disagreeing on them or on length_product); train or install the model again",
		         name);
		rc = -1;
	}
	return rc;
}

void mdb_model_free(mdb_model *m) {
	for (size_t p = 0; m->conf_n && p < m->n_labels; p++) { /* the seven are allocated together */
		free(m->conf_cut ? m->conf_cut[p] : NULL);
		free(m->conf_value ? m->conf_value[p] : NULL);
		free(m->conf_min_length ? m->conf_min_length[p] : NULL);
		free(m->conf_length_weight ? m->conf_length_weight[p] : NULL);
		free(m->conf_full_length ? m->conf_full_length[p] : NULL);
		free(m->conf_length_product ? m->conf_length_product[p] : NULL);
	}
	free(m->conf_n);
	free(m->conf_cut);
	free(m->conf_value);
	free(m->conf_min_length);
	free(m->conf_length_weight);
	free(m->conf_full_length);
	free(m->conf_length_product);
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
		return mdb_out_of_memory(err, "a model");
	}
	for (size_t k = 0; k < n; k++) {
		qc[k].q = &out->query[k];
		any_query |= has_query[k];
	}
	by_class bt = {cls, n, (char *)tc, sizeof *tc, template_row, NULL, 0};
	by_class bq = {cls, n, (char *)qc, sizeof *qc, query_row, NULL, 0};
	if (mdb_rows(st, MODEL_TEMPLATES_SQL, "templates", &name, 1, NULL, 0, want_t, 4, by_class_sink, &bt, err) ||
	    (any_query &&
	     mdb_rows(st, MODEL_QUERIES_SQL, "keyframes", &name, 1, NULL, 0, want_q, 7, by_class_sink, &bq, err))) {
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
	int q = mdb_rows(st, MODEL_SQL, "classes", &name, 1, NULL, 0, want, 8, model_sink, &c, err);
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
		mdb_out_of_memory(err, "a model");
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
