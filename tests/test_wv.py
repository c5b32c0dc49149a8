"""Tests for gmwm.wv: exactness against exact rational arithmetic, independent references,
chi-square CI, Monte Carlo moments and coverage, Allan variance relation, input validation."""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction
from functools import cache
from itertools import accumulate

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view
from scipy.stats import chi2

from conftest import needs_c_kernel
from gmwm.errors import GMWMError, InputError
from gmwm.wv import AllanVariance, WaveletVariance, Workspace, avar, wvar, wvar_many

# --------------------------------------------------------------------------------------------------
# references


def exact_wv(x: np.ndarray, J: int) -> np.ndarray:
    """WV from the partial-sum form in exact integer arithmetic (float64 samples are dyadic
    rationals, so scaling by a common 2**E makes every partial sum an exact Python int)."""
    ratios = [float(v).as_integer_ratio() for v in x]
    E = max(d.bit_length() - 1 for _, d in ratios)
    ints = [num << (E - (d.bit_length() - 1)) for num, d in ratios]
    S = [0, *accumulate(ints)]
    T = len(x)
    out = []
    for j in range(1, J + 1):
        tau, m = 2**j, 2 ** (j - 1)
        total = sum((S[t] - 2 * S[t - m] + S[t - tau]) ** 2 for t in range(tau, T + 1))
        out.append(float(Fraction(total, tau**2 * 4**E * (T - tau + 1))))
    return np.array(out)


def direct_wv(x: np.ndarray, J: int) -> np.ndarray:
    """Slow direct filter sums of the definition (docs/METHODS.md §2.1), O(T tau) per level."""
    out = []
    for j in range(1, J + 1):
        tau, m = 2**j, 2 ** (j - 1)
        win = sliding_window_view(x, tau)            # row t: x[t .. t+tau-1], newest last
        w = (win[:, m:].sum(axis=1) - win[:, :m].sum(axis=1)) / tau
        out.append(np.mean(w * w))
    return np.array(out)


def longdouble_pyramid(x: np.ndarray, J: int) -> np.ndarray:
    """The local-average recursion vectorised in extended precision."""
    v = np.asarray(x, dtype=np.longdouble) - np.longdouble(x[0])
    out = []
    for j in range(1, J + 1):
        m = 2 ** (j - 1)
        a, b = v[m:], v[:-m]
        out.append(float(np.mean(((a - b) / 2) ** 2)))
        v = (a + b) / 2                       # v[i] is now V_j at original index i + 2m - 1
    return np.array(out)


def naive_cumsum_wv(x: np.ndarray, J: int) -> np.ndarray:
    """Global cumulative sum without demeaning: the numerically poor form the module avoids."""
    S = np.concatenate(([0.0], np.cumsum(x)))
    T = x.size
    out = []
    for j in range(1, J + 1):
        tau, m = 2**j, 2 ** (j - 1)
        w = (S[tau:] - 2 * S[m:T + 1 - m] + S[:T + 1 - tau]) / tau
        out.append(np.mean(w * w))
    return np.array(out)


@cache
def hard_signals(T: int = 4000) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(20240601)
    return {
        "offset 1e6 x noise": 1e6 + rng.standard_normal(T),
        "RW(1) + WN(1e-4)": np.cumsum(rng.standard_normal(T)) + 1e-2 * rng.standard_normal(T),
        "drift + RW + offset": 3e5 + 0.7 * np.arange(T) + np.cumsum(rng.standard_normal(T)),
    }


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / np.abs(b)))


# --------------------------------------------------------------------------------------------------
# exactness and agreement with independent implementations


# (L, block, panel) layouts of the two-phase kernel: None = default (one block for T = 4000), then
# many short blocks with halos and several interleaved sub-series panels, incl. a ragged last panel
LAYOUTS = [None, (2, 37, 3), (5, 100, 8), (7, 1000, 5)]


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("name", list(hard_signals()))
def test_exact_rational_reference_on_hard_signals(name: str, layout: tuple | None) -> None:
    x = hard_signals()[name]
    J = int(np.floor(np.log2(x.size)))           # every scale, including M_J = T - 2**J + 1 small
    ref = exact_wv(x, J)
    if layout is None:
        got = wvar(x, J).variance
    else:
        n = x.size - 2.0 ** np.arange(1, J + 1) + 1
        got = 0.25 * Workspace(x.size, J, *layout).sums(x, J) / n
    # acceptance criterion is 1e-9; the pyramid is measured at ~4e-16, so assert a tighter bound
    assert rel_err(got, ref) < 1e-12


