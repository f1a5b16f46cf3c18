/* The chain search of C_KeyframeSearch.c as KEYFRAMES.md §5 describes it, with the
 * same per-keyframe pointers (reset per document, moved back by one interval after
 * a scan that found something), so hits come out in the toolbox's order and the
 * segments equal mocapdb.keyframes.search_kernels._chain_scan_kernel's. The
 * recursion runs as an explicit loop over levels: K is at most MDB_MAX_KEYFRAMES
 * only by the callers' checks, so the per-level arrays are allocated here. */
#include "chain.h"

#include <stdlib.h>

void mdb_spans_free(mdb_spans *s) {
	free(s->start);
	free(s->end);
	s->start = s->end = NULL;
	s->n = s->cap = 0;
}

int mdb_spans_push(mdb_spans *s, int64_t start, int64_t end) {
	if (s->n == s->cap) {
		size_t cap = s->cap ? 2 * s->cap : 64;
		int64_t *a = realloc(s->start, cap * sizeof *a);
		if (!a) {
			return -1;
		}
		s->start = a;
		int64_t *b = realloc(s->end, cap * sizeof *b);
		if (!b) {
			return -1;
		}
		s->end = b;
		s->cap = cap;
	}
	s->start[s->n] = start;
	s->end[s->n] = end;
	s->n++;
	return 0;
}

static int64_t max64(int64_t a, int64_t b) {
	return a > b ? a : b;
}

static int64_t min64(int64_t a, int64_t b) {
	return a < b ? a : b;
}

/* A hit [h_s, h_e], widened, clamped and merged into the document's segments. */
static int emit(mdb_spans *out, size_t base, int64_t h_s, int64_t h_e, int64_t n_frames, int64_t ext_l,
                int64_t ext_r) {
	int64_t s = max64(h_s - ext_l, 0);
	int64_t e = min64(h_e + ext_r, n_frames - 1);
	if (out->n > base && s <= out->end[out->n - 1]) {
		/* the toolbox overwrites the end; max is the same for its non-decreasing hit ends */
		out->end[out->n - 1] = max64(out->end[out->n - 1], e);
		return 0;
	}
	return mdb_spans_push(out, s, e);
}

int mdb_chain_document(size_t K, const int64_t *iv_start, const int64_t *iv_end, const size_t *off,
                       const int64_t *d_min, const int64_t *d_max, int64_t n_frames, int64_t ext_l,
                       int64_t ext_r, mdb_spans *out) {
	size_t base = out->n;
	for (size_t k = 0; k < K; k++) {
		if (off[k] == off[k + 1]) {
			return 0; /* a keyframe without a match: no chain in this document */
		}
	}
	if (K == 1) { /* not defined by the toolbox: every interval is a hit */
		for (size_t p = off[0]; p < off[1]; p++) {
			if (emit(out, base, iv_start[p], iv_end[p], n_frames, ext_l, ext_r)) {
				return -1;
			}
		}
		return 0;
	}
	if (K > MDB_MAX_KEYFRAMES) {
		return -2; /* no mdb_query holds more */
	}
	/* on the stack: this runs per document and class, and a malloc each cost more than the search */
	size_t ptr[MDB_MAX_KEYFRAMES];
	int64_t xs[MDB_MAX_KEYFRAMES], xe[MDB_MAX_KEYFRAMES], lo[MDB_MAX_KEYFRAMES], hi[MDB_MAX_KEYFRAMES];
	char found[MDB_MAX_KEYFRAMES] = {0};
	for (size_t k = 1; k < K; k++) {
		ptr[k] = off[k];
	}
	for (size_t p0 = off[0]; p0 < off[1]; p0++) {
		xs[0] = iv_start[p0];
		xe[0] = iv_end[p0];
		/* enter level 1 with the range X_1 allows */
		size_t level = 1;
		lo[1] = xs[0] + d_min[0];
		hi[1] = xe[0] + d_max[0];
		while (ptr[1] < off[2] && lo[1] > iv_end[ptr[1]]) {
			ptr[1]++;
		}
		found[1] = 0;
		for (;;) {
			size_t k = level, p = ptr[k];
			if (p < off[k + 1] && hi[k] >= iv_start[p] && lo[k] <= iv_end[p]) {
				found[k] = 1;
				xs[k] = max64(iv_start[p], lo[k]);
				xe[k] = min64(iv_end[p], hi[k]);
				if (k < K - 1) { /* recurse into level k+1 */
					size_t nk = k + 1;
					lo[nk] = xs[k] + d_min[k];
					hi[nk] = xe[k] + d_max[k];
					while (ptr[nk] < off[nk + 1] && lo[nk] > iv_end[ptr[nk]]) {
						ptr[nk]++;
					}
					found[nk] = 0;
					level = nk;
					continue;
				}
				/* last keyframe: the hit from the leftmost feasible frame of keyframe 1 */
				ptr[k] = p + 1;
				int64_t h_s = xs[k];
				for (size_t g = K - 1; g-- > 0;) {
					int64_t js = max64(h_s - d_max[g], xs[g]);
					if (js > min64(h_s - d_min[g], xe[g])) {
						return -2;
					}
					h_s = js;
				}
				if (emit(out, base, h_s, xe[k], n_frames, ext_l, ext_r)) {
					return -1;
				}
				continue;
			}
			/* level k scanned: step back onto the last intersecting interval (the next,
			 * later range may reuse it) and let level k-1 move on */
			if (found[k]) {
				ptr[k]--;
			}
			if (--level == 0) {
				break;
			}
			ptr[level]++;
		}
	}
	return 0;
}
