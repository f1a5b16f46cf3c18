/* Δ's DP over DP_LANES template rows at a time, for distance.c, which includes this file once per
 * vector width with DP_LANES, the function's name DP_FN and its target attributes DP_ATTR defined
 * (gcc's vector extensions: the widest the CPU runs in one instruction, chosen when called).
 *
 * Each lane does the scalar row loop's operations in the same order — the comparisons with strict
 * "<", the selects, the multiplication by the step weight and the addition — so every double is
 * the one the scalar loop gives. Row i of frame j reads only rows i-1 and i-2 of frames j-1 and j-2,
 * so the rows of a frame are independent. A column of the ring holds PAD rows of +inf above row 0
 * (the predecessors that do not exist) and room past row K-1 for a last vector: those rows cost 0
 * and hold values nothing reads. */
#define DP_CAT_(a, b) a##b
#define DP_CAT(a, b) DP_CAT_(a, b)
#define DP_VD DP_CAT(vd, DP_LANES)
#define DP_VI DP_CAT(vi, DP_LANES)

typedef double DP_VD __attribute__((vector_size(DP_LANES * sizeof(double))));
typedef int64_t DP_VI __attribute__((vector_size(DP_LANES * sizeof(int64_t))));

/* One frame's rows 1 .. K-1: p0/q0 the column of frame j (D, starts), p1/q1 of j-1, p2/q2 of
 * j-2, each at row 0; c the frame's costs. A row's predecessors are rows i-1 and i-2 of the
 * previous columns. Loaded as vectors starting there, each would straddle two of the vectors the
 * previous frame stored, and a load the CPU cannot forward from one store waits until both are
 * written — every frame, since frame j+1 reads what frame j just wrote. So the loads are the
 * stored vectors themselves (rows 1 + LANES·v, aligned, which the CPU forwards) and the
 * predecessor vectors are cut from two neighbours by a lane shuffle (below row 1: the +inf of PAD
 * and row 0); the same doubles. */
static inline __attribute__((always_inline)) void DP_CAT(dp_column, DP_LANES)(size_t K, const double *c, double *p0,
                                                                             const double *p1, const double *p2,
                                                                             int64_t *q0, const int64_t *q1,
                                                                             const int64_t *q2, const int with_starts) {
	const DP_VD zero = {0.0}, one = zero + 1.0, two = zero + 2.0, inf = zero + INFINITY;
	const DP_VI none = (DP_VI){0} - 1;
	/* lanes of [b, a] from LANES-1 (rows i-1 ..) and from LANES-2 (rows i-2 ..), b the vector below a */
	const DP_VI back1 = DP_BACK1, back2 = DP_BACK2;
	DP_VD b1 = inf, b2 = inf;   /* rows i-LANES .. i-1 of frames j-1, j-2 */
	DP_VI s1 = none, s2 = none; /* and their starts */
	b1[DP_LANES - 1] = p1[0];
	b2[DP_LANES - 1] = p2[0];
	if (with_starts) {
		s1[DP_LANES - 1] = q1[0];
		s2[DP_LANES - 1] = q2[0];
	}
	for (size_t i = 1; i < K; i += DP_LANES) { /* K: the rows to compute, 1 .. K-1 */
		DP_VD a1, a2, ci;
		memcpy(&a1, p1 + i, sizeof a1);
		memcpy(&a2, p2 + i, sizeof a2);
		DP_VD v0 = __builtin_shuffle(b1, a1, back1); /* (1, 1), weight 1 */
		DP_VD v1 = __builtin_shuffle(b2, a2, back1); /* (1, 2), weight 1 */
		DP_VD v2 = __builtin_shuffle(b1, a1, back2); /* (2, 1), weight 2 */
		b1 = a1;
		b2 = a2;
		memcpy(&ci, c + i, sizeof ci);
		DP_VI m1 = v1 < v0;
		DP_VD best = (DP_VD)SELECT(m1, (DP_VI)v1, (DP_VI)v0);
		DP_VI m2 = v2 < best;
		best = (DP_VD)SELECT(m2, (DP_VI)v2, (DP_VI)best);
		DP_VD bw = (DP_VD)SELECT(m2, (DP_VI)two, (DP_VI)one);
		DP_VD d = best + bw * ci;
		memcpy(p0 + i, &d, sizeof d);
		if (with_starts) {
			DP_VI u1, u2;
			memcpy(&u1, q1 + i, sizeof u1);
			memcpy(&u2, q2 + i, sizeof u2);
			DP_VI t0 = __builtin_shuffle(s1, u1, back1), t1 = __builtin_shuffle(s2, u2, back1),
			      t2 = __builtin_shuffle(s1, u1, back2);
			s1 = u1;
			s2 = u2;
			DP_VI st = SELECT(m2, t2, SELECT(m1, t1, t0));
			DP_VI reached = d < inf;
			st = SELECT(reached, st, none);
			memcpy(q0 + i, &st, sizeof st);
		}
	}
}

