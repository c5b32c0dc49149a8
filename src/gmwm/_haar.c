/* Classical Haar (MODWT) wavelet-variance sums: the C twin of the Numba kernels in
 * gmwm/_wvkernels.py, loaded without Numba's runtime (no JIT start-up for `gmwm wv`).
 *
 * Algorithm (module docstring of gmwm.wv): phase 1 runs levels 1..L on time blocks with a
 * recomputed halo of 2^L - 1 samples and stores V_L "panel-major" (the interleaved sub-series of
 * V_L, a panel of c of them at a time, each panel contiguous); phase 2 runs levels L+1..J on each
 * panel. Blocks (phase 1) and panels (phase 2) are independent: they are shared among threads and
 * their per-level sums are added to the totals in block (panel) order afterwards, so the result
 * does not depend on the number of threads, nor on how a stream cuts the signal into chunks.
 *
 * Levels are done two per pass (pair_step), which halves the traffic to the cache a pass streams
 * from; the values are those of one level at a time.
 *
 * Schedule (speed only: every value and every sum is computed by the same operations in the same
 * order as in the plain two-phase pyramid the Numba twin runs):
 * - Threads take runs of consecutive blocks (parallel_for). A run's first block recomputes its
 *   halo; its later blocks copy each level's values below the block start from the previous
 *   block's last values (block_levels), so a pass covers only the block. The block start sits on
 *   a 64-byte boundary of the work buffers.
 * - pair_step keeps the first level's averages of the last 2m positions in a small ring instead
 *   of recomputing them from V_{t-2m} and V_{t-3m} (the same value, two operations fewer).
 * - While a block (panel) computes, the samples of the next block (the next panel) are
 *   prefetched, spread over its pair passes; the DRAM reads overlap the arithmetic.
 * - A last level whose averages nothing reads (phase 2's top level) only gets its sums.
 *
 * Bit-identity with the Numba twin on any IEEE-754 machine: the element-wise values are
 * subtractions, additions and exact halvings; every sum of squares is accumulated in 16 explicit
 * lanes reduced by a fixed tree (reduce16), then the tail in order. No operation's order is left
 * to the compiler, so vector width (SSE2, AVX2, AVX-512) does not change the bits.
 * Build with -ffp-contract=off: a fused multiply-add would change them.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if !defined(_WIN32)
#include <pthread.h>
#define HAVE_PTHREADS 1
#endif

/* GCC on x86-64 Linux: an AVX2 clone of the hot loops, chosen at load time when the CPU has it
 * (the same operations in the same order as the baseline clone: the same bits; tests build the
 * baseline alone with -DGMWM_HAAR_NO_CLONES to check it). */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) \
    && !defined(GMWM_HAAR_NO_CLONES)
#define HOT __attribute__((target_clones("avx2", "default")))
#else
#define HOT
#endif

#if defined(__GNUC__) || defined(__clang__)
#define PREFETCH(p) __builtin_prefetch((p), 0, 2)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define PREFETCH(p) ((void)(p))
#define ALWAYS_INLINE inline
#endif

typedef Py_ssize_t ssz;

#define LANES 16
#define RING 4096 /* values of pair_step's ring (32 KiB) */

/* Averages only: dst[t] = (src[t] + src[t - lag]) / 2 for t in [lo, hi). */
HOT static void level_avg(const double *restrict src, double *restrict dst, ssz lo, ssz hi,
                          ssz lag)
{
    const double *cur = src + lo, *prev = src + lo - lag;
    double *out = dst + lo;
    for (ssz i = 0; i < hi - lo; i++)
        out[i] = 0.5 * (cur[i] + prev[i]);
}

/* Sum of 16 lanes, reduced pairwise (l, l + 8), (l, l + 4), (l, l + 2), (0, 1). */
static inline double reduce16(double *a)
{
    for (int w = LANES / 2; w >= 1; w /= 2)
        for (int l = 0; l < w; l++)
            a[l] = a[l] + a[l + w];
    return a[0];
}

/* One pyramid level on [lo, hi): dst[t] = (src[t] + src[t - lag]) / 2; returns
 * sum (src[t] - src[t - lag])^2: 16 lanes over the first 16*floor(n/16) terms (lane l takes the
 * terms i = l mod 16), reduce16, then the remaining terms one at a time. */
