"""Every estimator result of the library passes the shared protocol battery
(tests/result_protocol.py): GMWM and ARMAV fits (also with a component at the boundary, a user
covariance, read back from a file), AVSM (directly and through gmwm.fit) and the bootstrap (with
refits, without, and with too few converged refits)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import gmwm
from gmwm import bootstrap as bs
from gmwm.avsm import fit_avsm
from gmwm.codec import result_from_dict, result_to_dict
from gmwm.model import Model
from result_protocol import check_result  # tests/ is on sys.path (pytest rootdir-less import)


@pytest.fixture(scope="module")
def wn_ar1():
    m = Model("WN+AR1")
    return m, m.simulate(m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.2}),
                         2**13, np.random.default_rng(4))


@pytest.fixture(scope="module")
def gmwm_fit(wn_ar1):
    m, x = wn_ar1
    return gmwm.fit(x, m, n_starts=2)


def _wn_rw(seed: int = 1) -> np.ndarray:
    m = Model("WN+RW", freq=100.0)
    return m.simulate(np.array([1.0, 1e-4]), 2**14, np.random.default_rng(seed))


def test_gmwm_and_armav_results(gmwm_fit, wn_ar1):
    check_result(gmwm_fit)
    assert np.all(np.isfinite(gmwm_fit.se))
    m, x = wn_ar1
    check_result(gmwm.fit(x, m, method="armav", n_starts=1))
    check_result(gmwm.fit(gmwm.wvar(x), m, weights=gmwm_fit.wv_cov, n_starts=1))


def test_a_component_at_the_boundary_has_nan_se_and_no_interval():
    # white noise fitted with WN + RW: the RW ends at 0 in this replicate (no SE)
    x = np.random.default_rng(3).standard_normal(2**16)
    res = gmwm.fit(x, "WN+RW")
    assert res.diagnostics["at_boundary"] == ["RW[1]"] and np.isnan(res.se[1])
    check_result(res)


def test_a_rejected_model_and_a_fit_without_the_test(wn_ar1):
    m, x = wn_ar1
    wrong = gmwm.fit(x, "WN")   # the AR1 left out: rejected, a warning on every surface
    assert wrong.gof is not None and wrong.gof.rejected()
    check_result(wrong)
    fast = gmwm.fit(x, m, se_cov="gaussian", n_starts=1)   # the bootstrap's fast path
    assert fast.gof is None and "not computed" in fast.summary()
    check_result(fast)


def test_a_result_read_back_from_its_file(gmwm_fit):
    check_result(result_from_dict(result_to_dict(gmwm_fit)))


def test_avsm_results_directly_and_through_fit():
    x = _wn_rw()
    direct = fit_avsm(gmwm.wvar(x, freq=100.0), Model("WN+RW", freq=100.0))
    check_result(direct)
    via = gmwm.fit(x, Model("WN+RW", freq=100.0), method="avsm")
    check_result(via)
    np.testing.assert_array_equal(via.params, direct.params)
    assert via.settings.method == "avsm" and via.seconds_wv > 0
    assert np.all(np.isnan(via.se)) and np.all(np.isnan(via.conf_int()))


def test_bootstrap_results(gmwm_fit):
    boot = bs.parametric_bootstrap(gmwm_fit, 4, seed=1)
    assert boot.n_converged >= 2
    check_result(boot)
    np.testing.assert_array_equal(boot.params, gmwm_fit.params)
    np.testing.assert_array_equal(boot.conf_int(), boot.percentile_ci())
    wv_only = bs.parametric_bootstrap(gmwm_fit, 3, seed=1, refit=False)
    check_result(wv_only)
    assert np.all(np.isnan(wv_only.se))
    one = bs.parametric_bootstrap(gmwm_fit, 1, seed=1)
    check_result(one)
    assert one.to_json_dict()["wv_cov"] is None


def test_changing_a_result_builds_a_new_one(gmwm_fit):
    with pytest.raises(dataclasses.FrozenInstanceError):
        gmwm_fit.converged = False
    changed = dataclasses.replace(gmwm_fit, converged=False)
    assert gmwm_fit.converged and not changed.converged
    with pytest.raises(ValueError):
        gmwm_fit.params[0] = 0.0


def test_the_battery_rejects_a_result_that_breaks_the_protocol(gmwm_fit):
    @dataclasses.dataclass
    class Mutable:  # gmwm_fit's data, but mutable and with writeable arrays
        params: np.ndarray
        se: np.ndarray
        param_names: list
        settings: object

        def conf_int(self, alpha=0.05):
            return gmwm_fit.conf_int(alpha)

        def summary(self):
            return gmwm_fit.summary()

        def to_json_dict(self):
            return gmwm_fit.to_json_dict()

    broken = Mutable(np.array(gmwm_fit.params), np.array(gmwm_fit.se), gmwm_fit.param_names,
                     gmwm_fit.settings)
    with pytest.raises((AssertionError, pytest.fail.Exception)):
        check_result(broken)
    nan_json = dataclasses.replace(gmwm_fit)
    object.__setattr__(nan_json, "to_json_dict", lambda: {"objective": float("nan")})
    with pytest.raises(ValueError, match="JSON"):
        check_result(nan_json)