def test_exactness_check_detects_a_global_cumsum() -> None:
    # the reference above must be able to fail: the undemeaned global cumulative sum is off
    x = hard_signals()["offset 1e6 x noise"]
    assert rel_err(naive_cumsum_wv(x, 11), exact_wv(x, 11)) > 1e-9


@pytest.mark.parametrize("T", [4, 5, 7, 8, 9, 31, 33, 100, 257, 1000, 1025, 2047, 3001])
def test_matches_direct_filter_all_levels(T: int) -> None:
    rng = np.random.default_rng(T)
    x = rng.standard_normal(T) + np.cumsum(rng.standard_normal(T))
    J = int(np.floor(np.log2(T)))
    for levels in range(1, J + 1):
        np.testing.assert_allclose(wvar(x, levels).variance, direct_wv(x, levels), rtol=1e-11)


@pytest.mark.parametrize(("T", "J"), [(2**16, 16), (2**17 + 11, 17), (300_007, 18), (300_007, 3),
                                    (300_007, 12)])
def test_matches_longdouble_pyramid_long_signals(T: int, J: int) -> None:
    # default layout on long signals: many blocks, many interleaved sub-series panels, and (J <= 11)
    # the blocked phase only
    rng = np.random.default_rng(7)
    x = 50.0 + np.cumsum(rng.standard_normal(T)) + rng.standard_normal(T)
    assert rel_err(wvar(x, J).variance, longdouble_pyramid(x, J)) < 1e-12


def test_default_levels_and_counts() -> None:
    x = np.random.default_rng(0).standard_normal(5000)
    wv = wvar(x)
    J = int(np.floor(np.log2(5000))) - 1           # default floor(log2 T) - 1 = 11
    assert wv.n_levels == J == 11
    np.testing.assert_array_equal(wv.levels, np.arange(1, J + 1))
    np.testing.assert_array_equal(wv.scales, 2.0 ** np.arange(1, J + 1))
    np.testing.assert_array_equal(wv.n, 5000 - 2 ** np.arange(1, J + 1) + 1)
    assert wv.n_samples == 5000


def test_offset_invariance_and_no_demeaning_of_coefficients() -> None:
    rng = np.random.default_rng(3)
    x = rng.standard_normal(2000)
    np.testing.assert_allclose(wvar(x + 123.0).variance, wvar(x).variance, rtol=1e-12)
    # a drift gives constant non-zero coefficients: nu_j = omega^2 tau^2 / 16 exactly
    omega = 1e-3
    t = np.arange(1, 2**14 + 1, dtype=float)
    wv = wvar(omega * t, 13)
    np.testing.assert_allclose(wv.variance, omega**2 * wv.scales**2 / 16, rtol=1e-12)


def test_wvar_many_equals_wvar_rows() -> None:
    rng = np.random.default_rng(11)
    X = np.cumsum(rng.standard_normal((5, 3000)), axis=1)
    got = wvar_many(X, 9)
    assert got.shape == (5, 9)
    for r in range(5):
        np.testing.assert_array_equal(got[r], wvar(X[r], 9).variance)
    assert wvar_many(X).shape == (5, int(np.floor(np.log2(3000))) - 1)


# --------------------------------------------------------------------------------------------------
# confidence intervals


def test_ci_formula_against_scipy() -> None:
    x = np.random.default_rng(5).standard_normal(3000)
    for alpha in (0.05, 0.1):
        wv = wvar(x, 11, alpha=alpha, ci="eta3")
        eta = np.maximum((3000 - 2.0 ** np.arange(1, 12) + 1) / 2.0 ** np.arange(1, 12), 1.0)
        np.testing.assert_allclose(wv.edof, eta, rtol=1e-15)
        assert not np.all(eta == np.round(eta))                 # non-integer dof are used
        for j in range(11):
            lo = eta[j] * wv.variance[j] / chi2.ppf(1 - alpha / 2, eta[j])
            hi = eta[j] * wv.variance[j] / chi2.ppf(alpha / 2, eta[j])
            assert wv.ci_low[j] == pytest.approx(lo, rel=1e-13)
            assert wv.ci_high[j] == pytest.approx(hi, rel=1e-13)
    assert wv.edof[-1] == 1.0                                    # M_11 / 2**11 < 1 -> floor at 1