HOT static double level_step(const double *restrict src, double *restrict dst, ssz lo, ssz hi,
                             ssz lag)
{
    const double *cur = src + lo, *prev = src + lo - lag;
    double *out = dst + lo;
    const ssz n = hi - lo, n16 = n - n % LANES;
    double a[LANES] = {0.0};
    ssz i = 0;
    for (; i < n16; i += LANES)
        for (int l = 0; l < LANES; l++) {
            const double x = cur[i + l], y = prev[i + l], d = x - y;
            a[l] += d * d;
            out[i + l] = 0.5 * (x + y);
        }
    double acc = reduce16(a);
    for (; i < n; i++) {
        const double x = cur[i], y = prev[i], d = x - y;
        acc += d * d;
        out[i] = 0.5 * (x + y);
    }
    return acc;
}

/* sum (src[t] - src[t - lag])^2 over [lo, hi), lanes as level_step; no averages. */
HOT static double diff_sq(const double *restrict src, ssz lo, ssz hi, ssz lag)
{
    const double *cur = src + lo, *prev = src + lo - lag;
    const ssz n = hi - lo, n16 = n - n % LANES;
    double a[LANES] = {0.0};
    ssz i = 0;
    for (; i < n16; i += LANES)
        for (int l = 0; l < LANES; l++) {
            const double d = cur[i + l] - prev[i + l];
            a[l] += d * d;
        }
    double acc = reduce16(a);
    for (; i < n; i++) {
        const double d = cur[i] - prev[i];
        acc += d * d;
    }
    return acc;
}

/* Two levels in one pass (lags m and 2m) on [lo, hi): from V at t, t-m, t-2m, t-3m,
 * v = (V_t + V_{t-m})/2 and w = (V_{t-2m} + V_{t-3m})/2 (the first level's averages at t and
 * t - 2m; w is v of 2m positions earlier, kept in `ring` when given and 2m is a multiple of 16,
 * else recomputed), dst[t] = (v + w)/2 (unless !keep); the two sums of squares of V_t - V_{t-m}
 * and v - w go to s[0] and s[1], lanes as level_step. The values are those of two separate
 * levels, with half the memory traffic. */
static ALWAYS_INLINE void
pair_body(const double *restrict src, double *restrict dst, ssz lo, ssz hi, ssz m, double *s,
          const double *pf, ssz pf_lines, double *restrict ring, const int keep)
{
    const double *p0 = src + lo, *p1 = src + lo - m, *p2 = src + lo - 2 * m,
                 *p3 = src + lo - 3 * m;
    double *out = keep ? dst + lo : NULL;
    const ssz n = hi - lo, n16 = n - n % LANES;
    double a[LANES] = {0.0}, b[LANES] = {0.0};
    ssz i = 0;
    if (ring != NULL && (2 * m) % LANES == 0 && 2 * m <= RING) {
        /* w at t is v at t - 2m: kept in a ring of 2m values rather than recomputed (one
         * addition and one multiplication fewer per position; the same value). The ring starts
         * with w of the first 2m positions, computed as in the loop below. */
        const ssz R = 2 * m, r_n = R < n16 ? R : n16;
        for (ssz k = 0; k < r_n; k++)
            ring[k] = 0.5 * (p2[k] + p3[k]);
        ssz r = 0;
        for (; i < n16; i += LANES) {
            if (i / LANES < pf_lines)
                PREFETCH(pf + i / 2);
            double *rg = ring + r;
            for (int l = 0; l < LANES; l++) {
                const double x = p0[i + l], y = p1[i + l];
                const double v = 0.5 * (x + y), w = rg[l], d = x - y, e = v - w;
                rg[l] = v;
                a[l] += d * d;
                b[l] += e * e;
                if (keep)
                    out[i + l] = 0.5 * (v + w);
            }
            r += LANES;
            r = r == R ? 0 : r;
        }
    }
    for (; i < n16; i += LANES) {
        if (i / LANES < pf_lines)   /* one line of pf per 16 positions (see pf_share) */
            PREFETCH(pf + i / 2);
        for (int l = 0; l < LANES; l++) {
            const double x = p0[i + l], y = p1[i + l], u = p2[i + l], z = p3[i + l];
            const double v = 0.5 * (x + y), w = 0.5 * (u + z), d = x - y, e = v - w;
            a[l] += d * d;
            b[l] += e * e;
            if (keep)
                out[i + l] = 0.5 * (v + w);
        }
    }
    double s0 = reduce16(a), s1 = reduce16(b);
    for (; i < n; i++) {
        const double x = p0[i], y = p1[i], u = p2[i], z = p3[i];
        const double v = 0.5 * (x + y), w = 0.5 * (u + z), d = x - y, e = v - w;
        s0 += d * d;
        s1 += e * e;
        if (keep)
            out[i] = 0.5 * (v + w);
    }
    s[0] = s0;
    s[1] = s1;
}

