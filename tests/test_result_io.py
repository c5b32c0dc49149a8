"""Lossless GMWMResult files (gmwm.codec.result_to_dict / result_from_dict / write_result /
read_result): what the pipeline passes between rules instead of a pickle."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import gmwm
from gmwm import bootstrap as bs
from gmwm.codec import read_result, result_from_dict, result_to_dict, write_result
from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.wv import wvar


@pytest.fixture(scope="module")
def signal():
    model = Model("WN+AR1", freq=100.0)
    theta = model.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.5})
    return model, model.simulate(theta, 2**12, np.random.default_rng(7))


@pytest.fixture(scope="module")
def fitted(signal):
    model, x = signal
    return gmwm.fit(x, model, freq=100.0, n_starts=2, seed=5)


def _assert_same(a, b):
    assert a.model == b.model and a.method == b.method
    for name in ("params", "se", "cov", "weights", "wv_cov"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), strict=True)
    assert a.objective == b.objective or (np.isnan(a.objective) and np.isnan(b.objective))
    assert (a.converged, a.message, a.seconds_wv, a.seconds_fit) == \
        (b.converged, b.message, b.seconds_wv, b.seconds_fit)
    for name in ("levels", "scales", "variance", "ci_low", "ci_high", "n"):
        np.testing.assert_array_equal(getattr(a.wv, name), getattr(b.wv, name), strict=True)
    assert (a.wv.n_samples, a.wv.freq, a.wv.alpha, a.wv.efficiency) == \
        (b.wv.n_samples, b.wv.freq, b.wv.alpha, b.wv.efficiency)
    ka, kb = a.fit_kwargs(), b.fit_kwargs()
    assert ka.keys() == kb.keys()
    for k in ka:
        np.testing.assert_array_equal(ka[k], kb[k])


def test_round_trip_is_bit_identical(fitted, tmp_path):
    d = result_to_dict(fitted)
    text = json.dumps(d, allow_nan=False)  # strict JSON
    back = result_from_dict(json.loads(text))
    _assert_same(fitted, back)
    assert back.diagnostics == json.loads(json.dumps(fitted.diagnostics))
    assert back.settings == fitted.settings
    assert back.summary() == fitted.summary()

    path = write_result(tmp_path / "fit.json", fitted)
    _assert_same(fitted, read_result(path))


def test_non_finite_values_and_user_covariance(signal, fitted, tmp_path):
    model, x = signal
    user = gmwm.fit(x, model, freq=100.0, weights=fitted.wv_cov, n_starts=2, seed=5)
    assert isinstance(user.settings.weights, np.ndarray)
    odd = dataclasses.replace(
        user, se=np.array([np.nan, np.inf, 1.0]), objective=-np.inf,
        diagnostics={**user.diagnostics, "condition_number": np.inf, "tup": (1, np.float64(2.5)),
                     "label": "NaN", "fixed": np.array([True, False, True])})
    back = read_result(write_result(tmp_path / "odd.json", odd))
    _assert_same(odd, back)
    np.testing.assert_array_equal(back.settings.weights, user.settings.weights, strict=True)
    assert back.settings == user.settings
    assert back.diagnostics["condition_number"] == np.inf
    assert back.diagnostics["tup"] == [1, 2.5] and back.diagnostics["label"] == "NaN"
    np.testing.assert_array_equal(back.diagnostics["fixed"], [True, False, True], strict=True)


def test_robust_wv_keeps_its_efficiency(signal):
    model, x = signal
    res = gmwm.fit(wvar(x, robust=True, freq=100.0), model, freq=100.0, n_starts=1, seed=1)
    back = result_from_dict(result_to_dict(res))
    assert back.wv.robust and back.wv.efficiency == res.wv.efficiency
    np.testing.assert_array_equal(back.wv.edof, res.wv.edof)


def test_bootstrap_of_reloaded_result_gives_identical_draws(fitted, tmp_path):
    back = read_result(write_result(tmp_path / "fit.json", fitted))
    a = bs.parametric_bootstrap(fitted, 3, seed=np.random.SeedSequence(9, spawn_key=(4,)))
    b = bs.parametric_bootstrap(back, 3, seed=np.random.SeedSequence(9, spawn_key=(4,)))
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.wv, b.wv)
    np.testing.assert_array_equal(a.converged, b.converged)
    assert a.settings == b.settings


@pytest.mark.parametrize("content, words", [
    ("{not json", "not a JSON gmwm result"),
    ('{"format": "other"}', "not a gmwm result"),
    ('[1, 2]', "not a gmwm result"),
])
def test_bad_files_are_one_line_errors(tmp_path, content, words):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(InputError) as info:
        read_result(p)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_damaged_and_missing_files(fitted, tmp_path):
    d = result_to_dict(fitted)
    del d["wv"]["variance"]
    p = tmp_path / "damaged.json"
    p.write_text(json.dumps(d))
    with pytest.raises(InputError, match="damaged gmwm result"):
        read_result(p)
    with pytest.raises(InputError, match="file not found"):
        read_result(tmp_path / "missing.json")


def test_a_file_of_the_earlier_settings_layout_still_reads(signal, fitted):
    # before FitSettings: settings a dict (a user covariance as weights "covariance" plus
    # weights_cov), a copy in diagnostics, and method a field of its own
    model, x = signal
    user = gmwm.fit(x, model, freq=100.0, weights=fitted.wv_cov, n_starts=2, seed=5)
    d = result_to_dict(user)
    tree = dict(d["settings"])
    old = {k: tree[k] for k in ("method", "n_starts", "reweight", "seed", "levels", "max_nfev",
                                "nested", "se_cov")}
    old.update(weights="covariance", weights_cov=tree["weights"])
    d.update(settings=old, method=tree["method"])
    d["diagnostics"]["settings"] = {k: v for k, v in old.items() if k != "weights_cov"}
    back = result_from_dict(json.loads(json.dumps(d, allow_nan=False)))
    assert back.settings == user.settings
    np.testing.assert_array_equal(back.params, user.params, strict=True)


def test_a_file_without_the_gof_field_still_reads(fitted):
    # written before fits carried their goodness-of-fit test: read with gof None
    d = result_to_dict(fitted)
    assert d["gof"] is not None
    del d["gof"]
    back = result_from_dict(json.loads(json.dumps(d, allow_nan=False)))
    assert back.gof is None
    np.testing.assert_array_equal(back.params, fitted.params, strict=True)


def test_the_gof_test_round_trips(fitted):
    back = result_from_dict(json.loads(json.dumps(result_to_dict(fitted), allow_nan=False)))
    for name in ("statistic", "df", "p_value", "objective", "freq", "method", "notes"):
        assert getattr(back.gof, name) == getattr(fitted.gof, name)
    for name in ("eigenvalues", "residuals", "scales"):
        np.testing.assert_array_equal(getattr(back.gof, name), getattr(fitted.gof, name),
                                      strict=True)
