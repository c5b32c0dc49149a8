"""gmwm.datasheet: datasheet coefficients of a fit, IEEE 952 Allan readings, Kalibr YAML."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from gmwm.datasheet import allan_readings, datasheet
from gmwm.model import Model
from gmwm.units import unit_system
from gmwm.wv import avar

FS = 200.0


def fake_result(spec: str, values: dict[str, float], se: dict[str, float] | None = None,
                freq: float = FS):
    """A fit-like object with the attributes the datasheet reads."""
    model = Model(spec, freq=freq)
    theta = np.array([values[n] for n in model.param_names], dtype=float)  # may sit on a bound
    s = np.full(theta.size, np.nan) if se is None else np.array([se[n] for n in model.param_names])
    return SimpleNamespace(model=model, params=theta, param_names=model.param_names, se=s,
                           cov=np.diag(s ** 2), wv=SimpleNamespace(freq=freq))


def test_gyro_coefficients_in_datasheet_units():
    # ARW 0.15 deg/sqrt(h), RRW 10 deg/h/sqrt(h), Q 2e-4 deg, rate ramp 30 deg/h/h (docs/METHODS.md §10)
    n, k, q, r = 0.15 / 60, 10 / 216000, 2e-4, 30 / 1.296e7
    res = fake_result("QN+WN+RW+DR", {"QN[1].Q2": (q * FS) ** 2, "WN[1].sigma2": n * n * FS,
                                       "RW[1].gamma2": k * k / FS, "DR[1].omega": r / FS})
    ds = datasheet(res, "deg/s")
    assert ds["ARW"]["value"] == pytest.approx(0.15, rel=1e-12) and ds["ARW"]["unit"] == "deg/sqrt(h)"
    assert ds["RRW"]["value"] == pytest.approx(10, rel=1e-12) and ds["RRW"]["unit"] == "deg/h/sqrt(h)"
    assert ds["QN"]["value"] == pytest.approx(2e-4, rel=1e-12) and ds["QN"]["unit"] == "deg"
    assert ds["RR"]["value"] == pytest.approx(30, rel=1e-12) and ds["RR"]["unit"] == "deg/h/h"
    assert ds["ARW"]["ci95"] is None  # no standard errors: no interval


def test_accelerometer_in_g_converts_to_si_labels():
    n = 0.05 / 60 / 9.80665  # VRW 0.05 m/s/sqrt(h) for a signal in g
    res = fake_result("WN+RW", {"WN[1].sigma2": n * n * FS, "RW[1].gamma2": 1e-14})
    ds = datasheet(res, "g")
    assert ds["VRW"]["value"] == pytest.approx(0.05, rel=1e-12) and ds["VRW"]["unit"] == "m/s/sqrt(h)"
    assert "AccRW" in ds and ds["AccRW"]["unit"] == "m/s/h/sqrt(h)"


def test_gm_ar1_and_sin_terms():
    res = fake_result("AR1+GM+SIN", {"AR1[1].phi": math.exp(-1 / (5.0 * FS)), "AR1[1].sigma2": 1e-6,
                                      "GM[1].beta": 0.01, "GM[1].sigma2": 4e-6,
                                      "SIN[1].alpha": 0.002, "SIN[1].beta": 2 * math.pi * 7 / FS})
    ds = datasheet(res, "rad/s")
    # AR1 -> GM[1] (5 s), the GM (100 s) -> GM[2]
    assert ds["GM[1]"]["correlation_time"]["value"] == pytest.approx(5.0, rel=1e-9)
    phi = math.exp(-1 / (5.0 * FS))
    assert ds["GM[1]"]["sigma"]["value"] == pytest.approx(math.sqrt(1e-6 / (1 - phi * phi)), rel=1e-9)
    assert ds["GM[2]"]["correlation_time"]["value"] == pytest.approx(100.0)
    assert ds["GM[2]"]["sigma"]["value"] == pytest.approx(2e-3) and ds["GM[2]"]["sigma"]["unit"] == "rad/s"
    assert ds["SIN[1]"]["frequency"]["value"] == pytest.approx(7.0) and ds["SIN[1]"]["frequency"]["unit"] == "Hz"
    assert ds["SIN[1]"]["amplitude"]["value"] == pytest.approx(0.002)


def test_negative_phi_stays_an_ar1_and_zero_component_has_no_time_scale():
    res = fake_result("2*AR1", {"AR1[1].phi": -0.5, "AR1[1].sigma2": 1.0, "AR1[2].phi": 0.9,
                                 "AR1[2].sigma2": 0.0})
    ds = datasheet(res)
    assert ds["AR1[1]"]["phi"]["value"] == -0.5
    assert ds["GM[1]"]["sigma"]["value"] == 0.0
    assert ds["GM[1]"]["correlation_time"]["value"] is None


def test_interval_is_the_image_of_the_parameter_interval():
    sigma2, se = 1.25e-3, 1e-5
    res = fake_result("WN", {"WN[1].sigma2": sigma2}, se={"WN[1].sigma2": se})
    e = datasheet(res, "deg/s")["ARW"]
    # N = 60 sqrt(sigma2 / fs) of the sigma2 interval [sigma2 - z se, sigma2 exp(z se / sigma2)]
    z = 1.959963984540054
    n = lambda s2: 60 * math.sqrt(s2 / FS)
    assert e["ci95"][0] == pytest.approx(n(sigma2 - z * se), rel=1e-12)
    assert e["ci95"][1] == pytest.approx(n(sigma2 * math.exp(z * se / sigma2)), rel=1e-12)


def test_generic_unit_labels():
    us = unit_system("V")
    assert us.white[0] == "V/sqrt(Hz)" and us.sensor is None
    assert unit_system("dps").unit == "deg/s" and unit_system("m/s2").sensor == "accelerometer"


def test_allan_readings_recover_n_and_k_on_a_simulation():
    fs, n, k = 100.0, 0.01, 1e-3  # N [u sqrt(s)], K [u/sqrt(s)]; crossover near 17 s of 2621 s
    model = Model("WN+RW", freq=fs)
    x = model.simulate(np.array([n * n * fs, k * k / fs]), 2**18, np.random.default_rng(11))
    r = allan_readings(avar(x, freq=fs), "rad/s")
    assert r["N"]["value"] == pytest.approx(n, rel=0.02)  # ~0.3 % MC error at 2^18 samples
    assert r["N"]["ci95"][0] < n < r["N"]["ci95"][1]
    assert r["N"]["tau_range_s"][0] <= 1.0 <= r["N"]["tau_range_s"][1] and not r["N"]["extrapolated"]
    assert r["K"]["value"] == pytest.approx(k, rel=0.35)  # a few long clusters: ~15 % MC error
    assert r["K"]["ci95"][0] < k < r["K"]["ci95"][1]
    # B: the AD minimum / 0.6643, in the unit of the signal for rad/s
    adev = np.sqrt(avar(x, freq=fs).avar)
    assert r["B"]["value"] == pytest.approx(adev.min() / 0.6643, rel=1e-3)


def test_allan_readings_without_random_walk_region():
    x = np.random.default_rng(2).standard_normal(2**14)
    r = allan_readings(avar(x, freq=10.0), "deg/s")
    assert r["K"]["value"] is None and "slope +0.5" in r["K"]["note"]
    assert r["N"]["unit"] == "deg/sqrt(h)" and r["B"]["unit"] == "deg/h"


def test_ar1_sigma_interval_is_unbounded_when_phi_may_be_one():
    # phi's interval reaches 1 (a random walk cannot be excluded): the stationary sigma has no
    # upper bound; the innovation variance is within 1.96 SE of 0, so the interval starts at 0
    res = fake_result("AR1", {"AR1[1].phi": 0.9995, "AR1[1].sigma2": 1e-6},
                      se={"AR1[1].phi": 1e-3, "AR1[1].sigma2": 1e-6})
    e = datasheet(res)["GM[1]"]
    assert e["sigma"]["ci95"] == [0.0, math.inf]
    assert e["correlation_time"]["ci95"][1] == math.inf
    # inside the domain: the delta method on the stationary variance (positive lower end)
    res = fake_result("AR1", {"AR1[1].phi": 0.9, "AR1[1].sigma2": 1e-2},
                      se={"AR1[1].phi": 1e-3, "AR1[1].sigma2": 1e-4})
    lo, hi = datasheet(res)["GM[1]"]["sigma"]["ci95"]
    assert 0 < lo < math.sqrt(1e-2 / (1 - 0.81)) < hi < math.inf


def test_a_process_the_datasheet_does_not_know_is_an_error(monkeypatch: pytest.MonkeyPatch):
    # a process class with no datasheet_kind (e.g. a new one) stops the datasheet: no silent gap
    from gmwm.errors import ModelError
    from gmwm.processes import PROCESSES

    res = fake_result("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6})
    assert set(datasheet(res, "deg/s")) == {"ARW", "RRW"}
    monkeypatch.setattr(PROCESSES["RW"], "datasheet_kind", None)
    with pytest.raises(ModelError, match="does not know process RW"):
        datasheet(res, "deg/s")


def test_every_process_says_what_it_gives_on_a_datasheet():
    from gmwm.processes import PROCESSES
    from gmwm.units import COEFFICIENT_KINDS

    us = unit_system("deg/s")
    for name, proc in PROCESSES.items():
        assert proc.datasheet_kind in (*COEFFICIENT_KINDS, "sinusoid", "gauss_markov", "ar1"), name
        if proc.datasheet_kind in COEFFICIENT_KINDS:
            us.coefficient(proc.datasheet_kind)
            # monotone increasing in the scale parameter, 0 at 0 (so intervals map end to end)
            assert proc.coefficient(0.0, FS) == 0.0 < proc.coefficient(1.0, FS) < proc.coefficient(
                2.0, FS), name
