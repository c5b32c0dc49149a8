/* Lag sums of the model-based covariance of the Haar WV estimator: the C twin of the Numba
 * kernels in gmwm/_wvcovkernels.py (all_pairs and the functions it calls), loaded without
 * Numba's runtime, so that `gmwm plan` (which computes a covariance per candidate length) does not
 * pay for importing Numba and loading its cache.
 *
 * The method (gmwm/wvcov.py's module docstring): for every pair of scales (tau_j >= tau_k), the
 * lags h are cut at the kinks of gamma_jk(h) (h = a - b, a in {0, m_j, tau_j}, b in {0, m_k,
 * tau_k}) and at the ends of the lag range; each piece is summed exactly next to a kink and by
 * Gregory's end-corrected rule with a graded Gauss-Legendre integral elsewhere.
 *
 * Bit-identity with the Numba twin on any IEEE-754 machine: every expression below is the
 * Python expression of the twin with the same operands in the same order (left to right, as
 * Python evaluates them; -p * x is (-p) * x in both), the elementary functions are the C
 * library's exp, expm1 and pow that Numba calls too, and phi ** n (n an integer) is done by
 * Numba's own method (ipow). Sorting and the unique values of a small array are exact whatever
 * the algorithm. Build with -ffp-contract=off: a fused multiply-add would change the bits.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define N_DIRECT 16 /* lags summed exactly next to every kink (_N_DIRECT) */

typedef struct {
    double T, wn, rw, qn;
    Py_ssize_t nar, n_gl, n_grades, n_greg;
    const double *ar_a, *ar_p, *ar_pl, *ar_sm;
    const unsigned char *ar_neg;
    const double *gl_x, *gl_w, *grades, *greg_l, *greg_r;
    double *edges; /* scratch of _lattice_sum: 3 + 2 nar n_grades values */
} ctx;

typedef struct {
    double tj, mj, tk, mk;
    const double *uj, *uk;
    const unsigned char *e3;
} pair;

/* exp(-x) minus its Taylor polynomial of degree n - 1, for x >= 0 (_exp_tail). */
static double exp_tail(double x, int n)
{
    if (x < 0.5) {
        double term = 1.0;
        for (int k = 1; k < n + 1; k++)
            term *= -x / (double)k;
        double s = term;
        for (int k = n + 1; k < 30; k++) {
            term *= -x / (double)k;
            s += term;
            if (fabs(term) <= 1e-17 * fabs(s))
                break;
        }
        return s;
    }
    double s = expm1(-x);
    double term = 1.0;
    for (int k = 1; k < n; k++) {
        term *= -x / (double)k;
        s -= term;
    }
    return s;
}

static double e3f(double x) { return exp_tail(x, 3); }
static double e2f(double x) { return exp_tail(x, 2); }

/* x ** n for an integer n >= 0, as Numba computes a float to an integer power: by squaring,
 * and by pow() above 0x10000. */
static double ipow(double x, int64_t n)
{
    if (n > 0x10000)
        return pow(x, (double)n);
    double r = 1.0;
    while (n != 0) {
        if (n & 1)
            r *= x;
        n >>= 1;
        x *= x;
    }
    return r;
}

/* phi^n for n >= 0 with |phi| = exp(-a); the sign for phi < 0 from the parity of n (_pw). */
static double pw(double a, int neg, double n, int64_t par)
{
    const double x = a * n;
    if (x > 745.0)
        return 0.0;
    const double v = exp(-x);
    if (neg && (par & 1))
        return -v;
    return v;
}