HOT static void pair_step(const double *restrict src, double *restrict dst, ssz lo, ssz hi, ssz m,
                          double *s, const double *pf, ssz pf_lines, double *restrict ring)
{
    pair_body(src, dst, lo, hi, m, s, pf, pf_lines, ring, 1);
}

/* The sums of pair_step alone (the averages of a last pass are not needed). */
HOT static void pair_sums(const double *restrict src, ssz lo, ssz hi, ssz m, double *s,
                          const double *pf, ssz pf_lines, double *restrict ring)
{
    pair_body(src, NULL, lo, hi, m, s, pf, pf_lines, ring, 0);
}

/* Averages only of pair_step. */
HOT static void pair_avg(const double *restrict src, double *restrict dst, ssz lo, ssz hi, ssz m)
{
    const double *p0 = src + lo, *p1 = src + lo - m, *p2 = src + lo - 2 * m,
                 *p3 = src + lo - 3 * m;
    double *out = dst + lo;
    for (ssz i = 0; i < hi - lo; i++)
        out[i] = 0.5 * (0.5 * (p0[i] + p1[i]) + 0.5 * (p2[i] + p3[i]));
}

/* What the caller works on next (the next block's samples, the next panel: pf[:pf_n)) is
 * prefetched while this one computes, one cache line per 16 positions of its pair passes, the
 * lines shared evenly among the n_pairs pair passes (so that the memory reads spread over the
 * whole computation): pair pass k prefetches *lines lines from the returned address. */
static const double *pf_share(const double *pf, ssz pf_n, ssz n_pairs, ssz k, ssz *lines)
{
    const ssz total = (pf_n + 7) / 8, share = n_pairs > 0 ? (total + n_pairs - 1) / n_pairs : 0;
    const ssz first = share * k;
    *lines = pf == NULL || first >= total ? 0 : (total - first < share ? total - first : share);
    return *lines > 0 ? pf + 8 * first : NULL;
}

/* Levels 1..n_levels on a[:n], lags in multiples of `unit`, ping-ponging between a and b, two
 * levels per pass (pair_step; a last odd level alone). Level j is defined from position
 * lo_j = 2 lag_j - unit; the sum of squared differences at positions >= acc_from of level j goes
 * to out[j - 1] (0 when there are none): for the first level of a pair, the positions below the
 * second level's lo (which pair_step does not reach) are summed apart (diff_sq) and added first.
 * Returns 0 if the last computed level's averages are in a, 1 if in b; without need_last, the
 * last level's averages are not computed (only its sums). */
