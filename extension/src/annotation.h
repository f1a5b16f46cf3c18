/* The annotation chain of one motion after Δ (TEMPLATES.md §9.1, §10; issue 11's segment
 * filters): hit extraction into Δ̄^τ, the segmenter over per-label rows, the filters and the
 * confidence. Pure C over arrays, the twin of mocapdb.annotation.chain / postprocess, with the
 * same comparisons in the same order, so the segments and their doubles are the same. */
#ifndef MOCAPDB_ANNOTATION_H
#define MOCAPDB_ANNOTATION_H

#include <stddef.h>
#include <stdint.h>

/* A segment: label index, 0-based inclusive frames, cost (Δ̄^τ at its ends) and confidence. */
typedef struct {
	int64_t label, start, end;
	double cost, confidence;
} mdb_segment;

typedef struct {
	mdb_segment *at;
	size_t n, cap;
} mdb_segments;

void mdb_segments_free(mdb_segments *s);

/* How a model turns per-label rows into segments: per label whether it is concurrent
 * (annotated on its own beside the others), its minimum length and the frames it must win
 * (0: none); the margin (0: none); per label its confidence maps (conf_n steps in all, sorted by
 * (conf_min_length, cut): from score conf_cut[k] on, confidence conf_value[k], for segments of
 * at least conf_min_length[k] frames, the score of a segment of n frames, with l = min(n, F) / F,
 * raw · (1 + w · l) / (1 + w) where conf_length_product[k], else (raw + w · l) / (1 + w),
 * w = conf_length_weight[k], F = conf_full_length[k] (alike on a map's steps); 0 steps:
 * the raw score). */
typedef struct {
	size_t n_labels;
	const char *concurrent;
	const int64_t *min_frames;
	const int64_t *min_won;
	double margin;
	const size_t *conf_n;
	double *const *conf_cut, *const *conf_value;
	int64_t *const *conf_min_length;
	double *const *conf_length_weight;
	int64_t *const *conf_full_length;
	char *const *conf_length_product;
	const char *set; /* per label: whether its rows are set (NULL: all are); the others are +inf throughout,
	                  * never read */
} mdb_label_rules;

/* The candidates of mdb_classification_delta and the room to sort them: grown as slices need,
 * reused across calls (one per thread); zeros to start with. */
typedef struct {
	struct mdb_candidate *at, *tmp;
	size_t cap;
} mdb_hit_scratch;

void mdb_hit_scratch_free(mdb_hit_scratch *s);

/* Δ̄^τ of one slice (as _extract_hits_kernel without the hits): repeatedly the first minimum of Δ
 * over the frames no hit covers yet, while <= tau; its frames back to the path's start (starts,
 * relative to the slice) that have no value get its cost; +inf elsewhere. 1, or 0 when no Δ is
 * <= tau (+inf everywhere: cd is not written), or -1 when out of memory. */
int mdb_classification_delta(const double *delta, const int64_t *starts, size_t n, double tau, double *cd,
                             mdb_hit_scratch *scratch);

/* as mocapdb.annotation.postprocess.WON_FRACTION: a segment wins this share of its label's minimum */
#define MDB_WON_FRACTION (1.0 / 3.0)

/* Segments of one motion of n frames (chain._segment_labels, then drop_short_segments):
 * label_cd (n_labels rows of n, the label's Δ̄^τ; overwritten) and label_ratio (Δ̄^τ / τ, for the
 * confidence). Appended to out sorted by (label, start). 0, or -1 when out of memory. */
int mdb_label_segments(double *label_cd, const double *label_ratio, size_t n, const mdb_label_rules *rules,
                       mdb_segments *out);

#endif