/* sum_b beta_b K_AR(n0 + b), b in (0, m, tau), beta = (1, -2, 1) (_g_ar). */
static double g_ar(const ctx *C, double n0, int64_t par, double m, double tau, Py_ssize_t c,
                   int e3, double u)
{
    const double a = C->ar_a[c];
    const int neg = C->ar_neg[c] != 0;
    const double p = C->ar_p[c];
    if (n0 >= 0.0 || n0 + tau <= 0.0) {
        double x;
        int64_t px;
        if (n0 >= 0.0) {
            x = n0;
            px = par;
        } else {
            x = -(n0 + tau);
            px = par + (int64_t)tau;
        }
        if (e3)
            return -p * (expm1(-a * x) * u * u - e2f(a * m) * (u + a * m));
        return -p * pw(a, neg, x, px) * u * u;
    }
    double s = 0.0;
    if (!neg && a * tau <= 2.0) {
        const double sm = C->ar_sm[c];
        for (int ib = 0; ib < 3; ib++) {
            const double b = ib == 0 ? 0.0 : (ib == 1 ? m : tau);
            const double w = ib != 1 ? 1.0 : -2.0;
            const double n = fabs(n0 + b);
            s += w * -p * (e3f(a * n) + n * sm);
        }
        if (!e3)
            s -= p * a * a * m * m;
        return s;
    }
    const double pl = C->ar_pl[c];
    for (int ib = 0; ib < 3; ib++) {
        const double b = ib == 0 ? 0.0 : (ib == 1 ? m : tau);
        const double w = ib != 1 ? 1.0 : -2.0;
        const double n = fabs(n0 + b);
        const double pe = p == 0.0 ? 0.0 : p * pw(a, neg, n, par + (int64_t)b);
        s += w * (-pe - pl * n);
    }
    return s;
}

/* gamma_jk(h) = Cov(W_{j,t}, W_{k,t-h}); par = parity of h (_gamma). */
static double gamma_jk(const ctx *C, const pair *P, double h, int64_t par)
{
    const double tj = P->tj, mj = P->mj, tk = P->tk, mk = P->mk;
    const double norm = 1.0 / (tj * tk);
    if (h > tj || h < -tk) {
        double s = 0.0;
        for (Py_ssize_t c = 0; c < C->nar; c++) {
            if (C->ar_p[c] == 0.0)
                continue;
            double e;
            if (h >= tj)
                e = pw(C->ar_a[c], C->ar_neg[c] != 0, h - tj, par + (int64_t)tj);
            else
                e = pw(C->ar_a[c], C->ar_neg[c] != 0, -h - tk, par + (int64_t)tk);
            s -= C->ar_p[c] * e * P->uj[c] * P->uj[c] * P->uk[c] * P->uk[c];
        }
        return s * norm;
    }
    double s = 0.0;
    for (int ia = 0; ia < 3; ia++) {
        const double a = ia == 0 ? 0.0 : (ia == 1 ? mj : tj);
        const double alpha = ia != 1 ? 1.0 : -2.0;
        const double n0 = h - a;
        const int64_t p0 = par + (int64_t)a;
        double g = 0.0;
        const int pos = n0 >= 0.0;
        const int negs = n0 + tk <= 0.0;
        if (pos || negs) {
            const double x = pos ? n0 : -(n0 + tk);
            g += C->rw * mk * mk * (x + mk) / 2.0;
        } else {
            for (int ib = 0; ib < 3; ib++) {
                const double b = ib == 0 ? 0.0 : (ib == 1 ? mk : tk);
                const double w = ib != 1 ? 1.0 : -2.0;
                const double n = fabs(n0 + b);
                g += w * (-0.5 * C->wn * n + C->rw * (n * n * n - n) / 12.0);
            }
        }
        if (C->qn != 0.0) {
            for (int ib = 0; ib < 3; ib++) {
                const double b = ib == 0 ? 0.0 : (ib == 1 ? mk : tk);
                const double w = ib != 1 ? 1.0 : -2.0;
                if (n0 + b == 0.0)
                    g += w * C->qn;
            }
        }
        for (Py_ssize_t c = 0; c < C->nar; c++)
            g += g_ar(C, n0, p0, mk, tk, c, P->e3[c] != 0, P->uk[c]);
        s += alpha * g;
    }
    return s * norm;
}

/* (N(h) gamma(h), N(h) gamma(h)^2) (_point). */
static void point(const ctx *C, const pair *P, double h, int64_t par, double *v1, double *v2)
{
    const double T = C->T, th = T + h, kh = P->tk + h;
    const double nn = (T <= th ? T : th) - (P->tj >= kh ? P->tj : kh) + 1.0;
    if (nn <= 0.0) {
        *v1 = 0.0;
        *v2 = 0.0;
        return;
    }
    const double g = gamma_jk(C, P, h, par);
    *v1 = nn * g;
    *v2 = nn * g * g;
}