static int pyramid(double *a, double *b, ssz n, ssz n_levels, ssz unit, ssz acc_from,
                   double *out, double *tails, const double *pf, ssz pf_n, double *ring,
                   int need_last)
{
    double *src = a, *dst = b, *tmp;
    int which = 0;
    for (ssz j = 1; j <= n_levels;) {
        const ssz m = unit << (j - 1), lo1 = 2 * m - unit;
        out[j - 1] = 0.0;
        if (j < n_levels) {
            const ssz lo2 = 4 * m - unit;
            out[j] = 0.0;
            if (lo1 < n) {
                const ssz p_lo = lo1 > acc_from ? lo1 : acc_from, p_hi = lo2 < n ? lo2 : n;
                const double head = p_lo < p_hi ? diff_sq(src, p_lo, p_hi, m) : 0.0;
                out[j - 1] = head;
                if (lo2 < n) {
                    const ssz acc_lo = lo2 > acc_from ? lo2 : acc_from;
                    double s[2] = {0.0, 0.0};
                    const int keep = need_last || j + 1 < n_levels;
                    if (acc_lo > lo2 && keep)
                        pair_avg(src, dst, lo2, acc_lo < n ? acc_lo : n, m);
                    ssz pf_l;
                    const double *pf_k = pf_share(pf, pf_n, n_levels / 2, j / 2, &pf_l);
                    if (acc_lo < n && keep)
                        pair_step(src, dst, acc_lo, n, m, s, pf_k, pf_l, ring);
                    else if (acc_lo < n)
                        pair_sums(src, acc_lo, n, m, s, pf_k, pf_l, ring);
                    out[j - 1] = head + s[0];
                    out[j] = s[1];
                    if (tails != NULL) {          /* for the next block (block_levels) */
                        memcpy(tails, src + n - 3 * m, (size_t)(3 * m) * sizeof(double));
                        tails += 3 * m;
                    }
                    tmp = src; src = dst; dst = tmp;
                    which = 1 - which;
                }
            }
            j += 2;
        } else {
            if (lo1 < n) {
                const ssz acc_lo = lo1 > acc_from ? lo1 : acc_from;
                if (acc_lo > lo1 && need_last)
                    level_avg(src, dst, lo1, acc_lo < n ? acc_lo : n, m);
                if (acc_lo < n)   /* the same sum with or without the averages */
                    out[j - 1] = need_last ? level_step(src, dst, acc_lo, n, m)
                                           : diff_sq(src, acc_lo, n, m);
                if (tails != NULL)
                    memcpy(tails, src + n - m, (size_t)m * sizeof(double));
                tmp = src; src = dst; dst = tmp;
                which = 1 - which;
            }
            j += 1;
        }
    }
    return which;
}

/* ---- phase 1 ------------------------------------------------------------------------------- */

/* Levels 1..L of a block that follows, in the same run, a block whose pyramid (pyramid or
 * block_levels) saved its tails: a[h:n) holds V_0 of the block's positions (h = 2^L - 1), and the
 * values of each level below the block start, which pyramid would recompute in the halo, are
 * instead copied from the previous block's tails (the same values: V_j at t depends only on the
 * samples t - 2^j + 1 .. t). Every pass then covers exactly [h, n), which is what pyramid sums for
 * such a block (acc_from = h >= lo_j, no head terms): the same sums, the same bits. Saves its own
 * tails for the next block. The pair passes prefetch pf[:pf_n) (the next block's samples). */
static int block_levels(double *a, double *b, ssz h, ssz n, ssz L, double *out, double *tails,
                        const double *pf, ssz pf_n, double *ring, int need_last)
{
    double *src = a, *dst = b, *tmp;
    int which = 0;
    for (ssz j = 1; j <= L;) {
        const ssz m = (ssz)1 << (j - 1);
        if (j < L) {
            double s[2] = {0.0, 0.0};
            memcpy(src + h - 3 * m, tails, (size_t)(3 * m) * sizeof(double));
            ssz pf_l;
            const double *pf_k = pf_share(pf, pf_n, L / 2, j / 2, &pf_l);
            if (need_last || j + 1 < L)
                pair_step(src, dst, h, n, m, s, pf_k, pf_l, ring);
            else
                pair_sums(src, h, n, m, s, pf_k, pf_l, ring);
            out[j - 1] = 0.0 + s[0];  /* as pyramid: head (0.0 here) + s[0] */
            out[j] = s[1];
            memcpy(tails, src + n - 3 * m, (size_t)(3 * m) * sizeof(double));
            tails += 3 * m;
            j += 2;
        } else {
            memcpy(src + h - m, tails, (size_t)m * sizeof(double));
            out[j - 1] = need_last ? level_step(src, dst, h, n, m) : diff_sq(src, h, n, m);
            memcpy(tails, src + n - m, (size_t)m * sizeof(double));
            j += 1;
        }
        tmp = src; src = dst; dst = tmp;
        which = 1 - which;
    }
    return which;
}

typedef struct {
    const double *x;      /* x[t - t_lo] is sample t */
    ssz t_lo, t_begin, t_end, block, L;
    double x0;
    double *blk;          /* per-block sums, n_blocks x L */
    double *store;        /* panel-major V_L (NULL: not kept) */
    ssz k_first, nrows, panel;
    int stream;           /* non-temporal stores into the store (large stores only) */
    int fail;
} p1_job;