/* The costs of rows a .. b-1 of the template for word w into c. */
static inline __attribute__((always_inline)) void DP_CAT(dp_costs, DP_LANES)(const mdb_template *t, uint64_t w,
                                                                            size_t a, size_t b, double *c) {
	if (t->btable) {
		const size_t b0 = w & 255, b1 = 256 + ((w >> 8) & 255), b2 = 512 + ((w >> 16) & 255),
		             b3 = 768 + ((w >> 24) & 255), b4 = 1024 + ((w >> 32) & 255);
		for (size_t i = a; i < b; i++) {
			const double *r = t->btable + i * 5 * 256;
			c[i] = r[b0] + r[b1] + r[b2] + r[b3] + r[b4];
		}
	} else {
		for (size_t i = a; i < b; i++) {
			c[i] = t->table[i * MDB_N_COST + (size_t)__builtin_popcountll((t->value[i] ^ w) & t->mask[i])];
		}
	}
}

/* With bounded (mdb_mt_distance_in's bound finite), a frame's rows are computed only up to the
 * highest one a path of cost <= bound can reach: the costs are non-negative, so every cell of
 * such a path is <= bound (a double sum of non-negative terms never falls below a partial sum),
 * and row i of frame j+1 has one only when row i-1 of frame j or j-1, or row i-2 of frame j, has
 * one: rows above max(top(j) + 2, top(j-1) + 1) are out of reach, top(j) the highest row of frame
 * j that is <= bound. A cell out of reach holds +inf, or a value > bound where its vector passes
 * the reach: the cells <= bound, their predecessor choices and so their starts are the full DP's,
 * since a cell > bound never wins against one <= bound. */