static void sort_doubles(double *x, Py_ssize_t n)
{
    for (Py_ssize_t i = 1; i < n; i++) { /* insertion sort: a few values */
        const double v = x[i];
        Py_ssize_t k = i;
        for (; k > 0 && x[k - 1] > v; k--)
            x[k] = x[k - 1];
        x[k] = v;
    }
}

/* sum over h = h0 + step i, i = 0..n-1, of (N gamma, N gamma^2) (_lattice_sum). */
static void lattice_sum(const ctx *C, const pair *P, double h0, double step, int64_t n,
                        int64_t kd, int left, int right, double *o1, double *o2)
{
    const int64_t kl = left ? kd : 0;
    const int64_t kr = right ? kd : 0;
    const int64_t par = (int64_t)h0 & 1;
    const int64_t alt = step == 1.0 ? 1 : 0;
    double s1 = 0.0, s2 = 0.0, v1, v2;
    if (n <= kl + kr + 40) {
        for (int64_t i = 0; i < n; i++) {
            point(C, P, h0 + step * (double)i, par + alt * i, &v1, &v2);
            s1 += v1;
            s2 += v2;
        }
        *o1 = s1;
        *o2 = s2;
        return;
    }
    for (int64_t ii = 0; ii < kl; ii++) {
        point(C, P, h0 + step * (double)ii, par + alt * ii, &v1, &v2);
        s1 += v1;
        s2 += v2;
    }
    for (int64_t ii = n - kr; ii < n; ii++) {
        point(C, P, h0 + step * (double)ii, par + alt * ii, &v1, &v2);
        s1 += v1;
        s2 += v2;
    }
    const double A = (double)kl;
    const double B = (double)(n - 1 - kr);
    for (Py_ssize_t i = 0; i < C->n_greg; i++) {
        point(C, P, h0 + step * (A + (double)i), par + alt * (kl + i), &v1, &v2);
        s1 += C->greg_l[i] * v1;
        s2 += C->greg_l[i] * v2;
        point(C, P, h0 + step * (B - (double)i), par + alt * (n - 1 - kr - i), &v1, &v2);
        s1 += C->greg_r[i] * v1;
        s2 += C->greg_r[i] * v2;
    }
    const double mid = 0.5 * (A + B);
    double *edges = C->edges;
    Py_ssize_t ne = 0;
    edges[ne] = A;
    edges[ne + 1] = B;
    ne += 2;
    if (C->nar > 0)
        edges[ne++] = mid;
    const double last = (double)(n - 1);
    for (Py_ssize_t c = 0; c < C->nar; c++) {
        if (C->ar_a[c] <= 0.0 || C->ar_p[c] == 0.0)
            continue;
        for (Py_ssize_t q = 0; q < C->n_grades; q++) {
            const double d = C->grades[q] / (C->ar_a[c] * step);
            if (left && A < d && d < mid)
                edges[ne++] = d;
            if (right && mid < last - d && last - d < B)
                edges[ne++] = last - d;
        }
    }
    sort_doubles(edges, ne);
    for (Py_ssize_t q = 0; q + 1 < ne; q++) {
        const double lo = edges[q], hi = edges[q + 1];
        if (hi <= lo)
            continue;
        const double half = 0.5 * (hi - lo);
        const double cen = 0.5 * (hi + lo);
        for (Py_ssize_t r = 0; r < C->n_gl; r++) {
            point(C, P, h0 + step * (cen + half * C->gl_x[r]), par, &v1, &v2);
            s1 += half * C->gl_w[r] * v1;
            s2 += half * C->gl_w[r] * v2;
        }
    }
    *o1 = s1;
    *o2 = s2;
}

/* Terms summed exactly at each end of a piece, on the unit lattice (kd) and on the even/odd
 * sub-lattices (kd2), and whether to split by parity (_direct_ends). */