/* Store V_L of positions t in [t_a, t_b) (values src[t - s0]) panel-major: s = t - (P - 1),
 * row k = s / P, residue r = s % P in panel p = r / c at (k - k_first) * c_p + (r - p c) of the
 * panel's region, which starts at nrows * p * c. Panel by panel, so that each panel's part is
 * written in one contiguous run. */
static void store_vl(const p1_job *jb, const double *src, ssz s0, ssz t_a, ssz t_b)
{
    const ssz L = jb->L, P = (ssz)1 << L, halo = P - 1, c = jb->panel;
    const ssz s_a = t_a - halo, s_b = t_b - halo;            /* s in [s_a, s_b) */
    const ssz k_a = s_a >> L, r_a = s_a & (P - 1);
    const ssz k_b = (s_b - 1) >> L, r_b = ((s_b - 1) & (P - 1)) + 1;  /* last row: r < r_b */
    const double *base = src + (halo - s0);                  /* base[s] = V_L at s */
    for (ssz r0 = 0; r0 < P; r0 += c) {
        const ssz cp = r0 + c < P ? c : P - r0;
        double *dst = jb->store + jb->nrows * r0 - jb->k_first * cp;   /* dst[k cp + ci] */
        for (ssz k = k_a; k <= k_b; k++) {
            ssz lo = k == k_a ? r_a - r0 : 0, hi = k == k_b ? r_b - r0 : cp;
            lo = lo > 0 ? lo : 0;
            hi = hi < cp ? hi : cp;
            const double *in = base + (k << L) + r0;
            double *o = dst + k * cp;
#ifdef __SSE2__
            /* whole 16-byte pairs with non-temporal stores: the store is written once and read
             * much later (phase 2), so skip reading its lines into the cache first */
            if (jb->stream && ((uintptr_t)(o + lo) & 15) == 0) {
                ssz ci = lo;
                for (; ci + 2 <= hi; ci += 2)
                    _mm_stream_pd(o + ci, _mm_loadu_pd(in + ci));
                for (; ci < hi; ci++)
                    o[ci] = in[ci];
                continue;
            }
#endif
            for (ssz ci = lo; ci < hi; ci++)
                o[ci] = in[ci];
        }
    }
}

/* dst[i] = src[i] - x0 */
HOT static void shift_copy(const double *restrict src, double *restrict dst, ssz n, double x0)
{
    for (ssz i = 0; i < n; i++)
        dst[i] = src[i] - x0;
}

