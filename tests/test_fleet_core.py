"""The statistics of the fleet table (gmwm.fleet.core): the random-effects estimate against a
hand-computed DerSimonian-Laird case, the Q-profile interval of the spread (its coverage in a small
seeded simulation; the full study is benchmarks/bench_fleet.py), the out-of-family rule, drift."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

pytest.importorskip("statsmodels")

from gmwm.fleet.core import (
    Estimate,
    fit_drift,
    fleet_table,
    log_se,
    q_profile_tau2,
    random_effects,
)

# five units: log values y and within-unit variances v
Y = [0.0, 0.5, 1.0, -0.2, 0.3]
V = [0.04, 0.01, 0.09, 0.04, 0.02]


def test_dersimonian_laird_by_hand():
    # weights 1/v = 25, 100, 100/9, 25, 50; sum S = 211.111
    # fixed-effect mean (0 + 50 + 11.111 - 5 + 15) / S = 71.111 / 211.111 = 0.336842
    # Q = sum w (y - 0.336842)^2 = 17.657895; C = S - sum w^2 / S = 145.394737
    # tau^2 = (Q - (k - 1)) / C = 13.657895 / 145.394737 = 0.0939367
    re = random_effects(Y, V, method="dl")
    assert re.q == pytest.approx(17.657895, rel=1e-6)
    assert re.tau2 == pytest.approx(0.0939367, rel=1e-5)
    w = [1 / (v + 0.0939367) for v in V]
    mu = sum(a * b for a, b in zip(w, Y, strict=True)) / sum(w)
    assert re.mu == pytest.approx(mu, rel=1e-5)          # 0.293730
    assert re.se_mu == pytest.approx(1 / math.sqrt(sum(w)), rel=1e-5)  # 0.160608
    assert re.i2 == pytest.approx((17.657895 - 4) / 17.657895, rel=1e-6)
    # the prediction interval: mu +- t_{3, 0.975} sqrt(tau^2 + se^2), t = 3.182446
    half = 3.182446 * math.sqrt(0.0939367 + re.se_mu ** 2)
    assert re.pi == pytest.approx((re.mu - half, re.mu + half), rel=1e-5)


def test_paule_mandel_solves_its_equation():
    re = random_effects(Y, V, method="pm")
    w = 1 / (np.array(V) + re.tau2)
    mu = np.sum(w * Y) / np.sum(w)
    assert np.sum(w * (np.array(Y) - mu) ** 2) == pytest.approx(len(Y) - 1, rel=1e-4)


def test_q_profile_ends_solve_the_chi2_quantiles():
    from scipy.stats import chi2

    lo, hi = q_profile_tau2(Y, V)
    for t2, p in ((lo, 0.975), (hi, 0.025)):
        w = 1 / (np.array(V) + t2)
        mu = np.sum(w * Y) / np.sum(w)
        assert np.sum(w * (np.array(Y) - mu) ** 2) == pytest.approx(chi2.ppf(p, 4), rel=1e-6)
    # homogeneous units: the lower end is 0
    assert q_profile_tau2([0.0, 0.01, -0.01, 0.0], [0.04] * 4)[0] == 0.0


def test_tau_interval_coverage_small_simulation():
    """Seeded: 150 fleets of 12 units, tau = 0.3, unequal within-unit errors; the Q-profile
    interval covers tau^2 in 95 % of fleets (exact under the model); 150 replicates give a
    binomial SE of 1.8 %, the band below is 4 SE wide either side."""
    rng = np.random.default_rng(20261128)
    tau2, k, hits, R = 0.09, 12, 0, 150
    for _ in range(R):
        v = rng.uniform(0.005, 0.1, k)
        y = 1.0 + rng.normal(0, math.sqrt(tau2), k) + rng.normal(0, np.sqrt(v))
        lo, hi = q_profile_tau2(y, v)
        hits += lo <= tau2 <= hi
    assert abs(hits / R - 0.95) <= 4 * math.sqrt(0.95 * 0.05 / R)


def _fleet(values, widths=1.1, unit="rad/s/sqrt(Hz)"):
    return [Estimate(f"u{i}", f"u{i}_rec", "gx.noise_density", v, (v / widths, v * widths), unit,
                     "gyroscope") for i, v in enumerate(values)]


def test_out_of_family_unit_found_with_its_reason():
    vals = [1.0e-4, 1.05e-4, 0.97e-4, 1.02e-4, 0.99e-4, 1.03e-4, 3.0e-4]
    fleet = fleet_table(_fleet(vals))
    out = fleet.out_of_family
    assert [v.estimate.unit for v in out] == ["u6"]
    assert "above the fleet's 95 % prediction interval" in out[0].reason
    assert "gx.noise_density" in out[0].reason
    summ = fleet.coefficients["gx.noise_density"]
    assert summ.n_units == 7
    assert summ.prediction[0] < 1e-4 < summ.prediction[1]


def test_unit_inside_the_band_is_in_family_and_flagged_terms_are_excluded():
    ests = _fleet([1.0e-4, 1.05e-4, 0.97e-4, 1.02e-4])
    ests.append(Estimate("u9", "u9_rec", "gx.noise_density", 0.0, (0.0, 2e-4),
                         "rad/s/sqrt(Hz)", excluded="at the boundary 0"))
    fleet = fleet_table(ests)
    assert not fleet.out_of_family
    status = {v.estimate.unit: (v.status, v.reason) for v in fleet.verdicts}
    assert status["u9"] == ("excluded", "at the boundary 0")
    assert fleet.coefficients["gx.noise_density"].excluded == (("u9", "at the boundary 0"),)
    assert fleet.to_json_dict()["units"][-1]["value"] is None  # never a number


def test_too_few_units_give_no_fleet_estimate():
    fleet = fleet_table(_fleet([1e-4, 2e-4]))
    assert fleet.coefficients["gx.noise_density"].fit is None
    assert {v.status for v in fleet.verdicts} == {"no fleet estimate"}


def test_drift_slope_recovers_a_known_trend():
    d0 = dt.date(2025, 1, 1)
    dates = [d0 + dt.timedelta(days=int(365.25 * t)) for t in (0.0, 0.25, 0.5, 0.75, 1.0)]
    rate = math.log(1.2)  # +20 % per year
    y = [math.log(1e-4) + rate * (d - d0).days / 365.25 for d in dates]
    slope, ci, icpt = fit_drift(dates, y, [0.02] * 5)
    assert slope == pytest.approx(rate, rel=1e-9)
    assert icpt == pytest.approx(math.log(1e-4))
    # exact line: no inflation; var = 1 / sum w (t - tbar)^2, t in years (whole days)
    t = [(d - d0).days / 365.25 for d in dates]
    sxx = sum((x - sum(t) / 5) ** 2 for x in t) / 0.02 ** 2
    assert ci[1] - slope == pytest.approx(1.959964 / math.sqrt(sxx), rel=1e-5)


def test_drift_flagged_in_the_fleet_only_when_it_excludes_zero():
    ests = []
    for k, day in enumerate((0, 120, 240, 360)):
        d = dt.date(2025, 1, 1) + dt.timedelta(days=day)
        for u, growth in (("steady", 1.0), ("aging", 1.5)):
            v = 1e-4 * growth ** (day / 365.25)
            ests.append(Estimate(u, f"{u}_{k}", "gx.noise_density", v, (v / 1.05, v * 1.05),
                                 date=d))
    drifts = {d.unit: d for d in fleet_table(ests).drifts}
    assert drifts["aging"].flagged and not drifts["steady"].flagged
    assert drifts["aging"].percent_per_year[0] == pytest.approx(50.0, rel=1e-3)


def test_log_se():
    assert log_se((1.0, math.e ** (2 * 1.959964))) == pytest.approx(1.0, rel=1e-6)
    assert log_se((0.0, 1.0)) is None and log_se(None) is None


def test_compare_flags_units_that_moved_beyond_their_intervals():
    from gmwm.fleet.core import compare_units

    def table(vals, rec):
        return {"units": [{"unit": u, "coefficient": "gx.noise_density", "recording": rec,
                           "value": v, "ci95": None if v is None else [v / 1.05, v * 1.05]}
                          for u, v in vals.items()]}

    old = table({"a": 1.0e-4, "b": 1.0e-4, "c": 1.0e-4}, "r1")
    new = table({"a": 1.01e-4, "b": 1.3e-4, "c": None}, "r2")
    rows = compare_units(old, new)
    assert [(r["unit"], r["moved"]) for r in rows] == [("a", False), ("b", True)]
    # ln(1.3) / sqrt(2 * (ln(1.05) / 1.96)^2)
    assert rows[1]["z"] == pytest.approx(math.log(1.3) / (math.sqrt(2) * math.log(1.05) / 1.959964),
                                         rel=1e-5)
    assert compare_units(old, old) == []  # the same recordings: nothing to compare
