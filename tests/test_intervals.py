"""Intervals inside the parameter space (gmwm.intervals): the rule, its agreement with the
"not distinguishable from zero" warning, datasheet images, bootstrap intervals, and every end
inside the domain over a few hundred default fits of several models."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gmwm
from gmwm.datasheet import datasheet
from gmwm.diagnostics import is_weak
from gmwm.intervals import (
    bootstrap_basic,
    fit_intervals,
    function_interval,
    image_interval,
    param_domains,
    param_intervals,
    scale_interval,
)
from gmwm.model import Model

Z = 1.959963984540054


def test_rule_by_kind():
    m = Model("WN+AR1+SIN+RW+DR")
    # WN strong, AR1 phi near 1, AR1 variance weak, SIN alpha strong, SIN beta near pi, RW weak,
    # DR negative and strong
    theta = np.array([1.0, 0.9995, 1e-4, 0.5, 3.1, 1e-7, -2e-3])
    se = np.array([0.01, 0.001, 1e-4, 0.05, 0.1, 1e-7, 1e-4])
    ci = param_intervals(m, theta, np.diag(se**2))
    # strong scale parameter: Wald lower end, log-scale upper end (contains the Wald interval)
    assert ci[0, 0] == pytest.approx(1 - Z * 0.01) and ci[0, 0] > 0
    assert ci[0, 1] == pytest.approx(math.exp(Z * 0.01)) and ci[0, 1] > 1 + Z * 0.01
    # phi: Wald cut at 1
    assert ci[1, 0] == pytest.approx(0.9995 - Z * 0.001) and ci[1, 1] == 1.0
    # weak variance: reaches 0, the log-scale upper end continued linearly from z se = estimate
    assert ci[2, 0] == 0.0 and ci[2, 1] == pytest.approx(1e-4 + (math.e - 1) * Z * 1e-4)
    assert ci[5, 0] == 0.0
    # SIN beta cut at pi
    assert ci[4, 1] == pytest.approx(math.pi)
    # negative drift keeps its sign: the rule on |omega|, mirrored
    assert ci[6, 1] == pytest.approx(-2e-3 + Z * 1e-4) and ci[6, 1] < 0
    assert ci[6, 0] == pytest.approx(-2e-3 * math.exp(Z * 0.05))
    # agreement with the weak flag at alpha = 0.05
    scale = [0, 2, 3, 5, 6]
    weak = is_weak(theta, se)
    for i in scale:
        assert (ci[i, 0] == 0.0) == bool(weak[i]) or (theta[i] < 0 and ci[i, 1] == 0) == weak[i]


def test_scale_ends_move_continuously_and_nest_in_alpha():
    # across the weak/strong switch (estimate = z se) the ends are continuous in the estimate,
    # and for every estimate the 95 % interval contains the 90 % one (no jump at the switch)
    s = 1.0
    for z in (Z, 1.6448536269514722):
        below, above = scale_interval(z * s * (1 - 1e-9), s, z), scale_interval(z * s, s, z)
        assert below[1] == pytest.approx(above[1], rel=1e-8) and above[1] == pytest.approx(
            math.e * z * s)
        assert below[0] == 0.0 and above[0] == 0.0
    for a in np.linspace(0.0, 5.0, 201):
        w, n = scale_interval(a, s, Z), scale_interval(a, s, 1.6448536269514722)
        assert w[0] <= n[0] <= a <= n[1] <= w[1]
        assert w[1] >= a + Z * s and w[0] == max(a - Z * s, 0.0)   # contains Wald cut at 0


def test_boundary_component_and_missing_se():
    m = Model("WN+AR1+RW")
    theta = np.array([1.0, 0.5, 0.0, 1e-6])
    fixed = np.array([False, True, True, False])
    upper = np.array([np.nan, np.nan, 3e-4, np.nan])
    se = np.array([0.01, np.nan, np.nan, np.nan])
    ci = param_intervals(m, theta, None, fixed=fixed, boundary_upper=upper, se=se)
    assert tuple(ci[1]) == (-1.0, 1.0)            # shape of a vanished AR1: whole domain
    assert tuple(ci[2]) == (0.0, 3e-4)            # [0, z se_0]
    assert np.all(np.isnan(ci[3]))                # no SE, not at the boundary: no interval


def test_image_and_function_intervals():
    # RRW K = sqrt(gamma2 f): the image of the gamma2 interval; reaches 0 with it
    lo, hi = image_interval(lambda g: math.sqrt(g * 100.0), (0.0, 4e-6))
    assert lo == 0.0 and hi == pytest.approx(0.02)
    # correlation time 1 / beta is decreasing: ends swap; beta's lower end 0 -> infinite time
    lo, hi = image_interval(lambda b: 1 / b if b > 0 else math.inf, (0.0, 0.5))
    assert lo == 2.0 and hi == math.inf
    # stationary variance of an AR1 whose innovation variance is weak reaches 0
    def fn(t):
        return t[1] / (1 - t[0] ** 2)

    cov = np.diag([1e-6, 1e-8])
    assert function_interval(fn, np.array([0.9, 1e-5]), cov, weak=True)[0] == 0.0
    lo, hi = function_interval(fn, np.array([0.9, 1e-3]), np.diag([1e-6, 1e-9]))
    assert 0 < lo < 1e-3 / 0.19 < hi


def test_bootstrap_basic_inside_domain():
    m = Model("WN+AR1+SIN")
    est = np.array([1.0, 0.999, 1e-3, 0.2, 3.0])
    q = np.array([[0.95, 1.04], [0.990, 0.9999], [0.0, 3e-3], [0.15, 0.26], [2.9, 3.14]])
    ci = bootstrap_basic(m, est, q)
    for (lo, hi), (d_lo, d_hi) in zip(ci, param_domains(m), strict=True):
        assert d_lo <= lo <= hi <= d_hi
    assert ci[0] == pytest.approx([1 / 1.04, 1 / 0.95])   # log-scale basic interval
    assert tuple(ci[2]) == (0.0, 3e-3)                      # refits at 0: percentile, from 0
    assert ci[1, 1] == 1.0                                  # 2 * 0.999 - 0.990 > 1: cut


def _datasheet_sizes(ds: dict) -> dict[str, tuple[float, float]]:
    """Datasheet intervals of each component's size coefficient (ARW, RRW, QN, RR, GM/AR1
    sigma, SIN amplitude), keyed by the component's scale parameter."""
    out = {}
    for entry in ds.values():
        parts = [entry] if "value" in entry else [v for k, v in entry.items()
                                                   if k in ("sigma", "amplitude")]
        for e in parts:
            name = next(n for n in e["parameters"]
                        if n.split(".")[1] in ("sigma2", "gamma2", "Q2", "omega", "alpha"))
            out[name] = tuple(e["ci95"])
    return out