/* Blocks [b_first, b_last) of the job (block b covers [t_begin + b block, ...)). */
static void phase1_blocks(p1_job *jb, ssz b_first, ssz b_last)
{
    const ssz L = jb->L, P = (ssz)1 << L, halo = P - 1, len = jb->block + halo;
    /* the block start (index halo) on a 64-byte boundary: aligned vector stores in every pass */
    const ssz pad = (8 - halo % 8) % 8;
    double *mem_a = malloc((size_t)(len + pad + 8) * sizeof(double));
    double *mem_b = malloc((size_t)(len + pad + 8) * sizeof(double));
    /* the values each pass reads below the block start (3m per pair, m for a last single level;
     * less than 2 * 2^L in all) */
    double *tails = malloc((size_t)(2 * P + RING) * sizeof(double));   /* + pair_step's ring */
    if (mem_a == NULL || mem_b == NULL || tails == NULL) {
        free(mem_a);
        free(mem_b);
        free(tails);
        jb->fail = 1;
        return;
    }
    double *buf_a = mem_a + ((-(ssz)((uintptr_t)mem_a / sizeof(double))) & 7) + pad;
    double *buf_b = mem_b + ((-(ssz)((uintptr_t)mem_b / sizeof(double))) & 7) + pad;
    /* a block may reuse the previous block's tails when it starts at or after the halo and
     * blocks are at least 2^L long (then every tail lies at or after its level's first
     * position, and inside the previous block or its halo) */
    const int carry_ok = jb->block >= P;
    int have_tails = 0;
    const double x0 = jb->x0;
    for (ssz b = b_first; b < b_last; b++) {
        const ssz b0 = jb->t_begin + b * jb->block;
        const ssz b1 = b0 + jb->block < jb->t_end ? b0 + jb->block : jb->t_end;
        const ssz s0 = b0 - halo > 0 ? b0 - halo : 0;
        const ssz n = b1 - s0;
        int which;
        if (have_tails && b0 >= halo) {
            /* the next block's samples, prefetched during this one's passes */
            const ssz nb0 = b1, nb1 = nb0 + jb->block < jb->t_end ? nb0 + jb->block : jb->t_end;
            ssz pf_n = b + 1 < b_last ? nb1 - nb0 : 0;
            shift_copy(jb->x + (b0 - jb->t_lo), buf_a + halo, b1 - b0, x0);
            which = block_levels(buf_a, buf_b, halo, n, L, jb->blk + b * L, tails,
                                 jb->x + (nb0 - jb->t_lo), pf_n, tails + 2 * P,
                                 jb->store != NULL);
        } else {
            /* buffers shifted so that the block start (index b0 - s0) is at index halo */
            const ssz off = halo - (b0 - s0);
            shift_copy(jb->x + (s0 - jb->t_lo), buf_a + off, n, x0);
            which = pyramid(buf_a + off, buf_b + off, n, L, 1, b0 - s0, jb->blk + b * L,
                            carry_ok && b1 - b0 == jb->block ? tails : NULL, NULL, 0,
                            tails + 2 * P, jb->store != NULL);
            have_tails = carry_ok && b1 - b0 == jb->block;
            if (jb->store != NULL) {
                const ssz t_a = b0 > halo ? b0 : halo;
                if (t_a < b1)
                    store_vl(jb, (which == 0 ? buf_a : buf_b) + off, s0, t_a, b1);
            }
            continue;
        }
        if (jb->store != NULL) {
            const ssz t_a = b0 > halo ? b0 : halo;
            if (t_a < b1)
                store_vl(jb, which == 0 ? buf_a : buf_b, s0, t_a, b1);
        }
    }
    free(mem_a);
    free(mem_b);
    free(tails);
#ifdef __SSE2__
    if (jb->stream)
        _mm_sfence();  /* the non-temporal stores are visible before the thread ends */
#endif
}

/* ---- phase 2 ------------------------------------------------------------------------------- */

typedef struct {
    double *store;        /* panels p_begin.. contiguous */
    ssz rows, n_out, L, panel, p_begin, n_levels2;
    double *psum;         /* per-panel sums, n_panels x n_levels2 */
    int fail;
} p2_job;

static void phase2_panels(p2_job *jb, ssz q_first, ssz q_last)
{
    const ssz P = (ssz)1 << jb->L, c = jb->panel;
    const ssz cw = c < P ? c : P;
    double *pan_b = malloc((size_t)(jb->rows * cw + RING) * sizeof(double));  /* + the ring */
    if (pan_b == NULL) {
        jb->fail = 1;
        return;
    }
    for (ssz q = q_first; q < q_last; q++) {
        const ssz p = jb->p_begin + q, r0 = p * c;
        const ssz cp = r0 + c < P ? c : P - r0;
        ssz last = jb->n_out - (jb->rows - 1) * P - r0;
        last = last > 0 ? last : 0;
        last = last < cp ? last : cp;
        double *pan = jb->store + jb->rows * q * c;
        /* the next panel of this run (rows * c values after this one, or fewer when it is
         * the last), prefetched during this one's passes */
        const ssz pf_n = q + 1 < q_last ? jb->rows * (r0 + 2 * c <= P ? c : P - r0 - c) : 0;
        pyramid(pan, pan_b, (jb->rows - 1) * cp + last, jb->n_levels2, cp, 0,
                jb->psum + q * jb->n_levels2, NULL, pan + jb->rows * cp, pf_n,
                pan_b + jb->rows * cw, 0);
    }
    free(pan_b);
}

/* ---- threads: items [0, n) taken in chunks ------------------------------------------------- */

/* The threads take runs of `chunk` consecutive items until none is left, so that a thread slowed
 * by other work on the machine takes fewer of them (the result does not depend on who does which:
 * the sums are kept per item and added in item order afterwards). Runs of several items keep the
 * blocks of a run consecutive (each run's first block recomputes its halo). */
