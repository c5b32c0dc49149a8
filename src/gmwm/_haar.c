/* Classical Haar (MODWT) wavelet-variance sums: the C twin of the Numba kernel
 * gmwm._wvkernels.wv_sums, loaded without Numba's runtime so that `gmwm wv` does not pay Numba's
 * start-up (~0.6 s) for a 0.15 s computation.
 *
 * Same algorithm and the same floating-point operations in the same order as the Numba kernel
 * compiled for a host where LLVM vectorises with 512-bit registers (AMD Zen 4/5, the machine the
 * reports are made on; LLVM keeps 256-bit vectors on most Intel AVX-512 parts): the element-wise
 * values are one add, one subtraction and an exact halving; the sum of squares follows the lane
 * layout LLVM chose for the `reassoc` reduction, written out here as explicit partial sums. On
 * such a host both kernels give identical bits (tests/test_wv.py checks it); the order below is
 * fixed, so this kernel gives those bits on any IEEE-754 machine. Build with -ffp-contract=off:
 * a fused multiply-add would change the bits.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>

/* Averages only: dst[t] = (src[t] + src[t - lag]) / 2 for t in [lo, hi). */
static void level_avg(const double *src, double *dst, Py_ssize_t lo, Py_ssize_t hi,
                      Py_ssize_t lag)
{
    const double *cur = src + lo, *prev = src + lo - lag;
    double *out = dst + lo;
    for (Py_ssize_t i = 0; i < hi - lo; i++)
        out[i] = 0.5 * (cur[i] + prev[i]);
}

/* One pyramid level on [lo, hi): dst[t] = (src[t] + src[t - lag]) / 2; returns
 * sum (src[t] - src[t - lag])^2. The partial sums reproduce the vectorised loop: 32-element
 * strips into 4 x 8 lanes, combined (((A0 + A1) + A2) + A3) then halved 8 -> 4 -> 2 -> 1; a
 * 4-lane strip loop seeded with that sum in lane 0 while >= 4 elements remain (reduced
 * (b0 + b2) + (b1 + b3)); then one element at a time. Fewer than 4 elements, or an output that
 * starts less than 256 bytes after either input, take the plain sequential sum (LLVM's
 * short-trip and alias guards). */
static double level_step(const double *src, double *dst, Py_ssize_t lo, Py_ssize_t hi,
                         Py_ssize_t lag)
{
    const double *cur = src + lo, *prev = src + lo - lag;
    double *out = dst + lo;
    const Py_ssize_t n = hi - lo;
    double acc = 0.0;
    Py_ssize_t i = 0;
    if (n <= 0)
        return 0.0;
    const uintptr_t po = (uintptr_t)out;
    const int vector = n >= 4 && po - (uintptr_t)prev >= 256 && po - (uintptr_t)cur >= 256;
    if (vector) {
        const Py_ssize_t n32 = n & ~(Py_ssize_t)31, n4 = n & ~(Py_ssize_t)3;
        if (n32 > 0) {
            double a[4][8] = {{0.0}};
            for (; i < n32; i += 32)
                for (int k = 0; k < 4; k++)
                    for (int l = 0; l < 8; l++) {
                        const Py_ssize_t e = i + 8 * k + l;
                        const double x = cur[e], y = prev[e], d = x - y;
                        a[k][l] += d * d;
                        out[e] = 0.5 * (x + y);
                    }
            double s[8], h[4];
            for (int l = 0; l < 8; l++)
                s[l] = a[3][l] + (a[2][l] + (a[1][l] + a[0][l]));
            for (int l = 0; l < 4; l++)
                h[l] = s[l] + s[l + 4];
            acc = (h[0] + h[2]) + (h[1] + h[3]);
        }
        if (n4 > i) {
            double b[4] = {acc, 0.0, 0.0, 0.0};
            for (; i < n4; i += 4)
                for (int l = 0; l < 4; l++) {
                    const double x = cur[i + l], y = prev[i + l], d = x - y;
                    b[l] += d * d;
                    out[i + l] = 0.5 * (x + y);
                }
            acc = (b[0] + b[2]) + (b[1] + b[3]);
        }
    }
    for (; i < n; i++) {
        const double x = cur[i], y = prev[i], d = x - y;
        acc += d * d;
        out[i] = 0.5 * (x + y);
    }
    return acc;
}

/* Levels 1..n_levels on a[:n], lags in multiples of `unit`, ping-ponging between a and b; squared
 * differences at positions >= acc_from are added to sums[first + j - 1]. Returns 0 if the last
 * level's averages are in a, 1 if in b. */
static int pyramid(double *a, double *b, Py_ssize_t n, Py_ssize_t n_levels, Py_ssize_t unit,
                   Py_ssize_t acc_from, double *sums, Py_ssize_t first)
{
    double *src = a, *dst = b, *tmp;
    int which = 0;
    for (Py_ssize_t j = 1; j <= n_levels; j++) {
        const Py_ssize_t lag = unit << (j - 1);
        const Py_ssize_t lo = 2 * lag - unit;
        if (lo >= n)
            break;
        const Py_ssize_t acc_lo = lo > acc_from ? lo : acc_from;
        if (acc_lo > lo)
            level_avg(src, dst, lo, acc_lo < n ? acc_lo : n, lag);
        if (acc_lo < n)
            sums[first + j - 1] += level_step(src, dst, acc_lo, n, lag);
        tmp = src; src = dst; dst = tmp;
        which = 1 - which;
    }
    return which;
}

