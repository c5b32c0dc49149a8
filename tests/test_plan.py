"""Recording plans: the predicted precision is the fit's own sandwich at the model's values, the
identifiability rule and length searches, durations and targets, and ``gmwm plan`` (text, JSON,
plot, errors)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import gmwm
from gmwm.cli import main
from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.plan import (
    IDENTIFIABLE_RSE,
    _expected_wv,
    default_fit_options,
    format_duration,
    make_plan,
    parse_duration,
    parse_target,
    predict,
)

GYRO = Model("WN+GM+RW", freq=100.0)
THETA = GYRO.theta({"WN[1].sigma2": 1.1e-3, "GM[1].beta": 0.076, "GM[1].sigma2": 3.6e-5,
                    "RW[1].gamma2": 5.4e-10})


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


# ---- durations and targets -------------------------------------------------------------------------

@pytest.mark.parametrize("text, seconds", [("30min", 1800), ("2h", 7200), ("1.5d", 129600),
                                           ("90s", 90), ("1w", 604800), ("2 hr", 7200),
                                           ("1e3s", 1000)])
def test_parse_duration(text, seconds):
    assert parse_duration(text) == seconds


@pytest.mark.parametrize("bad", ["90", "2 fortnights", "-1h", "0s", ""])
def test_bad_durations(bad):
    with pytest.raises(InputError, match="duration"):
        parse_duration(bad)


def test_format_duration():
    assert format_duration(45) == "45 s"
    assert format_duration(750) == "12.5 min"
    assert format_duration(7560) == "2.1 h"
    assert format_duration(3 * 86400) == "3 d"


def test_parse_target():
    assert parse_target("RRW=20%") == ("RRW", 0.2)
    assert parse_target("RW[1].gamma2 = 0.1") == ("RW[1].gamma2", 0.1)
    for bad in ("RRW", "RRW=abc", "RRW=0%", "=5%"):
        with pytest.raises(InputError, match="target"):
            parse_target(bad)


# ---- the prediction is the fit's sandwich ----------------------------------------------------------

@pytest.mark.slow
def test_prediction_equals_the_fits_standard_errors_on_the_expected_wv():
    """A fit of the WV a recording has on average, nu(theta) with its default interval, lands on
    theta; the SEs it reports are the prediction (same V, weights and sandwich)."""
    n = 2 ** 20
    pred = predict(GYRO, THETA, n)
    res = gmwm.fit(_expected_wv(GYRO, THETA, n), GYRO)
    np.testing.assert_allclose(res.params, THETA, rtol=1e-5)
    np.testing.assert_allclose(res.se, [pred.se[k] for k in GYRO.param_names], rtol=1e-3)
    assert pred.levels == res.wv.n_levels == 19 and pred.n_samples == n
    assert default_fit_options() == ("ci", "gmwm")


def test_white_noise_precision_scales_like_one_over_sqrt_t():
    wn = Model("WN", freq=1.0)
    theta = wn.theta({"WN[1].sigma2": 2.0})
    r1 = predict(wn, theta, 2 ** 16).rse["WN[1].sigma2"]
    r2 = predict(wn, theta, 2 ** 18).rse["WN[1].sigma2"]
    assert r2 / r1 == pytest.approx(0.5, rel=0.02)
    # white noise: the relative SE of sigma2 is about sqrt(2 / T) (the variance of a variance)
    assert r2 == pytest.approx(math.sqrt(2 / 2 ** 18), rel=0.1)


def test_coefficients_and_identifiability():
    short, long = predict(GYRO, THETA, 2 ** 14, unit="deg/s"), predict(GYRO, THETA, 2 ** 22,
                                                                      unit="deg/s")
    assert set(short.coefficients) == {"ARW", "GM[1].correlation_time", "GM[1].sigma", "RRW"}
    arw = long.coefficients["ARW"]
    assert arw["unit"] == "deg/sqrt(h)"
    assert arw["value"] == pytest.approx(math.sqrt(1.1e-3 / 100) * 60)
    # delta method: ARW = sqrt(sigma2 / f_s) has half the relative SE of sigma2
    assert arw["rse"] == pytest.approx(0.5 * long.rse["WN[1].sigma2"], rel=1e-4)
    lo, hi = arw["ci95"]
    assert lo < arw["value"] < hi and math.log(hi / arw["value"]) == pytest.approx(
        1.959964 * arw["rse"], rel=1e-4)
    assert not short.identifiable["RW[1]"] and long.identifiable["RW[1]"]
    assert short.rse["RW[1].gamma2"] > IDENTIFIABLE_RSE >= long.rse["RW[1].gamma2"]
    assert short.identifiable["WN[1]"]


def test_bi_coefficient_is_the_gm_peak():
    pred = predict(GYRO, THETA, 2 ** 20, unit="deg/s", bi="GM[1]")
    bi = pred.coefficients["BI"]
    assert bi["unit"] == "deg/h"
    sigma = math.sqrt(3.6e-5) * 3600
    assert bi["value"] == pytest.approx(0.6173642831444414 * sigma / 0.6642824702679827, rel=1e-9)
    assert bi["rse"] == pytest.approx(pred.coefficients["GM[1].sigma"]["rse"], rel=1e-4)


def test_predict_refuses_too_short_recordings():
    with pytest.raises(InputError, match="fewer than the 4 parameters"):
        predict(GYRO, THETA, 16)


# ---- lengths ---------------------------------------------------------------------------------------

@pytest.mark.slow
def test_min_length_and_target_are_where_the_criterion_switches():
    plan = make_plan(GYRO, THETA, [3600.0], unit="deg/s", targets=[("RRW", 0.2)])
    t = plan.min_length["RW[1]"]
    n = round(t * GYRO.freq)
    assert predict(GYRO, THETA, n).identifiable["RW[1]"]
    assert not predict(GYRO, THETA, round(n / 1.05)).identifiable["RW[1]"]
    target = plan.targets["RRW=0.2"]
    n = round(target["seconds"] * GYRO.freq)
    assert predict(GYRO, THETA, n, unit="deg/s").coefficients["RRW"]["rse"] <= 0.2
    assert predict(GYRO, THETA, round(n / 1.05), unit="deg/s").coefficients["RRW"]["rse"] > 0.2
    assert plan.min_length["WN[1]"] < 1.0


@pytest.mark.slow
def test_unreachable_target_and_unknown_name():
    plan = make_plan(GYRO, THETA, [3600.0], unit="deg/s", targets=[("RRW", 1e-4)],
                     max_search_s=86400.0)
    assert plan.targets["RRW=0.0001"]["seconds"] is None
    assert plan.targets["RRW=0.0001"]["duration"].startswith(">")
    with pytest.raises(InputError, match="not a coefficient or parameter.*RRW"):
        make_plan(GYRO, THETA, [3600.0], unit="deg/s", targets=[("RRX", 0.2)])


# ---- gmwm plan --------------------------------------------------------------------------------------

@pytest.mark.slow
def test_plan_json_from_a_datasheet(capsys):
    code, out, err = run(capsys, "plan", "--datasheet", "mti-1", "--sensor", "gyroscope", "--freq",
                         100, "--duration", "1h", "--duration", "6h", "--target", "BI=10%",
                         "--json")
    assert code == 0, err
    obj = json.loads(out)
    assert obj["command"] == "plan" and obj["datasheet"]["part"] == "Xsens MTi-1"
    assert obj["model"] == "WN+GM" and obj["freq"] == 100.0 and obj["units"] == "deg/s"
    assert [p["duration"] for p in obj["lengths"]] == ["1 h", "6 h"]
    for p in obj["lengths"]:
        assert set(p["se"]) == {"WN[1].sigma2", "GM[1].beta", "GM[1].sigma2"}  # as in gmwm fit
        assert set(p["coefficients"]) >= {"ARW", "BI"}
    assert obj["lengths"][1]["se"]["GM[1].beta"] < obj["lengths"][0]["se"]["GM[1].beta"]
    assert set(obj["min_length"]) == {"WN[1]", "GM[1]"}
    assert obj["min_length"]["GM[1]"]["term"] == "BI (GM[1])"
    assert any("absent from the model: random walk" in n for n in obj["notes"])
    t = obj["targets"]["BI=0.1"]
    assert t["name"] == "BI" and 3600 < t["seconds"] < 6 * 3600
    assert "correlation time" in obj["notes"][0] and "Wald" in obj["identifiable_rule"]


@pytest.mark.slow
def test_plan_text_and_plot_from_a_model(capsys, tmp_path):
    png = tmp_path / "plan.png"
    code, out, err = run(capsys, "plan", "WN+RW", "-p", "WN[1].sigma2=1.25e-3", "-p",
                         "RW[1].gamma2=3.9e-11", "--freq", 200, "--units", "deg/s", "--target",
                         "RRW=20%", "--duration", "30min", "--duration", "4h", "--plot", png)
    assert code == 0, err
    assert png.read_bytes().startswith(b"\x89PNG")
    assert "recording plan for the model WN+RW at 200 Hz, signal in deg/s" in out
    assert "identifiable from" in out and "RRW [deg/h/sqrt(h)]" in out
    assert "target RRW to 20% (relative SE): record" in out
    lines = [ln for ln in out.splitlines() if ln.strip().startswith(("30 min", "4 h"))]
    assert len(lines) == 2


def test_plan_every_sensor_of_a_datasheet(capsys):
    code, out, err = run(capsys, "plan", "--datasheet", "adis16448", "--freq", 200, "--duration",
                         "1h", "--json")
    assert code == 0, err
    plans = json.loads(out)["plans"]
    assert set(plans) == {"gyroscope", "accelerometer"}
    assert plans["accelerometer"]["units"] == "m/s^2"


@pytest.mark.parametrize("argv, code, fragment", [
    (["--datasheet", "mti-1", "WN"], 2, "not both"),
    ([], 2, "give a datasheet"),
    (["--datasheet", "mti-1"], 2, "give the sampling frequency"),
    (["WN", "-p", "WN[1].sigma2=1"], 2, "--freq"),
    (["--datasheet", "mti-1", "--freq", "100", "--duration", "90"], 1, "give a number and a unit"),
    (["--datasheet", "mti-1", "--freq", "100", "--target", "XYZ=10%"], 1, "not a coefficient"),
    (["--datasheet", "mti-1", "--freq", "100", "--sensor", "gyroscope", "--units", "m/s^2"], 1,
     "not a gyroscope unit"),
    (["--datasheet", "nope.yaml", "--freq", "100"], 1, "not found"),
    (["WN", "-p", "WN[1].sigma2=1", "--freq", "1", "--duration", "2s"], 1, "needs at least"),
])
def test_plan_errors_are_one_line(capsys, argv, code, fragment):
    got, out, err = run(capsys, "plan", *argv)
    assert got == code and fragment in err and err.count("\n") == 1 and out == ""


def test_plan_help_has_an_example(capsys):
    code, out, _ = run(capsys, "plan", "--help")
    assert code == 0 and "usage: gmwm plan" in out and "example" in out and "exit status" in out