typedef struct {
    void (*fn)(void *, ssz, ssz);
    void *job;
    ssz n, chunk, next;   /* next: the first item not taken yet */
#ifdef HAVE_PTHREADS
    pthread_mutex_t lock;
#endif
} work;

static void *run_work(void *arg)
{
    work *w = (work *)arg;
    for (;;) {
#ifdef HAVE_PTHREADS
        pthread_mutex_lock(&w->lock);
#endif
        const ssz lo = w->next;
        w->next = lo < w->n ? lo + w->chunk : lo;
#ifdef HAVE_PTHREADS
        pthread_mutex_unlock(&w->lock);
#endif
        if (lo >= w->n)
            break;
        w->fn(w->job, lo, lo + w->chunk < w->n ? lo + w->chunk : w->n);
    }
    return NULL;
}

static void parallel_for(void (*fn)(void *, ssz, ssz), void *job, ssz n, int n_threads)
{
    if (n_threads > n)
        n_threads = (int)n;
#ifdef HAVE_PTHREADS
    if (n_threads > 1) {
        pthread_t tid[64];
        int started[64] = {0};
        if (n_threads > 64)
            n_threads = 64;
        ssz chunk = n / (8 * (ssz)n_threads);   /* about 8 runs per thread */
        work w;
        w.fn = fn;
        w.job = job;
        w.n = n;
        w.chunk = chunk > 1 ? chunk : 1;
        w.next = 0;
        if (pthread_mutex_init(&w.lock, NULL) == 0) {
            for (int i = 1; i < n_threads; i++)
                started[i] = pthread_create(&tid[i], NULL, run_work, &w) == 0;
            run_work(&w);                     /* (a thread that did not start: the others) */
            for (int i = 1; i < n_threads; i++)
                if (started[i])
                    pthread_join(tid[i], NULL);
            pthread_mutex_destroy(&w.lock);
            return;
        }
    }
#endif
    (void)n_threads;
    if (n > 0)
        fn(job, 0, n);
}

static void p1_fn(void *job, ssz lo, ssz hi) { phase1_blocks((p1_job *)job, lo, hi); }
static void p2_fn(void *job, ssz lo, ssz hi) { phase2_panels((p2_job *)job, lo, hi); }

/* ---- Python bindings ----------------------------------------------------------------------- */

