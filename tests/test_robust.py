"""Robust wavelet variance (gmwm.wv.wvar(..., robust=True)) and the --robust CLI option.

Tolerances come from Monte Carlo runs of the same settings (30 seeds, noted at each test)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import gmwm
from gmwm._wvkernels import m_scale
from gmwm.cli import main
from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.wv import _start_scale, biweight_tuning, haar_coefficients, wvar

WN_RW = Model("WN+RW")
TRUTH = WN_RW.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4})


def _burst(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Five bursts of 64 samples of N(0, 30^2) added (about 1 % of 2^15 samples)."""
    x = x.copy()
    for s in rng.choice(x.size - 64, 5, replace=False):
        x[s:s + 64] += 30.0 * rng.standard_normal(64)
    return x


def _fit(data):
    # the penalty-free estimate; se_cov only changes the standard errors
    return gmwm.fit(data, WN_RW, se_cov="gaussian") if "se_cov" in \
        gmwm.fit.__code__.co_varnames else gmwm.fit(data, WN_RW)


def test_haar_coefficients_match_classical_wv() -> None:
    x = np.random.default_rng(1).standard_normal(3000).cumsum()
    wv = wvar(x)
    for j in (1, 4, 9):
        w = haar_coefficients(x, j)
        assert w.size == 3000 - 2**j + 1
        np.testing.assert_allclose(np.mean(w * w), wv.variance[j - 1], rtol=1e-12)


@pytest.mark.parametrize("eff", [0.3, 0.6, 0.9])
def test_biweight_efficiency_matches_monte_carlo(eff: float) -> None:
    """Var(mean square) / Var(M-scale) on iid N(0,1) samples equals the requested efficiency.
    800 replicates: the variance ratio has a relative MC error of about 7 %; allow 20 %."""
    c, b, bdp = biweight_tuning(eff)
    assert 0 < bdp <= 0.5 and c > 0
    rng = np.random.default_rng(np.random.SeedSequence(11))
    rob, cla = [], []
    for _ in range(800):
        w = rng.standard_normal(500)
        v = np.concatenate([[0.0], 2.0 * np.cumsum(w)])  # W_i = (v[i+1] - v[i]) / 2 = w_i
        rob.append(m_scale(v, w.size, 1, c, b, _start_scale(v, w.size, 1)))
        cla.append(np.mean(w * w))
    assert abs(np.mean(rob) - 1.0) < 0.01          # Fisher consistent (SE ~ 0.003)
    assert np.var(cla) / np.var(rob) == pytest.approx(eff, rel=0.2)


def test_tuning_rejects_bad_efficiency() -> None:
    with pytest.raises(InputError, match="efficiency"):
        wvar(np.ones(100) + np.arange(100), robust=True, eff=1.5)


def test_robust_wv_consistent_and_ci_on_clean_signal() -> None:
    """Clean WN+RW: robust and classical WV agree within the robust CI at the short scales, the
    CI uses eff * eta_3 edof, and the container records the efficiency."""
    x = WN_RW.simulate(TRUTH, 2**14, np.random.default_rng(3))
    cla = wvar(x)
    rob = wvar(x, robust=True, eff=0.6)
    assert rob.robust and not cla.robust and rob.efficiency == 0.6
    np.testing.assert_allclose(rob.edof, 0.6 * cla.edof)
    inside = (rob.ci_low[:8] <= cla.variance[:8]) & (cla.variance[:8] <= rob.ci_high[:8])
    assert inside.all()
    assert rob.to_dict()["efficiency"] == 0.6 and "efficiency" not in cla.to_dict()
    assert rob.subset(5).efficiency == 0.6


def test_robust_ci_coverage_white_noise() -> None:
    """Coverage of the 95 % robust CI for WN (true nu_j = 1 / 2^j) at levels 1-4 over 300
    replicates: eff * eta_3 is conservative, so coverage >= 95 % up to MC error (SE 1.3 %)."""
    rng = np.random.default_rng(np.random.SeedSequence(5))
    hits = np.zeros(4)
    for _ in range(300):
        wv = wvar(rng.standard_normal(2048), levels=4, robust=True)
        truth = 1.0 / wv.scales
        hits += (wv.ci_low <= truth) & (truth <= wv.ci_high)
    assert np.all(hits / 300 >= 0.92)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_robust_fit_resists_burst_contamination(seed: int) -> None:
    """WN(1) + RW(1e-4), T = 2^15, five 64-sample bursts of N(0, 30^2). Over 30 seeds (run when
    this test was written): classical WN sigma2 in [7.9, 10.8]; robust WN in [1.007, 1.060],
    robust RW gamma2 in [0.92e-4, 1.6e-4]."""
    rng = np.random.default_rng([7, seed])
    x = _burst(WN_RW.simulate(TRUTH, 2**15, rng), rng)
    classical = _fit(x).params
    robust = _fit(wvar(x, robust=True)).params
    assert classical[0] > 5.0
    assert 0.95 < robust[0] < 1.12
    assert 0.5e-4 < robust[1] < 2.2e-4


def test_cli_robust_fit_and_wv(tmp_path, capsys) -> None:
    rng = np.random.default_rng([7, 0])
    x = _burst(WN_RW.simulate(TRUTH, 2**15, rng), rng)
    path = tmp_path / "x.npy"
    np.save(path, x)
    assert main(["fit", str(path), "WN+RW", "--robust", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert 0.95 < out["params"]["WN[1].sigma2"] < 1.12
    assert main(["wv", str(path), "--robust", "--eff", "0.5", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    robust = d["variance"]
    assert d["robust"] is True and d["efficiency"] == 0.5
    assert main(["wv", str(path), "--json"]) == 0
    classical = json.loads(capsys.readouterr().out)["variance"]
    assert robust[0] < 0.2 * classical[0]
    assert main(["wv", str(path), "--robust", "--eff", "1.5"]) == 2
    assert "0.05, 0.99" in capsys.readouterr().err


def test_robust_selection_under_bursts() -> None:
    """Model choice on a burst-contaminated WN+RW (as above), candidates WN, WN+RW, QN+WN+RW,
    WN+AR1+RW. Over 8 seeds: on the classical WV WIC-log picked WN+RW 0 times (WN+AR1+RW 4x,
    WN 2x, QN+WN+RW 2x), on the robust WV 8 times (WIC: 7 times)."""
    from gmwm.select import rank_models

    cands = ["WN", "WN+RW", "QN+WN+RW", "WN+AR1+RW"]
    rng = np.random.default_rng([7, 0])
    x = _burst(WN_RW.simulate(TRUTH, 2**15, rng), rng)
    assert rank_models(x, cands).best.model != "WN+RW"
    ranking = rank_models(x, cands, robust=True)
    assert ranking.best.model == "WN+RW" and ranking.wv.robust
