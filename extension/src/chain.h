/* The keyframe-chain search of one document (KEYFRAMES.md §3-5): pure C over arrays,
 * no DuckDB. Frames are 0-based, interval and segment ends inclusive. */
#ifndef MOCAPDB_CHAIN_H
#define MOCAPDB_CHAIN_H

#include <stddef.h>
#include <stdint.h>

/* d_max of an unbounded gap: as mocapdb.keyframes.UNBOUNDED (1 << 62), so that
 * frame ± bound never overflows int64 */
#define MDB_UNBOUNDED ((int64_t)1 << 62)

/* most keyframes of a query (as mocapdb.extension.udfs.MAX_KEYFRAMES): bounds a search's memory */
#define MDB_MAX_KEYFRAMES 32

/* A keyframe query: K (mask, value) 40-bit keyframes (a frame matches iff word & mask == value),
 * the K-1 gap bounds, and the margins every hit is widened by. */
typedef struct {
	size_t K;
	uint64_t mask[MDB_MAX_KEYFRAMES], value[MDB_MAX_KEYFRAMES];
	int64_t d_min[MDB_MAX_KEYFRAMES], d_max[MDB_MAX_KEYFRAMES];
	int64_t ext_l, ext_r;
} mdb_query;

/* A growing list of (start, end) pairs. */
typedef struct {
	int64_t *start;
	int64_t *end;
	size_t n;
	size_t cap;
} mdb_spans;

void mdb_spans_free(mdb_spans *s);
/* Append one pair; 0 on success, -1 when out of memory. */
int mdb_spans_push(mdb_spans *s, int64_t start, int64_t end);

/* Segments of one document holding the chain of K keyframes, appended to `out`.
 *
 * Keyframe k's matching frames are the disjoint, sorted intervals
 * iv_start/iv_end[off[k] .. off[k+1]); d_min/d_max (K-1 each) bound the frame
 * distance between consecutive keyframes; every hit is widened by ext_l/ext_r,
 * clamped to 0 .. n_frames-1, and merged with the segment before it when they
 * overlap (only segments appended by this call are merged with).
 * Returns 0, -1 when out of memory, -2 on an inconsistent chain (the
 * toolbox's "illegal interval", impossible for valid input; or more than MDB_MAX_KEYFRAMES). */
int mdb_chain_document(size_t K, const int64_t *iv_start, const int64_t *iv_end, const size_t *off,
                       const int64_t *d_min, const int64_t *d_max, int64_t n_frames, int64_t ext_l,
                       int64_t ext_r, mdb_spans *out);

#endif
