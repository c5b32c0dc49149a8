"""The fused simulation + WV pass (gmwm.fused.simulate_wv) and its generator (gmwm._simkernels): the WV has
the bits of gmwm.wv.wvar on the materialised signal, the normals are standard normal, and the
replicates' mean WV is the model's WV."""

import numpy as np
import pytest
from scipy import stats

from gmwm import _simkernels as k
from gmwm import fused
from gmwm.errors import ModelError
from gmwm.model import Model
from gmwm.wv import wvar

MODELS = {
    "WN+RW": {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4},
    "QN+WN+RW+DR": {"QN[1].Q2": 0.1, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5,
                    "DR[1].omega": 1e-4},
    "2*AR1+2*SIN": {"AR1[1].phi": 0.9, "AR1[1].sigma2": 1.0, "AR1[2].phi": 0.9999,
                    "AR1[2].sigma2": 1e-6, "SIN[1].alpha": 0.5, "SIN[1].beta": 0.3,
                    "SIN[2].alpha": 0.1, "SIN[2].beta": 1e-3},
    "WN+AR1+RW+SIN": {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                      "RW[1].gamma2": 1e-6, "SIN[1].alpha": 0.2, "SIN[1].beta": 0.05},
    "QN+GM": {"QN[1].Q2": 0.1, "GM[1].beta": 0.01, "GM[1].sigma2": 1.0},
}


@pytest.mark.parametrize("spec", sorted(MODELS))
@pytest.mark.parametrize("n", [1000, 40_000, 300_001])
def test_fused_wv_equals_wvar_of_the_materialised_signal(spec, n):
    model = Model(spec)
    theta = model.theta(MODELS[spec])
    x = fused.simulate_signal(model, theta, n, np.random.default_rng(5))
    got = fused.simulate_wv(model, theta, n, np.random.default_rng(5))
    np.testing.assert_array_equal(got, wvar(x).variance)  # same bits, not just close
    if n > 40_000:
        J = 9
        np.testing.assert_array_equal(fused.simulate_wv(model, theta, n, np.random.default_rng(5), J),
                                      wvar(x, levels=J).variance)


def test_normals_are_standard_normal():
    state = k.seed_state(np.random.default_rng(11))
    z = np.empty(1 << 20)
    k.fill_normals(state, z, k.ZIG_K, k.ZIG_W, k.ZIG_F)
    n = z.size
    assert abs(z.mean()) < 5 / np.sqrt(n)
    assert abs(z.var() - 1) < 5 * np.sqrt(2 / n)
    assert abs(stats.skew(z)) < 5 * np.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 5 * np.sqrt(24 / n)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    # the tail beyond the base layer (its own sampler) has the normal's mass and shape
    tail = np.abs(z[np.abs(z) > k._ZIG_R])
    p = 2 * stats.norm.sf(k._ZIG_R)
    assert abs(tail.size - n * p) < 5 * np.sqrt(n * p)
    shifted = (stats.norm.sf(tail) / stats.norm.sf(k._ZIG_R))  # uniform on (0, 1) if right
    assert stats.kstest(shifted, "uniform").pvalue > 1e-3
    # the state advanced: the next block differs
    z2 = np.empty(16)
    k.fill_normals(state, z2, k.ZIG_K, k.ZIG_W, k.ZIG_F)
    assert not np.array_equal(z2, z[:16])


def test_uniforms_cover_the_unit_interval():
    state = k.seed_state(np.random.default_rng(2))
    u = np.empty(1 << 18)
    k.fill_uniforms(state, u)
    assert 0 <= u.min() and u.max() < 1
    assert stats.kstest(u, "uniform").pvalue > 1e-3


def test_mean_replicate_wv_is_the_model_wv():
    # no sinusoid: the model WV is then the expectation of the empirical WV
    spec = "QN+WN+AR1+RW+DR"
    model = Model(spec)
    theta = model.theta({"QN[1].Q2": 0.5, "WN[1].sigma2": 1.0, "AR1[1].phi": 0.95,
                         "AR1[1].sigma2": 0.1, "RW[1].gamma2": 1e-3, "DR[1].omega": 1e-3})
    n, R = 1 << 12, 300
    rng = np.random.default_rng(7)
    W = np.array([fused.simulate_wv(model, theta, n, rng) for _ in range(R)])
    truth = model.wv(theta, 2.0 ** np.arange(1, W.shape[1] + 1))
    z = (W.mean(0) - truth) / (W.std(0, ddof=1) / np.sqrt(R))
    assert np.all(np.abs(z) < 4.5), z


def test_bad_input_is_named():
    model = Model("WN")
    with pytest.raises(ModelError, match="positive"):
        fused.simulate_signal(model, np.array([1.0]), 0, np.random.default_rng(0))
    with pytest.raises(ModelError):
        fused.simulate_wv(model, np.array([-1.0]), 100, np.random.default_rng(0))


def test_fused_wv_with_the_numba_kernel(monkeypatch):
    import gmwm.wv as wv_module
    from gmwm import _wvkernels

    model = Model("WN+RW")
    theta = model.theta(MODELS["WN+RW"])
    want = fused.simulate_wv(model, theta, 70_000, np.random.default_rng(3))
    monkeypatch.setattr(wv_module, "classical_kernels", lambda: _wvkernels)
    np.testing.assert_array_equal(fused.simulate_wv(model, theta, 70_000, np.random.default_rng(3)),
                                  want)  # the C and Numba kernels have the same bits