static inline __attribute__((always_inline)) void DP_CAT(dp_frames, DP_LANES)(const mdb_template *t,
                                                                             const uint64_t *words, size_t n,
                                                                             double *delta, int64_t *starts,
                                                                             size_t stride, double *buf,
                                                                             int64_t *sbuf, const int with_starts,
                                                                             const int bounded, double bound,
                                                                             size_t *dirty) {
	size_t K = t->K;
	double *c = buf + 3 * stride;
	double *col[3] = {buf + PAD, buf + stride + PAD, buf + 2 * stride + PAD}; /* frames j, j-1, j-2 at row 0 */
	int64_t *scol[3] = {sbuf + PAD, sbuf + stride + PAD, sbuf + 2 * stride + PAD};
	size_t written[3] = {1, 1, 1}; /* bounded: rows 1 .. written-1 of a column may be finite, the rest are +inf */
	size_t wrote = 1;              /* bounded: rows 0 .. wrote-1 of a column written, for *dirty */
	size_t fresh = 0;              /* rows of c that hold the costs of the current word */
	long top1 = -1, top2 = -1;     /* bounded: top(j-1), top(j-2) */
	for (size_t j = 0; j < n; j++) {
		uint64_t w = words[j];
		if (j == 0 || w != words[j - 1]) { /* a word often lasts a few frames: its costs are the same */
			fresh = 0;
		}
		size_t rows = K; /* rows 1 .. rows-1 computed */
		if (bounded) {
			long reach = top1 + 2 > top2 + 1 ? top1 + 2 : top2 + 1;
			rows = reach + 1 < (long)K ? (size_t)(reach + 1) : K;
		}
		/* rows 0 .. rows-1 cost the word's; the rows past them that the last vector passes (bounded)
		 * hold some earlier word's costs or c's zero tail: all >= 0, and such a cell, out of reach,
		 * stays > bound whatever it adds (unbounded: rows = K, and the tail past K-1 costs 0) */
		size_t vec_end = rows > 1 ? 1 + (rows - 1 + DP_LANES - 1) / DP_LANES * DP_LANES : 1;
		if (fresh < rows) {
			DP_CAT(dp_costs, DP_LANES)(t, w, fresh, rows, c);
			fresh = rows;
		}
		size_t r0 = j % 3, r1 = (j + 2) % 3, r2 = (j + 1) % 3;
		col[r0][0] = c[0];
		if (with_starts) {
			scol[r0][0] = (int64_t)j; /* row 0: a path starts here */
		}
		DP_CAT(dp_column, DP_LANES)(rows, c, col[r0], col[r1], col[r2], scol[r0], scol[r1], scol[r2], with_starts);
		if (!bounded) {
			delta[j] = col[r0][K - 1];
			if (with_starts) {
				starts[j] = scol[r0][K - 1];
			}
			continue;
		}
		for (size_t i = vec_end; i < written[r0]; i += DP_LANES) {
			const DP_VD inf = (DP_VD){0.0} + INFINITY; /* whole vectors: a later frame loads them whole */
			memcpy(col[r0] + i, &inf, sizeof inf); /* computed for frame j-3, out of reach now */
		}
		written[r0] = vec_end;
		wrote = vec_end > wrote ? vec_end : wrote;
		long top = (long)rows - 1; /* the rows past the reach are > bound */
		while (top >= 0 && !(col[r0][top] <= bound)) {
			top--;
		}
		top2 = top1;
		top1 = top;
		double d = col[r0][K - 1];
		delta[j] = d <= bound ? d : INFINITY;
		if (with_starts) {
			starts[j] = d <= bound ? scol[r0][K - 1] : -1;
		}
	}
	if (bounded && wrote > *dirty) {
		*dirty = wrote;
	}
}

/* Δ (and the starts when not NULL) of n frames, in the ring buf / sbuf of columns of stride rows;
 * bounded by bound when finite, *dirty then raised to the rows it wrote in a column */
DP_ATTR static void DP_FN(const mdb_template *t, const uint64_t *words, size_t n, double *delta, int64_t *starts,
                          size_t stride, double *buf, int64_t *sbuf, double bound, size_t *dirty) {
	if (bound < INFINITY) {
		if (starts) {
			DP_CAT(dp_frames, DP_LANES)(t, words, n, delta, starts, stride, buf, sbuf, 1, 1, bound, dirty);
		} else {
			DP_CAT(dp_frames, DP_LANES)(t, words, n, delta, NULL, stride, buf, sbuf, 0, 1, bound, dirty);
		}
	} else if (starts) {
		DP_CAT(dp_frames, DP_LANES)(t, words, n, delta, starts, stride, buf, sbuf, 1, 0, INFINITY, dirty);
	} else {
		DP_CAT(dp_frames, DP_LANES)(t, words, n, delta, NULL, stride, buf, sbuf, 0, 0, INFINITY, dirty);
	}
}

#undef DP_VD
#undef DP_VI
#undef DP_LANES
#undef DP_BACK1
#undef DP_BACK2
#undef DP_FN
#undef DP_ATTR