static PyObject *py_phase1(PyObject *self, PyObject *args)
{
    Py_buffer x, sums, store;
    ssz t_lo, t_begin, t_end, L, block, k_first, nrows, panel;
    double x0;
    int n_threads;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnndnnw*w*nnni", &x, &t_lo, &t_begin, &t_end, &x0, &L, &block,
                          &sums, &store, &k_first, &nrows, &panel, &n_threads))
        return NULL;
    const ssz n_x = x.len / (ssz)sizeof(double);
    const ssz halo = L >= 1 && L <= 40 ? ((ssz)1 << L) - 1 : 0, P = halo + 1;
    const int keep = store.len > 0;
    const char *bad = NULL;
    if (L < 1 || L > 40 || block < 1 || panel < 1)
        bad = "phase1: bad level count, block or panel width";
    else if (t_begin < 0 || t_end <= t_begin || t_begin % block != 0)
        bad = "phase1: bad position range (t_begin must be a multiple of the block)";
    else if (t_lo < 0 || t_lo > (t_begin > halo ? t_begin - halo : 0) || t_end - t_lo > n_x)
        bad = "phase1: the samples do not cover the range and its halo";
    else if (sums.len < L * (ssz)sizeof(double))
        bad = "phase1: sums is shorter than the level count";
    else if (keep) {
        const ssz t_a = t_begin > halo ? t_begin : halo;
        if (t_a < t_end) {
            const ssz k_lo = (t_a - halo) / P, k_hi = (t_end - 1 - halo) / P;
            if (k_lo < k_first || k_hi >= k_first + nrows
                || store.len < nrows * P * (ssz)sizeof(double))
                bad = "phase1: the store does not hold the rows of this range";
        }
    }
    if (bad == NULL) {
        const ssz n_blocks = (t_end - t_begin + block - 1) / block;
        double *blk = calloc((size_t)(n_blocks * L), sizeof(double));
        if (blk == NULL)
            bad = "phase1: out of memory";
        else {
            /* non-temporal stores only for stores larger than a typical last-level cache */
            const int nt_stores = store.len > ((ssz)32 << 20);
            p1_job jb = {(const double *)x.buf, t_lo, t_begin, t_end, block, L, x0, blk,
                         keep ? (double *)store.buf : NULL, k_first, nrows, panel, nt_stores, 0};
            double *s = (double *)sums.buf;
            Py_BEGIN_ALLOW_THREADS
            parallel_for(p1_fn, &jb, n_blocks, n_threads);
            for (ssz b = 0; b < n_blocks; b++)   /* in block order: thread-count independent */
                for (ssz j = 0; j < L; j++)
                    s[j] += blk[b * L + j];
            Py_END_ALLOW_THREADS
            free(blk);
            if (jb.fail)
                bad = "phase1: out of memory";
        }
    }
    PyBuffer_Release(&x);
    PyBuffer_Release(&sums);
    PyBuffer_Release(&store);
    if (bad != NULL) {
        PyErr_SetString(strstr(bad, "memory") ? PyExc_MemoryError : PyExc_ValueError, bad);
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyObject *py_phase2(PyObject *self, PyObject *args)
{
    Py_buffer store, sums;
    ssz rows, n_out, L, panel, p_begin, p_end, n_levels2;
    int n_threads;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nnnnnnnw*i", &store, &rows, &n_out, &L, &panel, &p_begin,
                          &p_end, &n_levels2, &sums, &n_threads))
        return NULL;
    const ssz P = L >= 1 && L <= 40 ? (ssz)1 << L : 0;
    const ssz n_panels = panel >= 1 && P ? (P + panel - 1) / panel : 0;
    const char *bad = NULL;
    if (P == 0 || panel < 1 || rows < 1 || n_out < 1 || n_out > rows * P || n_levels2 < 1)
        bad = "phase2: bad level count, panel width or row count";
    else if (p_begin < 0 || p_end <= p_begin || p_end > n_panels)
        bad = "phase2: bad panel range";
    else if (store.len < (rows * (p_end * panel < P ? p_end * panel : P) - rows * p_begin * panel)
                         * (ssz)sizeof(double))
        bad = "phase2: the store is shorter than its panels";
    else if (sums.len < (L + n_levels2) * (ssz)sizeof(double))
        bad = "phase2: sums is shorter than the level count";
    if (bad == NULL) {
        const ssz n = p_end - p_begin;
        double *psum = calloc((size_t)(n * n_levels2), sizeof(double));
        if (psum == NULL)
            bad = "phase2: out of memory";
        else {
            p2_job jb = {(double *)store.buf, rows, n_out, L, panel, p_begin, n_levels2, psum, 0};
            double *s = (double *)sums.buf + L;
            Py_BEGIN_ALLOW_THREADS
            parallel_for(p2_fn, &jb, n, n_threads);
            for (ssz q = 0; q < n; q++)          /* in panel order */
                for (ssz j = 0; j < n_levels2; j++)
                    s[j] += psum[q * n_levels2 + j];
            Py_END_ALLOW_THREADS
            free(psum);
            if (jb.fail)
                bad = "phase2: out of memory";
        }
    }
    PyBuffer_Release(&store);
    PyBuffer_Release(&sums);
    if (bad != NULL) {
        PyErr_SetString(strstr(bad, "memory") ? PyExc_MemoryError : PyExc_ValueError, bad);
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"phase1", py_phase1, METH_VARARGS,
     "phase1(x, t_lo, t_begin, t_end, x0, L, block, sums, store, k_first, nrows, panel, "
     "n_threads): levels 1..L of positions [t_begin, t_end) (x[t - t_lo] = sample t, x0 = sample "
     "0) added to sums[:L] in block order; V_L stored panel-major in store (empty: not kept). "
     "Releases the GIL."},
    {"phase2", py_phase2, METH_VARARGS,
     "phase2(store, rows, n_out, L, panel, p_begin, p_end, n_levels2, sums, n_threads): levels "
     "L+1..L+n_levels2 of panels [p_begin, p_end) (contiguous in store, which is overwritten) "
     "added to sums[L:] in panel order. Releases the GIL."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_haar",
                                    "C kernel of the classical Haar wavelet variance.", -1,
                                    methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__haar(void) { return PyModule_Create(&module); }