static void direct_ends(const ctx *C, int64_t *kd_out, int64_t *kd2_out, int *split_out)
{
    int64_t kd = 0, kd2 = 0;
    int split = 0;
    for (Py_ssize_t c = 0; c < C->nar; c++) {
        if (C->ar_p[c] == 0.0)
            continue;
        const double a = C->ar_a[c];
        if (C->ar_neg[c]) {
            const double need = ceil(40.0 / a);
            if (need > 64.0)
                split = 1;
            else if ((int64_t)need > kd)
                kd = (int64_t)need;
        }
        if (a >= 0.05 && N_DIRECT > kd)
            kd = N_DIRECT;
        if (2.0 * a >= 0.05 && N_DIRECT > kd2)
            kd2 = N_DIRECT;
    }
    if (split)
        kd = kd2;
    *kd_out = kd;
    *kd2_out = kd2;
    *split_out = split;
}

static double clip(double x, double lo, double hi)
{
    const double y = x >= lo ? x : lo;
    return y <= hi ? y : hi;
}

/* (sum_h N gamma, sum_h N gamma^2) for one pair of scales (_pair_sums); uj, uk, e3: scratch of
 * nar values each. */
static void pair_sums(const ctx *C, double tj, double tk, double *uj, double *uk,
                      unsigned char *e3, double *o1, double *o2)
{
    const double T = C->T;
    const double mj = tj / 2.0, mk = tk / 2.0;
    int64_t kd, kd2;
    int split_parity;
    direct_ends(C, &kd, &kd2, &split_parity);
    for (Py_ssize_t c = 0; c < C->nar; c++) {
        const double a = C->ar_a[c];
        if (C->ar_neg[c]) {
            const double phi = -exp(-a);
            uj[c] = 1.0 - ipow(phi, (int64_t)mj);
            uk[c] = 1.0 - ipow(phi, (int64_t)mk);
            e3[c] = 0;
        } else {
            uj[c] = -expm1(-a * mj);
            uk[c] = -expm1(-a * mk);
            e3[c] = a * (tj + tk) <= 2.0;
        }
    }
    const pair P = {tj, mj, tk, mk, uj, uk, e3};
    const double h_lo = tj - T, h_hi = T - tk;
    double cand[11], kinks[9], bp[11];
    int nc = 0;
    const double as[3] = {0.0, mj, tj}, bs[3] = {0.0, mk, tk};
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            cand[nc++] = as[i] - bs[k];
    cand[nc] = h_lo;
    cand[nc + 1] = h_hi;
    nc += 2;
    for (int i = 0; i < 9; i++)
        kinks[i] = clip(cand[i], h_lo, h_hi);
    for (int i = 0; i < nc; i++)
        bp[i] = clip(cand[i], h_lo, h_hi);
    sort_doubles(bp, nc);
    int nb = 0;
    for (int i = 0; i < nc; i++)
        if (nb == 0 || bp[i] != bp[nb - 1])
            bp[nb++] = bp[i];
    double s1 = 0.0, s2 = 0.0, v1, v2;
    for (int i = 0; i < nb; i++) {
        const double h = bp[i];
        point(C, &P, h, (int64_t)h & 1, &v1, &v2);
        s1 += v1;
        s2 += v2;
        if (i + 1 == nb)
            break;
        const double lo = h + 1.0;
        const int64_t n = (int64_t)(bp[i + 1] - h) - 1;
        if (n <= 0)
            continue;
        int left = 0, right = 0;
        for (int k = 0; k < 9; k++) {
            left |= kinks[k] == h;
            right |= kinks[k] == bp[i + 1];
        }
        if (split_parity) {
            for (int64_t r = 0; r < 2; r++) {
                const int64_t nr = (n - r + 1) / 2; /* n >= 1: a floor division */
                if (nr > 0) {
                    lattice_sum(C, &P, lo + (double)r, 2.0, nr, kd2, left, right, &v1, &v2);
                    s1 += v1;
                    s2 += v2;
                }
            }
        } else {
            lattice_sum(C, &P, lo, 1.0, n, kd, left, right, &v1, &v2);
            s1 += v1;
            s2 += v2;
        }
    }
    *o1 = s1;
    *o2 = s2;
}