def exact_edof(g: np.ndarray, M: int) -> float:
    """2 nu^2 / Var(nu_hat) for Gaussian W = g * eps (eps iid N(0,1)), from the exact ACVS of W."""
    s = np.correlate(g, g, mode="full")[g.size - 1:][:M]
    k = np.arange(s.size)
    var = 2.0 / M**2 * (M * s[0] ** 2 + 2.0 * np.sum((M - k[1:]) * s[1:] ** 2))
    return 2.0 * s[0] ** 2 / var


def test_ci_coverage_white_noise() -> None:
    # eta_3 = M/2^j is conservative for WN: the exact edof (from the ACVS of W) is ~3x larger, so the
    # coverage is ~0.976 at j=1 and ~0.999 for j>=3, not 0.95. We predict it by treating nu_hat as
    # nu chi2(eta_exact)/eta_exact and require the MC coverage within 3 binomial SEs
    # sqrt(p(1-p)/R) of the prediction (+0.004 for the chi-square approximation), and >= nominal.
    R, T, sigma2 = 400, 2**12, 2.5
    rng = np.random.default_rng(2024)
    X = np.sqrt(sigma2) * rng.standard_normal((R, T))
    nu = wvar_many(X, 10)
    for j in (1, 2, 6):
        tau, M = 2**j, T - 2**j + 1
        eta3 = max(M / tau, 1.0)
        low = eta3 * nu[:, j - 1] / chi2.ppf(0.975, eta3)
        high = eta3 * nu[:, j - 1] / chi2.ppf(0.025, eta3)
        truth = sigma2 / tau
        cover = np.mean((low <= truth) & (truth <= high))
        h = np.r_[np.full(tau // 2, 1.0 / tau), np.full(tau // 2, -1.0 / tau)]
        eta = exact_edof(h, M)
        p = chi2.cdf(eta * chi2.ppf(0.975, eta3) / eta3, eta) - chi2.cdf(
            eta * chi2.ppf(0.025, eta3) / eta3, eta)
        assert abs(cover - p) <= 3 * np.sqrt(p * (1 - p) / R) + 0.004, (j, cover, p)
        assert cover >= 0.95 - 3 * np.sqrt(0.95 * 0.05 / R)


def test_ci_coverage_matches_wvar_ci() -> None:
    # the CI used in the coverage test is the one wvar returns
    x = np.random.default_rng(1).standard_normal(2**12)
    wv = wvar(x, 10, ci="eta3")
    eta3 = np.maximum(wv.n / wv.scales, 1.0)
    np.testing.assert_allclose(wv.ci_low, eta3 * wv.variance / chi2.ppf(0.975, eta3), rtol=1e-13)


# --------------------------------------------------------------------------------------------------
# Monte Carlo moments


def _mc_z(samples: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """z-scores of the MC mean against the truth; MC SE = sample SD / sqrt(R)."""
    se = samples.std(axis=0, ddof=1) / np.sqrt(samples.shape[0])
    return (samples.mean(axis=0) - truth) / se


def test_mean_white_noise_and_random_walk() -> None:
    # unbiasedness E nu_hat = nu: |z| < 4 at every level (P(|z|>4) ~ 6e-5 per check under H0)
    R, T, J = 300, 2**12, 9
    rng = np.random.default_rng(99)
    tau = 2.0 ** np.arange(1, J + 1)
    sigma2, gamma2 = 2.0, 0.3
    wn = wvar_many(np.sqrt(sigma2) * rng.standard_normal((R, T)), J)
    assert np.all(np.abs(_mc_z(wn, sigma2 / tau)) < 4)
    rw = wvar_many(np.cumsum(np.sqrt(gamma2) * rng.standard_normal((R, T)), axis=1), J)
    assert np.all(np.abs(_mc_z(rw, gamma2 * (tau**2 + 2) / (12 * tau))) < 4)
    # the test has power: a 5 % bias at level 1 (MC SE ~0.2 %) would give |z| >> 4
    assert np.abs(_mc_z(wn, 1.05 * sigma2 / tau)[0]) > 4


# --------------------------------------------------------------------------------------------------
# Allan variance


def test_avar_is_twice_wv_and_matches_definition() -> None:
    rng = np.random.default_rng(8)
    x = 10.0 + np.cumsum(rng.standard_normal(3000)) * 0.1 + rng.standard_normal(3000)
    freq = 200.0
    wv = wvar(x, 10, freq=freq)
    av = avar(x, 10, freq=freq)
    np.testing.assert_array_equal(av.avar, 2.0 * wv.variance)
    np.testing.assert_array_equal(av.ci_low, 2.0 * wv.ci_low)
    np.testing.assert_array_equal(av.ci_high, 2.0 * wv.ci_high)
    np.testing.assert_array_equal(av.clusters, 2 ** np.arange(10))
    np.testing.assert_allclose(av.tau, 2.0 ** np.arange(10) / freq, rtol=0)
    np.testing.assert_allclose(av.adev, np.sqrt(av.avar), rtol=0)
    # maximal-overlap AV straight from its definition (docs/METHODS.md §2.4), independent of the WV code
    for m, value in zip(av.clusters, av.avar):
        means = sliding_window_view(x, m).mean(axis=1)          # cluster mean ending at k
        d = means[m:] - means[:-m]
        assert value == pytest.approx(np.sum(d * d) / (2 * (x.size - 2 * m + 1)), rel=1e-12)
    json.dumps(av.to_dict())
    assert AllanVariance.from_wv(wv).avar.tolist() == av.avar.tolist()
    with pytest.raises(ValueError):
        av.avar[0] = 1.0                                         # read-only like the WV
    with pytest.raises(InputError, match="one entry per level"):
        AllanVariance([1, 2], [1, 2], [1.0, 2.0], [1.0], [0.5], [2.0], [99], 100)


# --------------------------------------------------------------------------------------------------
# container behaviour


def test_container_properties_subset_to_dict() -> None:
    wv = wvar(np.random.default_rng(4).standard_normal(4096), 10, freq=100.0)
    np.testing.assert_array_equal(wv.scales_s, wv.scales / 100.0)
    np.testing.assert_array_equal(wv.edof, np.maximum(wv.n / wv.scales, 1))
    with pytest.raises(dataclasses.FrozenInstanceError):
        wv.alpha = 0.1  # type: ignore[misc]
    with pytest.raises(ValueError):
        wv.variance[0] = 1.0
    sub = wv.subset([2, 5, 7])
    np.testing.assert_array_equal(sub.levels, [2, 5, 7])
    np.testing.assert_array_equal(sub.variance, wv.variance[[1, 4, 6]])
    np.testing.assert_array_equal(sub.ci_high, wv.ci_high[[1, 4, 6]])
    assert wv.subset(4).n_levels == 4 and wv.subset(4).levels[-1] == 4
    with pytest.raises(InputError, match="levels \\[11\\]"):
        wv.subset([3, 11])
    with pytest.raises(InputError):
        wv.subset(0)
    d = json.loads(json.dumps(wv.to_dict()))
    assert d["variance"] == wv.variance.tolist() and d["n_samples"] == 4096 and d["freq"] == 100.0
    assert d["levels"] == list(range(1, 11))


def test_from_table_recomputes_n_and_ci() -> None:
    wv = wvar(np.random.default_rng(6).standard_normal(5000), 11, alpha=0.1, freq=2.0)
    tab = WaveletVariance.from_table(wv.scales, wv.variance, n_samples=5000, freq=2.0, alpha=0.1)
    np.testing.assert_array_equal(tab.n, wv.n)
    np.testing.assert_array_equal(tab.levels, wv.levels)
    np.testing.assert_allclose(tab.ci_low, wv.ci_low, rtol=1e-14)
    np.testing.assert_allclose(tab.ci_high, wv.ci_high, rtol=1e-14)
    given = WaveletVariance.from_table([4, 16], [1.0, 0.5], [0.8, 0.3], [1.3, 0.9], n_samples=100)
    np.testing.assert_array_equal(given.levels, [2, 4])
    np.testing.assert_array_equal(given.ci_low, [0.8, 0.3])
    np.testing.assert_array_equal(given.n, [97, 85])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scales": [2, 6], "variance": [1, 1]}, "powers of 2"),
        ({"scales": [4, 2], "variance": [1, 1]}, "increasing"),
        ({"scales": [2, 4], "variance": [1, 0]}, "positive"),
        ({"scales": [2, 4], "variance": [1]}, "as many"),
        ({"scales": [1, 2], "variance": [1, 1]}, ">= 2"),
        ({"scales": [2, 4], "variance": [1, 1], "ci_low": [0.5, 0.5]}, "both"),
        ({"scales": [2, 4], "variance": [1, 1], "ci_low": [0.5, 2], "ci_high": [2, 3]},
         "ci_low <= variance"),
        ({"scales": [2, 4, 256], "variance": [1, 1, 1]}, "n_samples"),
    ],
)
def test_from_table_rejects_bad_tables(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        WaveletVariance.from_table(**kwargs, n_samples=100)


# --------------------------------------------------------------------------------------------------
# input validation


def test_bad_inputs() -> None:
    x = np.random.default_rng(0).standard_normal(1000)
    bad = x.copy()
    bad[[3, 50, 700]] = np.nan
    with pytest.raises(InputError, match="signal contains 3 NaN values"):
        wvar(bad)
    bad[[3, 50, 700]] = [np.inf, -np.inf, 1.0]
    with pytest.raises(InputError, match="2 infinite values"):
        wvar(bad)
    with pytest.raises(InputError, match="1-D"):
        wvar(x.reshape(10, 100))
    with pytest.raises(InputError, match="T=3"):
        wvar(x[:3])
    with pytest.raises(InputError, match=r"T=1000.*J=9.*J=11"):
        wvar(x, 11)
    with pytest.raises(InputError, match=">= 1"):
        wvar(x, 0)
    with pytest.raises(InputError, match="integer"):
        wvar(x, 2.5)
    with pytest.raises(InputError, match="alpha"):
        wvar(x, alpha=1.5)
    with pytest.raises(InputError, match="freq"):
        wvar(x, freq=0.0)
    with pytest.raises(InputError, match="numeric"):
        wvar(["a", "b", "c", "d"])
    with pytest.raises(InputError, match="complex"):
        wvar(x + 1j)
    with pytest.raises(InputError, match="overflow"):
        wvar(np.r_[1e300, -1e300, 1e300, -1e300, 1.0])
    X = np.random.default_rng(1).standard_normal((3, 64))
    X[1, 5] = np.nan
    with pytest.raises(InputError, match=r"X\[1\] contains 1 NaN values"):
        wvar_many(X)
    with pytest.raises(InputError, match="2-D"):
        wvar_many(x)
    with pytest.raises(GMWMError):                   # GMWMError is a ValueError subclass
        avar(x, 20)
    assert wvar(x.tolist(), 3).n_levels == 3         # lists are fine
    np.testing.assert_array_equal(wvar(x[::3]).variance, wvar(x[::3].copy()).variance)  # strided
    np.testing.assert_allclose(wvar(x.astype(np.float32)).variance,
                               wvar(x.astype(np.float32).astype(float)).variance, rtol=0)
    assert wvar(np.arange(8), 3).variance[0] == pytest.approx(0.25)   # ints are fine


# ---- the C kernel and its Numba twin -------------------------------------------------------------


@needs_c_kernel
def test_c_kernel_is_built() -> None:
    # the fallback is for installs without a C compiler; this project's own installs have one
    from gmwm.wv import kernel_name, load_kernel

    assert load_kernel() == "c" and kernel_name() == "c"


def _kernel_cases():
    rng = np.random.default_rng(11)
    cases = [(T, J, None) for T in (4, 5, 7, 31, 32, 33, 35, 63, 64, 65, 100, 129, 255, 1000)
             for J in sorted({1, T.bit_length() - 2 or 1, T.bit_length() - 1})]
    cases += [(4097, 11, None), (100_003, 15, None), (300_007, 18, None), (5000, 12, (3, 40, 2)),
              (70_000, 15, (5, 1000, 1)), (123_457, 16, (2, 64, 2)), (20_011, 14, (4, 48, 3)),
              (300_007, 18, (9, 8 << 9, 16))]
    for i, (T, J, layout) in enumerate(cases):
        x = rng.standard_normal(T)
        if i % 3 == 1:
            x = np.cumsum(x) + 1e6      # random walk on a large offset
        elif i % 3 == 2:
            x = 5.0 + 1e-3 * x          # small noise on an offset
        yield T, J, layout, x


def _numba_sums(x: np.ndarray, J: int, ws: Workspace) -> np.ndarray:
    from gmwm import _wvkernels

    out = np.zeros(J)
    store = ws.store()
    _wvkernels.phase1(x, 0, 0, ws.T, float(x[0]), ws.n_block, ws.block, out, store, 0, ws.rows,
                      ws.panel)
    if ws.phase2:
        _wvkernels.phase2(store, ws.rows, ws.n_out, ws.n_block, ws.panel, 0, ws.n_panels,
                          J - ws.n_block, out)
    return out


@needs_c_kernel
def test_c_kernel_matches_numba_kernel_bit_for_bit() -> None:
    # same operations in the same order (explicit 16-lane sums, blocks and panels added in order):
    # identical bits on any IEEE-754 host, for any number of threads
    n_cases = 0
    for T, J, layout, x in _kernel_cases():
        ws = Workspace(T, J, *(layout or ()))
        ref = _numba_sums(x, J, ws)
        for threads in (1, 2, 3):
            got = ws.sums(x, J, threads=threads)
            assert np.array_equal(got, ref), (T, J, layout, threads)
        n_cases += 1
    assert n_cases > 40


@needs_c_kernel
def test_c_kernel_rejects_work_arrays_that_do_not_fit() -> None:
    from gmwm import _haar

    x = np.zeros(1000)
    ws = Workspace(1000, 8, 4)
    store = np.empty(ws.rows << ws.n_block)
    with pytest.raises(ValueError, match="sums is shorter"):
        _haar.phase1(x, 0, 0, 1000, 0.0, ws.n_block, ws.block, np.zeros(3), store, 0, ws.rows,
                     ws.panel, 1)
    with pytest.raises(ValueError, match="do not cover"):
        _haar.phase1(x[:500], 0, 0, 1000, 0.0, ws.n_block, ws.block, np.zeros(8), store, 0,
                     ws.rows, ws.panel, 1)
    with pytest.raises(ValueError, match="multiple of the block"):
        _haar.phase1(x, 0, 3, 1000, 0.0, ws.n_block, ws.block, np.zeros(8), store, 0, ws.rows,
                     ws.panel, 1)
    with pytest.raises(ValueError, match="store does not hold"):
        _haar.phase1(x, 0, 0, 1000, 0.0, ws.n_block, ws.block, np.zeros(8), store[:10], 0,
                     ws.rows, ws.panel, 1)
    with pytest.raises(ValueError, match="panel range"):
        _haar.phase2(store, ws.rows, ws.n_out, ws.n_block, ws.panel, 0, 99, 4, np.zeros(8), 1)
    with pytest.raises(ValueError, match="shorter than its panels"):
        _haar.phase2(store[:10], ws.rows, ws.n_out, ws.n_block, ws.panel, 0, ws.n_panels, 4,
                     np.zeros(8), 1)


def test_exact_under_large_offset_long_signal() -> None:
    # a 1e8 offset on a random walk with tiny white noise: the pyramid subtracts sample 0 first,
    # so every level matches the extended-precision reference (a global cumulative sum would
    # lose ~8 digits here)
    rng = np.random.default_rng(17)
    T = 2**18 + 123
    x = 1e8 + np.cumsum(1e-3 * rng.standard_normal(T)) + 1e-6 * rng.standard_normal(T)
    J = 17
    assert rel_err(wvar(x, J).variance, longdouble_pyramid(x, J)) < 1e-12
    assert rel_err(naive_cumsum_wv(x, J), longdouble_pyramid(x, J)) > 1e-9


def test_numba_fallback_gives_the_c_bits(monkeypatch: pytest.MonkeyPatch) -> None:
    # without the C extension wvar uses the Numba twins; the WV is the same to the bit
    import gmwm.wv as wv_mod
    from gmwm import _wvkernels

    x = 3e5 + np.cumsum(np.random.default_rng(5).standard_normal(200_003))
    ref = wvar(x).variance
    monkeypatch.setattr(wv_mod, "classical_kernels", lambda: _wvkernels)
    assert wv_mod.kernel_name() == "numba"
    np.testing.assert_array_equal(wvar(x).variance, ref)


def test_thread_count_does_not_change_the_bits(monkeypatch: pytest.MonkeyPatch) -> None:
    x = np.cumsum(np.random.default_rng(6).standard_normal(400_001))
    monkeypatch.setenv("GMWM_NUM_THREADS", "1")
    one = wvar(x).variance
    monkeypatch.setenv("GMWM_NUM_THREADS", "3")
    np.testing.assert_array_equal(wvar(x).variance, one)
    monkeypatch.setenv("GMWM_NUM_THREADS", "many")
    with pytest.raises(InputError, match="GMWM_NUM_THREADS"):
        wvar(x)