CASES = [
    ("WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 1e-3,
                   "RW[1].gamma2": 1e-6}, 50),
    ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 60),
    ("QN+WN+RW+DR", {"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5,
                     "DR[1].omega": 1e-4}, 50),
    ("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9995, "AR1[1].sigma2": 1e-5}, 50),
    ("WN+AR1+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                    "SIN[1].alpha": 0.3, "SIN[1].beta": 0.35}, 25),
]


@pytest.mark.slow
@pytest.mark.parametrize("spec,truth,R", CASES, ids=[c[0] for c in CASES])
def test_every_end_inside_the_domain(spec, truth, R):
    """Default fits at T = 2^14 (weak RW and near-edge phi on purpose; 235 fits in all): every
    interval end in the closed domain, an interval wherever there is an SE or a boundary
    component, and a scale interval - and the datasheet coefficient of that component -
    reaches 0 exactly when the fit warns 'not distinguishable from zero' or puts the component
    at the boundary."""
    m = Model(spec)
    theta0 = m.theta(truth)
    wald_outside = 0
    for r in range(R):
        x = m.simulate_fast(theta0, 2**14, np.random.default_rng([31, r]))
        res = gmwm.fit(x, m)
        ci = fit_intervals(res)
        np.testing.assert_array_equal(res.conf_int(), ci)
        dom = param_domains(m, res.params)   # DR omega carries the signal's sign
        for i in range(m.n_params):
            lo, hi = ci[i]
            if np.isnan(lo):
                assert not np.isfinite(res.se[i]), (spec, r, res.param_names[i])
                continue
            assert dom[i, 0] <= lo <= hi <= dom[i, 1], (spec, r, res.param_names[i], ci[i])
            w = (res.params[i] - Z * res.se[i], res.params[i] + Z * res.se[i])
            wald_outside += int(w[0] < dom[i, 0]) + int(w[1] > dom[i, 1])
        weak = next((w for w in res.warnings if "not distinguishable" in w), None)
        weak_names = [] if weak is None else \
            weak.split("component(s) ", 1)[1].split(" not distinguishable")[0].split(", ")
        sizes = _datasheet_sizes(datasheet(res))
        for c in m.components:
            i = c.start + c.process.scale_index
            flagged = c.name in weak_names or c.name in res.diagnostics["at_boundary"]
            reaches_zero = ci[i, 0] == 0.0 or ci[i, 1] == 0.0
            assert reaches_zero == flagged, (spec, r, c.name, ci[i], res.warnings)
            # the datasheet coefficient of the component agrees with its parameter
            lo, hi = sizes[res.param_names[i]]
            assert (lo == 0.0 or hi == 0.0) == flagged, (spec, r, c.name, (lo, hi), ci[i])
            assert lo <= hi
    if spec in ("WN+AR1+RW", "WN+RW", "WN+AR1"):
        assert wald_outside > 0   # the case the rule exists for