/* ---- Python binding ------------------------------------------------------------------------ */

static PyObject *py_all_pairs(PyObject *self, PyObject *args)
{
    double T, wn, rw, qn;
    Py_buffer b[13];
    (void)self;
    memset(b, 0, sizeof(b));
    if (!PyArg_ParseTuple(args, "dy*dddy*y*y*y*y*y*y*y*y*y*w*w*", &T, &b[0], &wn, &rw, &qn, &b[1],
                          &b[2], &b[3], &b[4], &b[5], &b[6], &b[7], &b[8], &b[9], &b[10], &b[11],
                          &b[12]))
        return NULL;
    const Py_ssize_t d = (Py_ssize_t)sizeof(double);
    const Py_ssize_t J = b[0].len / d, nar = b[1].len / d;
    const char *bad = NULL;
    if (b[0].len % d || b[1].len % d || b[3].len != b[1].len || b[4].len != b[1].len
        || b[5].len != b[1].len || b[2].len != nar)
        bad = "all_pairs: tau and the AR1 arrays must be float64 (ar_neg: bool), the AR1 ones "
              "of one length";
    else if (b[6].len != b[7].len || b[9].len != b[10].len || b[6].len % d || b[8].len % d
             || b[9].len % d)
        bad = "all_pairs: bad quadrature arrays";
    else if (b[11].len != J * J * d || b[12].len != J * J * d)
        bad = "all_pairs: S1 and S2 must hold J x J float64 values";
    ctx C = {T, wn, rw, qn, nar, b[6].len / d, b[8].len / d, b[9].len / d,
             (const double *)b[1].buf, (const double *)b[3].buf, (const double *)b[4].buf,
             (const double *)b[5].buf, (const unsigned char *)b[2].buf,
             (const double *)b[6].buf, (const double *)b[7].buf, (const double *)b[8].buf,
             (const double *)b[9].buf, (const double *)b[10].buf, NULL};
    double *scratch = NULL;
    if (bad == NULL) {
        scratch = malloc((size_t)(3 + 2 * nar * C.n_grades + 2 * nar + 1) * sizeof(double)
                         + (size_t)nar + 1);
        if (scratch == NULL)
            bad = "all_pairs: out of memory";
    }
    if (bad == NULL) {
        double *uj = scratch, *uk = scratch + nar;
        C.edges = scratch + 2 * nar;
        unsigned char *e3 = (unsigned char *)(C.edges + 3 + 2 * nar * C.n_grades + 1);
        const double *tau = (const double *)b[0].buf;
        double *S1 = (double *)b[11].buf, *S2 = (double *)b[12].buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t j = 0; j < J; j++)
            for (Py_ssize_t k = j; k < J; k++) {
                double v1, v2;
                /* the larger scale first (why: gmwm/_wvcovkernels.py) */
                const double hi = tau[j] >= tau[k] ? tau[j] : tau[k];
                const double lo = tau[j] <= tau[k] ? tau[j] : tau[k];
                pair_sums(&C, hi, lo, uj, uk, e3, &v1, &v2);
                S1[j * J + k] = S1[k * J + j] = v1;
                S2[j * J + k] = S2[k * J + j] = v2;
            }
        Py_END_ALLOW_THREADS
        free(scratch);
    }
    for (int i = 0; i < 13; i++)
        PyBuffer_Release(&b[i]);
    if (bad != NULL) {
        PyErr_SetString(strstr(bad, "memory") ? PyExc_MemoryError : PyExc_ValueError, bad);
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"all_pairs", py_all_pairs, METH_VARARGS,
     "all_pairs(T, tau, wn, rw, qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm, gl_x, gl_w, grades, "
     "greg_l, greg_r, S1, S2): the lag sums (sum_h N gamma, sum_h N gamma^2) of every pair of "
     "scales written into S1 and S2 (J x J float64, C order); the same bits as "
     "gmwm._wvcovkernels.all_pairs. Releases the GIL."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_wvcov",
                                    "C kernel of the model-based WV covariance (gmwm.wvcov).",
                                    -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__wvcov(void) { return PyModule_Create(&module); }
