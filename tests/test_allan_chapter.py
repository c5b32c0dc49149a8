"""The Allan-variance chapter study (gmwm_studies.allan_chapter): exact AV identities, the
equal-AV constructions, the WN + AR1 likelihood, and the study functions at tiny sizes."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest

from gmwm.errors import InputError
from gmwm.wv import haar_coefficients
from gmwm_studies import allan_chapter as ac

ARMA_PAIRS = [(0.9, -0.5), (0.9, 0.5), (-0.6, 0.3), (0.99, 0.0), (0.0, 0.0)]


@pytest.mark.parametrize(("phi", "theta"), ARMA_PAIRS)
def test_lemma42_matches_definition_and_spectral_integral(phi, theta):
    spec = ac.arma11_spectrum(phi, theta, 1.3)
    for m in (1, 2, 3, 8, 64, 256):
        g = ac.arma11_acvf(phi, theta, 1.3, 2 * m)
        lemma = ac.av_from_acvf(g, m)
        assert ac.av_quadratic_form(g, m) == pytest.approx(lemma, rel=1e-13)
        assert ac.av_spectral(spec, m) == pytest.approx(lemma, rel=1e-11)


def test_lemma42_white_noise_and_input_check():
    g = np.r_[2.0, np.zeros(63)]
    assert ac.av_from_acvf(g, 32) == pytest.approx(2.0 / 32, rel=1e-15)
    with pytest.raises(InputError):
        ac.av_from_acvf(g[:10], 8)  # needs lags 0..15


def test_wn_ar1_is_an_arma11_and_matches_the_project_model():
    equiv = ac.arma11_as_wn_ar1(0.9, -0.5, 1.0)
    assert equiv is not None and equiv["WN[1].sigma2"] == pytest.approx(0.5 / 0.9)
    assert ac.arma11_as_wn_ar1(0.9, 0.5, 1.0) is None  # theta / phi > 0: no WN + AR1
    m = 2 ** np.arange(12)
    lemma = [ac.av_from_acvf(ac.arma11_acvf(0.9, -0.5, 1.0, 2 * k), k) for k in m]
    np.testing.assert_allclose(ac.model_av("WN+AR1", equiv, m), lemma, rtol=1e-12)


@pytest.mark.parametrize("theta", [-0.8, -0.5, 0.3, 0.9])
def test_ma1_formula_against_lemma_and_qn_wn_model(theta):
    m = np.arange(1, 130)
    closed = ac.ma1_av(theta, 2.0, m)
    lemma = [ac.av_from_acvf(ac.ma1_acvf(theta, 2.0, 2 * k), k) for k in m]
    np.testing.assert_allclose(closed, lemma, rtol=1e-14)
    qn = ac.ma1_as_qn_wn(theta, 2.0)
    assert (qn is None) == (theta >= 0)
    if qn:
        np.testing.assert_allclose(ac.model_av("QN+WN", qn, m), closed, rtol=1e-13)


def test_ma_coefficients_reproduce_the_autocovariance():
    for acv in (*ac.dyadic_pair_acvf(1.0, 0.1), ac.arma11_acvf(0.5, 0.4, 1.0, 0)[:1]):
        b = ac.ma_coefficients(acv)
        got = [float(b[: b.size - k] @ b[k:]) for k in range(len(acv))]
        np.testing.assert_allclose(got, acv, atol=1e-13)
    with pytest.raises(InputError):
        ac.ma_coefficients([1.0, 0.6])  # spectrum 1 + 1.2 cos < 0 somewhere


def _lemma_exact(d: list[Fraction], m: int) -> Fraction:
    def g(h: int) -> Fraction:
        return d[h] if h < len(d) else Fraction(0)

    return (m * (g(0) - g(m)) + sum(i * (2 * g(m - i) - g(i) - g(2 * m - i))
                                    for i in range(1, m))) / m**2


def test_dyadic_null_vector_exactly():
    d = [Fraction(int(v)) for v in ac.DYADIC_NULL]
    for m in range(1, 300):
        av = _lemma_exact(d, m)
        assert (av == 0) == (m & (m - 1) == 0 or m >= 5), m  # zero at dyadic m and all m >= 5
    # ... so two positive spectra sigma2 +- eps d have equal AV at every dyadic cluster
    x, y = ac.dyadic_pair_acvf(1.0, 0.1)
    for m in (1, 2, 4, 8, 1024):
        pad = np.zeros(2 * m)
        assert ac.av_from_acvf(np.r_[x, pad], m) == pytest.approx(
            ac.av_from_acvf(np.r_[y, pad], m), rel=1e-15)
    pad = np.zeros(6)
    assert abs(ac.av_from_acvf(np.r_[x, pad], 3) - ac.av_from_acvf(np.r_[y, pad], 3)) > 0.05
    with pytest.raises(InputError):
        ac.dyadic_pair_acvf(1.0, 0.2)  # 8 eps >= sigma2: a spectrum would go negative


def test_chapter_construction_equal_av_at_every_tau():
    ref = 4.0 * math.log(2.0)
    for tau in (2.0**-5, 1.0, 3.0, 1.37, 2.0**12):
        p = ac.flicker_av(tau, 1.0, 0.5, 1.0)
        q = ac.flicker_av(tau, 1.0, 0.5, -1.0)
        assert p == pytest.approx(q, rel=1e-13) and p == pytest.approx(ref, rel=1e-12)
    # Phi(f) = 3 Phi(3f) does not cancel: the condition is needed
    p, q = (ac.flicker_av(1.0, 1.0, 0.5, s, base=3.0) for s in (1.0, -1.0))
    assert abs(p / q - 1) > 1e-3


def test_kalman_loglike_equals_dense_and_mle_improves_on_truth():
    import gmwm

    truth = ac.MLE_SETTINGS["fast_ar1"]
    model = gmwm.Model("WN+AR1")
    x = model.simulate(model.theta(truth), 300, rng=5)
    p = (truth["AR1[1].phi"], truth["AR1[1].sigma2"], truth["WN[1].sigma2"])
    assert ac.wn_ar1_loglike(x, *p) == pytest.approx(ac.wn_ar1_loglike_dense(x, *p), rel=1e-11)
    x = model.simulate(model.theta(truth), 5000, rng=6)
    fit = ac.fit_wn_ar1_mle(x, ac.moment_start(x))
    assert fit.converged and not fit.boundary, fit.message
    assert fit.loglike >= ac.wn_ar1_loglike(x, *p)
    assert fit.loglike == pytest.approx(ac.wn_ar1_loglike(
        x, fit.params["AR1[1].phi"], fit.params["AR1[1].sigma2"], fit.params["WN[1].sigma2"]),
        abs=1e-6)
    assert abs(fit.params["AR1[1].phi"] - 0.99) < 0.01


def test_haar_levels_and_bartlett_lrv():
    rng = np.random.default_rng(3)
    x = rng.standard_normal(3000).cumsum()
    for j, w in ac.haar_levels(x, 9):
        np.testing.assert_array_equal(w, haar_coefficients(x, j))
    y = rng.standard_normal(200_000)
    assert ac.bartlett_lrv(y, 1) == pytest.approx(1.0, rel=0.02)
    # AR(1) with phi = 0.5: long-run variance (1 / (1 - phi))^2 = 4 (Bartlett bias ~ 2 / b)
    z = np.empty_like(y)
    z[0] = y[0]
    for t in range(1, y.size):
        z[t] = 0.5 * z[t - 1] + y[t]
    assert ac.bartlett_lrv(z, 400) == pytest.approx(4.0, rel=0.1)


@pytest.mark.slow
def test_study_functions_tiny():
    assert "eta3" in ac.interval_kinds()
    res = ac.adev_study("fig42", n_samples=4096, replicates=2, seed=1)
    assert list(res.replicates.replicate) == [0, 1]
    assert set(res.summary.quantity) >= {"N", "K", "slope_wn", "slope_rw", "gmwm_WN[1].sigma2"}
    n = res.summary.set_index("quantity").loc["N"]
    assert n.truth == 10.0 and abs(n.mc_mean - 10.0) < 1.0
    rd = ac.readings_table(res)
    assert list(rd.reading) == ["N", "K", "B"]

    ma1 = ac.ma1_study((-0.5,), n_samples=1024, replicates=3, seed=1, levels=5)
    assert len(ma1) == 5 and ma1.rel_lemma.max() < 1e-14 and ma1.rel_model.max() < 1e-13

    lem = ac.lemma42_study(pairs=((0.9, -0.5),), levels=6)
    assert lem.rel_spectral.max() < 1e-12 and lem.rel_project_model.max() < 1e-12

    amb = ac.ambiguity_study(levels=5, n_samples=256, replicates=2, seed=1)
    assert amb.summary["discrete_max_rel_diff_dyadic"] < 1e-14
    assert amb.summary["discrete_max_rel_diff_nondyadic"] > 0.01
    assert amb.summary["chapter_2phi2f_max_rel_diff_nondyadic"] < 1e-12

    iv, _ = ac.interval_study(n_samples=4096, replicates=3, seed=1)
    assert set(iv.interval) == {"gaussian_exact", "gaussian_eta3", "gaussian_lrv",
                                *ac.interval_kinds()}
    eta3 = iv[iv.interval == "eta3"]
    assert eta3.share_low_le_0.max() == 0.0  # chi-square intervals never leave (0, inf)
    # at the last level eta = 1 < 2 z^2: the Gaussian-variance interval's lower bound is < 0
    last = iv[(iv.interval == "gaussian_eta3") & (iv.m == iv.m.max())]
    assert float(last.share_low_le_0.iloc[0]) == 1.0

    per, summ = ac.mle_study((400,), replicates=2, settings={"fast": ac.MLE_SETTINGS["fast_ar1"]},
                             seed=1)
    assert set(summ.method) == {"gmwm", "mle", "mle_gmwm"} and (summ.replicates == 2).all()
    assert (per.loglike <= per.best_loglike + 1e-9).all()
    dense = ac.dense_cost(ac.MLE_SETTINGS["fast_ar1"], (50, 100), repeat=1)
    assert dense.abs_diff.max() < 1e-8

    numbers = {"fig41": {}, "fig42": ac.adev_numbers(res), "ma1": ac.ma1_numbers(ma1),
               "lemma42": ac.lemma42_numbers(lem), "ambiguity": amb.summary,
               "intervals": ac.interval_numbers(iv), "mle": ac.mle_numbers(summ, dense)}
    table = ac.summary_table(numbers)
    assert list(table.columns) == ["item", "quantity", "value", "reference"]
    assert {"Fig 4.2", "Example 4.2", "Lemma 4.2", "Sec 4.2.2", "Remark 4.3",
            "Example 4.1"} <= set(table["item"])
    assert pd.api.types.is_numeric_dtype(table["value"])


def test_slope_estimand_is_the_exact_av_fit_over_the_same_clusters():
    # Fig 4.2 at T = 1e5: clusters 1..16384; the RW slope is read on 4096-16384, where the WN's
    # sigma^2/m still adds, so its estimand is below the chapter's 1/2
    m = 2.0 ** np.arange(15)
    sets = ac._slope_sets("fig42", m)
    assert list(m[sets["slope_rw"]]) == [4096.0, 8192.0, 16384.0]
    av = 100.0 / m + 9e-4 * (m / 3.0 + 1.0 / (6.0 * m))
    x, y = np.log(m[sets["slope_rw"]]), 0.5 * np.log(av[sets["slope_rw"]])
    by_hand = np.sum((x - x.mean()) * (y - y.mean())) / np.sum((x - x.mean()) ** 2)
    assert by_hand == pytest.approx(0.49335, abs=1e-4)
    assert ac._slope(m, ac._av_true("fig42", m)["exact"], sets["slope_rw"]) == pytest.approx(
        by_hand, rel=1e-12)
    assert ac._slope(m, ac._av_true("fig41", m)["exact"], ac._slope_sets("fig41", m)["slope_all"]
                     ) == pytest.approx(-0.5, abs=1e-12)