/* Phase 1 on time blocks with a recomputed halo, phase 2 on interleaved sub-series of V_L (see
 * gmwm.wv's module docstring); the work arrays come from gmwm.wv._Workspace. */
static void wv_sums(const double *x, Py_ssize_t T, Py_ssize_t n_levels, Py_ssize_t L,
                    double *sums, double *buf_a, double *buf_b, Py_ssize_t buf_len, double *v_l,
                    double *pan_a, double *pan_b, Py_ssize_t pan_len)
{
    const Py_ssize_t halo = ((Py_ssize_t)1 << L) - 1;
    const Py_ssize_t block = buf_len - halo;
    const double x0 = x[0];
    for (Py_ssize_t b0 = 0; b0 < T;) {
        const Py_ssize_t b1 = b0 + block < T ? b0 + block : T;
        const Py_ssize_t s0 = b0 - halo > 0 ? b0 - halo : 0;
        const Py_ssize_t n = b1 - s0;
        for (Py_ssize_t i = 0; i < n; i++)
            buf_a[i] = x[s0 + i] - x0;
        const int which = pyramid(buf_a, buf_b, n, L, 1, b0 - s0, sums, 0);
        if (n_levels > L) {
            const double *src = which == 0 ? buf_a : buf_b;
            for (Py_ssize_t t = b0 > halo ? b0 : halo; t < b1; t++)
                v_l[t - halo] = src[t - s0];
        }
        b0 = b1;
    }
    if (n_levels <= L)
        return;
    const Py_ssize_t P = halo + 1, n_out = T - halo;
    const Py_ssize_t rows = (n_out + P - 1) / P;
    const Py_ssize_t width = pan_len / rows < P ? pan_len / rows : P;
    for (Py_ssize_t r0 = 0; r0 < P;) {
        const Py_ssize_t c = width < P - r0 ? width : P - r0;
        Py_ssize_t last = n_out - (rows - 1) * P - r0;
        last = last > 0 ? last : 0;
        last = last < c ? last : c;
        for (Py_ssize_t k = 0; k < rows - 1; k++)
            for (Py_ssize_t ci = 0; ci < c; ci++)
                pan_a[k * c + ci] = v_l[k * P + r0 + ci];
        for (Py_ssize_t ci = 0; ci < last; ci++)
            pan_a[(rows - 1) * c + ci] = v_l[(rows - 1) * P + r0 + ci];
        pyramid(pan_a, pan_b, (rows - 1) * c + last, n_levels - L, c, 0, sums, L);
        r0 += c;
    }
}

static PyObject *py_wv_sums(PyObject *self, PyObject *args)
{
    Py_buffer x, sums, buf_a, buf_b, v_l, pan_a, pan_b;
    Py_ssize_t n_levels, L;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnw*w*w*w*w*w*", &x, &n_levels, &L, &sums, &buf_a, &buf_b,
                          &v_l, &pan_a, &pan_b))
        return NULL;
    const Py_ssize_t T = x.len / (Py_ssize_t)sizeof(double);
    const Py_ssize_t halo = ((Py_ssize_t)1 << L) - 1;
    const Py_ssize_t buf_len = buf_a.len / (Py_ssize_t)sizeof(double);
    const Py_ssize_t pan_len = pan_a.len / (Py_ssize_t)sizeof(double);
    const char *bad = NULL;
    if (T < 2 || L < 1 || n_levels < L || n_levels > 62 || ((Py_ssize_t)1 << n_levels) > T)
        bad = "wv_sums: bad signal length or level counts";
    else if (sums.len < n_levels * (Py_ssize_t)sizeof(double))
        bad = "wv_sums: sums is shorter than n_levels";
    else if (buf_len <= halo || buf_b.len != buf_a.len)
        bad = "wv_sums: block buffers are too short or of different lengths";
    else if (n_levels > L && (v_l.len < (T - halo) * (Py_ssize_t)sizeof(double)
                              || pan_b.len != pan_a.len || pan_len < T / (halo + 1)))  /* rows */
        bad = "wv_sums: phase-2 work arrays are too short";
    if (bad == NULL) {
        Py_BEGIN_ALLOW_THREADS
        wv_sums((const double *)x.buf, T, n_levels, L, (double *)sums.buf, (double *)buf_a.buf,
                (double *)buf_b.buf, buf_len, (double *)v_l.buf, (double *)pan_a.buf,
                (double *)pan_b.buf, pan_len);
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&x);
    PyBuffer_Release(&sums);
    PyBuffer_Release(&buf_a);
    PyBuffer_Release(&buf_b);
    PyBuffer_Release(&v_l);
    PyBuffer_Release(&pan_a);
    PyBuffer_Release(&pan_b);
    if (bad != NULL) {
        PyErr_SetString(PyExc_ValueError, bad);
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"wv_sums", py_wv_sums, METH_VARARGS,
     "wv_sums(x, n_levels, n_block, sums, buf_a, buf_b, v_l, pan_a, pan_b): add "
     "sum_t (2 W_jt)^2 over the boundary-free Haar coefficients of the float64 signal x to "
     "sums[j-1] (work arrays: gmwm.wv._Workspace). Releases the GIL."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_haar",
                                    "C kernel of the classical Haar wavelet variance.", -1,
                                    methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__haar(void) { return PyModule_Create(&module); }
