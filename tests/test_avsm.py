"""AVSM on noise-free theoretical wavelet variances (docs/METHODS.md §3 formulas via gmwm.model)."""

from dataclasses import dataclass

import numpy as np
import pytest

from gmwm import units as u
from gmwm.avsm import fit_avsm
from gmwm.errors import InputError, ModelError
from gmwm.model import Model
from gmwm.wv import WaveletVariance, wvar
from gmwm_studies import sensors as s


@dataclass(frozen=True)
class _WV:
    """Minimal stand-in with the WaveletVariance attributes AVSM reads (for hand-made tables)."""
    levels: np.ndarray
    scales: np.ndarray
    variance: np.ndarray
    n: np.ndarray
    n_samples: int
    freq: float


def _theoretical_wv(model: str, truth: dict, T: int, freq: float = 250.0) -> WaveletVariance:
    scales = 2.0 ** np.arange(1, int(np.floor(np.log2(T))))  # J = floor(log2 T) - 1
    m = Model(model, freq=freq)
    return WaveletVariance.from_table(scales, m.wv(m.theta(truth), scales), n_samples=T, freq=freq)


def _rel_table_errors(res, truth, sensor):
    return {k: s.to_table_units(k, v, sensor) / s.to_table_units(k, truth[k], sensor) - 1
            for k, v in res.as_dict().items()}


def test_pure_wn_exact():
    truth = {"WN[1].sigma2": 1.7e-3}
    res = fit_avsm(_theoretical_wv("WN", truth, 2**20), "WN")
    assert res.param_names == ["WN[1].sigma2"]
    assert res.params[0] == pytest.approx(1.7e-3, rel=1e-12)  # a pure WN line is exact
    assert res.converged and res.message == "ok"
    assert res.regions["WN[1]"].method == "fixed-slope"


@pytest.mark.parametrize("model,truth,rel", [
    ("QN", {"QN[1].Q2": 2e-7}, 1e-12),
    ("DR", {"DR[1].omega": 1.3e-8}, 1e-12),
    ("RW", {"RW[1].gamma2": 1.5e-13}, 1e-2),  # the +2 in (tau^2+2) bends the first levels
])
def test_pure_terms_read_at_spec_points(model, truth, rel):
    res = fit_avsm(_theoretical_wv(model, truth, 2**22), model)
    (name, value), = truth.items()
    assert res.as_dict()[name] == pytest.approx(value, rel=rel)


def test_stim300_gyro_long_recovers_n_and_k():
    truth = s.stim300_truth("gyro")
    res = fit_avsm(_theoretical_wv("WN+RW", truth, 6_300_000), Model("WN+RW", freq=250.0))
    err = _rel_table_errors(res, truth, "gyro")
    assert abs(err["WN[1].sigma2"]) < 0.01  # N, measured +0.5 %
    assert abs(err["RW[1].gamma2"]) < 0.05  # K, measured +3.7 %
    assert res.converged and res.message == "ok"
    wn, rw = res.regions["WN[1]"], res.regions["RW[1]"]
    assert wn.levels.max() < rw.levels.min()  # disjoint regions, WN at short scales


def test_stim300_gyro_short_uses_tangent_and_overestimates_k():
    # documented bias (module docstring): at T = 2.5e6 no level has slope >= 0.4
    truth = s.stim300_truth("gyro")
    res = fit_avsm(_theoretical_wv("WN+RW", truth, 2_500_000), "WN+RW")
    err = _rel_table_errors(res, truth, "gyro")
    assert res.regions["RW[1]"].method == "tangent"
    assert "RW[1]" in res.message and res.converged
    assert 0.15 < err["RW[1].gamma2"] < 0.30  # measured +22 %
    assert abs(err["WN[1].sigma2"]) < 0.01


def test_stim300_accel_q_read_from_wn_scales():
    truth = s.stim300_truth("accel")
    res = fit_avsm(_theoretical_wv("QN+WN+RW+DR", truth, 2_500_000), "QN+WN+RW+DR")
    err = _rel_table_errors(res, truth, "accel")
    assert res.param_names == list(truth)
    assert res.regions["QN[1]"].method == "tangent"
    assert 10 < err["QN[1].Q2"] + 1 < 25  # docs/METHODS.md §9.2: Q about x16
    assert abs(err["WN[1].sigma2"]) < 0.02
    assert abs(err["RW[1].gamma2"]) < 0.10
    assert res.params[-1] > 0  # omega returned non-negative


def test_edof_filter_drops_last_levels():
    truth = s.stim300_truth("gyro")
    wv = _theoretical_wv("WN+RW", truth, 2_500_000)
    res = fit_avsm(wv, "WN+RW")
    eta = np.maximum(wv.n / wv.scales, 1)
    assert np.all(eta[res.levels - 1] >= 2) and res.levels.max() == 19
    res4 = fit_avsm(wv, "WN+RW", min_edof=4)
    assert res4.levels.max() == 18
    assert np.allclose(res.tau_s, 2.0 ** (res.levels - 1) / 250.0)
    assert np.allclose(res.adev, np.sqrt(2 * wv.variance[res.levels - 1]))


def test_bi_with_stand_in_model():
    # flat AD floor: WV = (ln2/pi) B^2 per scale, plus WN
    class _M:
        param_names = ("WN[1].sigma2", "BI[1].B2")

    scales = 2.0 ** np.arange(1, 21)
    b, s2 = 3e-3, 1e-4
    var = s2 / scales + s.bias_instability_wv_ideal(b, scales)
    wv = _WV(np.arange(1, 21), scales, var, (2**22 - scales + 1).astype(int), 2**22, 100.0)
    res = fit_avsm(wv, _M())
    assert res.as_dict()["BI[1].B2"] == pytest.approx(b * b, rel=0.05)
    assert res.regions["BI[1]"].method == "fixed-slope"


def test_ad_line_and_model_wv():
    truth = s.stim300_truth("gyro")
    wv = _theoretical_wv("WN+RW", truth, 6_300_000)
    res = fit_avsm(wv, "WN+RW")
    reg = res.regions["WN[1]"]
    n_cont = u.wn_density_from_sigma2(res.params[0], 250.0)
    assert reg.adev(1.0) == pytest.approx(n_cont, rel=1e-12)
    assert reg.coefficient == pytest.approx(n_cont, rel=1e-12)
    assert res.model_wv().shape == wv.variance.shape
    assert set(res.component_wv()) == {"WN[1]", "RW[1]"}


def test_errors():
    wv = _theoretical_wv("WN", {"WN[1].sigma2": 1.0}, 2**12)
    with pytest.raises(ModelError):
        fit_avsm(wv, "WN+AR1")
    with pytest.raises(InputError):
        fit_avsm(wv.subset([1]), "WN")


def test_simulated_pure_wn_unbiased_within_mc_error():
    # seeded Monte Carlo: R = 12 series of T = 2^17; tolerance = 4 x the MC standard error of the
    # mean relative error (SD / sqrt(R), estimated from the replicates) + 0.5 % allowance for
    # the rule's own bias (0 for a pure WN line)
    rng = np.random.default_rng(20240611)
    m = Model("WN", freq=250.0)
    theta = m.theta({"WN[1].sigma2": 1.7e-3})
    rel = np.array([fit_avsm(wvar(m.simulate(theta, 2**17, rng), freq=250.0), m).params[0]
                    for _ in range(12)]) / 1.7e-3 - 1
    se = rel.std(ddof=1) / np.sqrt(rel.size)
    assert abs(rel.mean()) < 4 * se + 0.005
    assert rel.std(ddof=1) < 0.1
