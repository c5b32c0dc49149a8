"""Sensor datasheets: coefficient units against hand-computed conversions, the YAML file's checks,
the datasheet -> model map (bias instability as a Gauss-Markov term), the datasheet's curves and
the verdict; ``--datasheet`` on ``gmwm fit`` and ``gmwm report``."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from gmwm import units as u
from gmwm.cli import main
from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.sensor_datasheet import (
    GM_PEAK_AD,
    GM_PEAK_X,
    VERDICT_RULE,
    bi_as_gauss_markov,
    bi_of_gauss_markov,
    compare,
    datasheet_curves,
    example_datasheets,
    load_datasheet,
    parse_datasheet,
    to_model,
)
from gmwm.sensor_datasheet import _interval_verdict as verdict
from gmwm.units import UNIT_SYSTEMS, coefficient_unit, convert, from_signal_units, to_signal_units
from gmwm.wv import wvar

G = 9.80665
DEG = math.pi / 180


# ---- units, against hand computations -----------------------------------------------------------

@pytest.mark.parametrize("value, src, dst, expected", [
    (0.66, "deg/sqrt(h)", "rad/s/sqrt(Hz)", 0.66 * DEG / 60),          # ARW -> Kalibr density
    (0.0135, "deg/s/rtHz", "deg/sqrt(h)", 0.0135 * 60),                 # density -> ARW
    (50, "ug/sqrt(Hz)", "m/s/sqrt(h)", 50e-6 * G * 60),                 # accel density -> VRW
    (0.23, "mg/√Hz", "m/s^2/sqrt(Hz)", 0.23e-3 * G),
    (1.34, "deg/h/sqrt(h)", "rad/s^2/sqrt(Hz)", 1.34 * DEG / 216000),   # RRW -> Kalibr
    (43.5, "m/s/h/sqrt(h)", "m/s^3/sqrt(Hz)", 43.5 / 216000),           # AccRW -> Kalibr
    (41.4, "m/s/h/h", "m/s^3", 41.4 / 3600 ** 2),                      # ramp
    (10, "deg/h", "rad/s", 10 * DEG / 3600),                            # bias instability
    (10, "°/hr", "dps", 10 / 3600),
    (0.05, "mg", "m/s^2", 0.05e-3 * G),
    (0.05, "mg", "ug", 50.0),
    (0.15, "deg/rt-hr", "deg/sqrt(s)", 0.15 / 60),
    (0.15, "°/√h", "arcsec/sqrt(s)", 0.15 / 60 * 3600),
    (2, "min", "s", 120.0),
    (3, "m/s²/√Hz", "m/s/sqrt(h)", 3 * 60),
])
def test_conversions_match_hand_computation(value, src, dst, expected):
    assert convert(value, src, dst) == pytest.approx(expected, rel=1e-12)
    assert convert(convert(value, src, dst), dst, src) == pytest.approx(value, rel=1e-12)


def test_signal_unit_forms_match_gmwm_units():
    # the §10.1 continuous forms in the signal unit, and the per-sample parameters of gmwm.units
    n = to_signal_units(0.15, "deg/sqrt(h)", "white", "deg/s")
    assert n == pytest.approx(0.15 / 60)
    assert to_signal_units(0.15, "deg/sqrt(h)", "white", "rad/s") == pytest.approx(0.15 / 60 * DEG)
    assert u.wn_from_density(n, 250) == pytest.approx(u.wn_from_arw_per_sqrt_hour(0.15, 250))
    k = to_signal_units(1.34, "deg/h/sqrt(h)", "random_walk", "deg/s")
    assert u.rw_gamma2_from_coefficient(k, 250) == pytest.approx(u.rw_from_per_hour_sqrt_hour(1.34,
                                                                                            250))
    assert to_signal_units(0.05, "mg", "level", "g") == pytest.approx(0.05e-3)
    assert to_signal_units(100, "s", "time", "deg/s") == 100.0
    assert from_signal_units(n, "white", "deg/s", "deg/sqrt(h)") == pytest.approx(0.15)


@pytest.mark.parametrize("signal", list(UNIT_SYSTEMS))
def test_every_report_label_parses_to_its_own_factor(signal):
    """The labels gmwm.datasheet prints (deg/sqrt(h), m/s/h/sqrt(h), mg, ...) read back to the
    factor the unit system applies: the two tables agree."""
    us = UNIT_SYSTEMS[signal]
    for kind, (label, factor) in (("white", us.white), ("random_walk", us.rw),
                                  ("quantization", us.qn), ("ramp", us.ramp),
                                  ("level", us.level)):
        assert to_signal_units(1.0, label, kind, signal) == pytest.approx(1.0 / factor, rel=1e-12)


@pytest.mark.parametrize("text, fragment", [
    ("furlong/s", "unknown unit 'furlong'"),
    ("deg/sqrt(h", "missing ')'"),
    ("deg^x", "exponent must be a number"),
    ("", "empty unit"),
])
def test_bad_units_are_one_line_errors(text, fragment):
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)")) as exc:
        coefficient_unit(text)
    assert "\n" not in str(exc.value)


def test_wrong_dimension_is_refused():
    with pytest.raises(InputError, match="cannot convert deg/h"):
        convert(1.0, "deg/h", "m/s/sqrt(h)")
    with pytest.raises(InputError, match="not a white term of a gyroscope"):
        to_signal_units(1.0, "m/s/sqrt(h)", "white", "deg/s")


# ---- the YAML file ---------------------------------------------------------------------------------

def write(tmp_path, text: str):
    p = tmp_path / "sheet.yaml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, fragment", [
    ("gyroscope:\n  white: 0.1 deg/sqrt(h)\ncolour: red\n", "colour: unknown key"),
    ("gyroscope:\n  whte: 0.1 deg/sqrt(h)\n", "gyroscope.whte: unknown term"),
    ("gyroscope:\n  white: 0.1\n", "gyroscope.white: 0.1 has no unit"),
    ("gyroscope:\n  white: -0.1 deg/sqrt(h)\n", "gyroscope.white: value must be positive"),
    ("gyroscope:\n  white: 0.1 m/s/sqrt(h)\n", "gyroscope.white: 0.1 m/s/sqrt(h) is not a white"),
    ("gyroscope:\n  white: 0.1 deg/parsec\n", "gyroscope.white: unit 'deg/parsec'"),
    ("accelerometer:\n  bias_instability: {value: 0.05 mg, correlation_time: 3 m}\n",
     "accelerometer.bias_instability.correlation_time: 3 m is not a time"),
    ("gyroscope:\n  gauss_markov: {sigma: 1 deg/h}\n", "gyroscope.gauss_markov: expected"),
    ("gyroscope: {}\n", "gyroscope: no noise term given"),
    ("part: x\n", "needs a 'gyroscope' or 'accelerometer' section"),
    ("gyroscope:\n  white: [0.1\n", "not valid YAML (line"),
    ("- 1\n- 2\n", "expected a mapping"),
    ("rate: 5 m\ngyroscope:\n  white: 0.1 deg/sqrt(h)\n", "rate: cannot convert"),
    ("gyroscope:\n  arw: 0.1 deg/sqrt(h)\n  white: 0.2 deg/sqrt(h)\n", "white given twice"),
])
def test_yaml_errors_name_the_key(tmp_path, text, fragment):
    with pytest.raises(InputError) as exc:
        load_datasheet(write(tmp_path, text))
    msg = str(exc.value)
    assert fragment in msg and "\n" not in msg and "sheet.yaml" in msg


def test_missing_file_lists_the_examples(tmp_path):
    with pytest.raises(InputError, match="not found.*stim300"):
        load_datasheet(tmp_path / "nope.yaml")


def test_value_forms_and_aliases():
    sheet = parse_datasheet({"rate": "200 Hz", "gyroscope": {
        "ARW": "0.15 deg/sqrt(h)", "rrw": {"value": 2, "unit": "deg/h/sqrt(h)"},
        "bi": {"value": "1 deg/h", "correlation_time": "2 min"},
        "gauss_markov": [{"sigma": "5 deg/h", "correlation_time": "10 s"}]}})
    g = sheet.sensor("gyroscope")
    assert sheet.rate == 200.0
    assert (g.white.value, g.white.unit) == (0.15, "deg/sqrt(h)")
    assert (g.random_walk.value, g.random_walk.unit) == (2.0, "deg/h/sqrt(h)")
    assert g.bi_correlation_time.value == 2 and len(g.gauss_markov) == 1
    with pytest.raises(InputError, match="no accelerometer section"):
        sheet.sensor("accelerometer")


@pytest.mark.parametrize("name", ["adis16448", "mti-1", "stim300"])
def test_packaged_examples_load_and_cite_a_source(name):
    assert name in example_datasheets()
    sheet = load_datasheet(name)
    assert sheet.source and "sheet" in sheet.source.lower()
    text = example_datasheets()[name].read_text()
    assert "Source:" in text  # every example cites where its numbers come from
    for spec in sheet.sensors.values():
        dm = to_model(spec, 100.0)
        assert "WN" in dm.model.spec


# ---- datasheet -> model ----------------------------------------------------------------------------

def test_gm_peak_constants():
    def g(x):
        return (2 * x - 3 + 4 * np.exp(-x) - np.exp(-2 * x)) / x ** 2

    r = minimize_scalar(lambda x: -g(x), bounds=(0.5, 5), method="bounded",
                        options={"xatol": 1e-10})
    assert r.x == pytest.approx(GM_PEAK_X, rel=1e-6)
    assert math.sqrt(g(r.x)) == pytest.approx(GM_PEAK_AD, rel=1e-9)


def test_bias_instability_gm_peaks_at_the_flicker_floor():
    """The GM standing for B = 10 deg/h with T_c = 100 s: its Allan deviation (exact discrete WV
    at 100 Hz, fine grid of cluster times) peaks at 0.6643 B near 1.89 T_c."""
    b, tc, fs = 10 / 3600, 100.0, 100.0   # in deg/s
    beta, s2 = bi_as_gauss_markov(b, tc)
    assert bi_of_gauss_markov(s2) == pytest.approx(b)
    m = Model("GM", freq=fs)
    clusters = np.geomspace(1, 1e5, 4000)  # samples
    adev = np.sqrt(2 * m.wv(m.theta({"GM[1].beta": beta, "GM[1].sigma2": s2}), 2 * clusters))
    i = int(np.argmax(adev))
    assert adev[i] == pytest.approx(math.sqrt(2 * math.log(2) / math.pi) * b, rel=2e-3)
    assert clusters[i] / fs == pytest.approx(GM_PEAK_X * tc, rel=0.01)


def test_to_model_parameters_and_correlation_time_rule():
    spec = parse_datasheet({"gyroscope": {"white": "0.15 deg/sqrt(h)",
                                          "random_walk": "10 deg/h/sqrt(h)",
                                          "bias_instability": "1 deg/h",
                                          "quantization": "1e-5 deg", "ramp": "3 deg/h/h"}}
                           ).sensor("gyroscope")
    dm = to_model(spec, 250.0, "deg/s")
    assert dm.model.spec == "QN+WN+GM+RW+DR" and dm.bi == "GM[1]"
    p = dm.model.as_dict(dm.theta)
    assert p["WN[1].sigma2"] == pytest.approx(u.wn_from_arw_per_sqrt_hour(0.15, 250))
    assert p["RW[1].gamma2"] == pytest.approx(u.rw_from_per_hour_sqrt_hour(10, 250))
    assert p["QN[1].Q2"] == pytest.approx((1e-5 * 250) ** 2)
    assert p["DR[1].omega"] == pytest.approx(u.dr_from_per_hour2(3, 250))
    # no correlation time given: the GM's AD peak where the WN and RW lines cross, sqrt(3) N / K
    n, k = 0.15 / 60, 10 / 216000
    assert 1 / p["GM[1].beta"] == pytest.approx(math.sqrt(3) * n / k / GM_PEAK_X)
    assert "not given" in dm.notes[0]
    given = parse_datasheet({"gyroscope": {"white": "0.15 deg/sqrt(h)", "bias_instability": {
        "value": "1 deg/h", "correlation_time": "5 min"}}}).sensor("gyroscope")
    dm2 = to_model(given, 250.0, "deg/s")
    assert 1 / dm2.model.as_dict(dm2.theta)["GM[1].beta"] == pytest.approx(300.0)
    assert "from the datasheet file" in dm2.notes[0]
    with pytest.raises(InputError, match="not a gyroscope unit"):
        to_model(given, 250.0, "m/s^2")


def test_datasheet_curves_keep_the_idealised_floor():
    spec = parse_datasheet({"accelerometer": {"white": "100 ug/sqrt(Hz)",
                                              "bias_instability": "0.05 mg"}}).sensor(
        "accelerometer")
    scales = 2.0 ** np.arange(1, 20)
    c = datasheet_curves(spec, scales, 200.0, "m/s^2")
    n2 = (100e-6 * G) ** 2 * 200.0
    floor = math.log(2) / math.pi * (0.05e-3 * G) ** 2
    np.testing.assert_allclose(c["wv"], n2 / scales + floor, rtol=1e-12)
    np.testing.assert_allclose(c["adev"], np.sqrt(2 * c["wv"]))


# ---- the verdict -----------------------------------------------------------------------------------

def test_verdict_rule():
    assert verdict(1.0, [0.9, 1.1], False) == "within"
    assert verdict(1.0, [0.5, 0.8], False) == "better"
    assert verdict(1.0, [1.2, 1.5], False) == "worse"
    assert verdict(10.0, [1.0, 5.0], True) == "shorter"
    assert verdict(1.0, None, False) == "no interval"
    assert "within" in VERDICT_RULE and "better" in VERDICT_RULE


def fake_fit(sigma2: float, se: float, freq: float = 100.0, n: int = 2 ** 16):
    """A WN fit-like object (what gmwm.datasheet reads) on a WV of white noise."""
    x = np.random.default_rng(1).normal(0, math.sqrt(sigma2), n)
    return SimpleNamespace(params=np.array([sigma2]), param_names=["WN[1].sigma2"],
                           se=np.array([se]), cov=np.array([[se * se]]), model=Model("WN", freq),
                           wv=wvar(x, freq=freq))


@pytest.mark.parametrize("arw, expected", [(0.15, "within"), (0.2, "better"), (0.1, "worse")])
def test_compare_converts_both_ways_and_judges(arw, expected):
    sigma2 = u.wn_from_arw_per_sqrt_hour(0.15, 100.0)   # a fit of exactly 0.15 deg/sqrt(h), 1 %
    res = fake_fit(sigma2, 0.01 * sigma2)
    spec = parse_datasheet({"gyroscope": {"white": f"{arw * DEG / 60} rad/s/sqrt(Hz)",
                                          "bias_instability": "10 deg/h"}}).sensor("gyroscope")
    rows = compare(res, spec, "deg/s")
    white = rows[0]
    assert white["term"] == "ARW" and white["unit"] == "rad/s/sqrt(Hz)"
    assert white["measured"] == pytest.approx(0.15 * DEG / 60, rel=1e-9)
    assert white["verdict"] == expected
    bi = rows[1]
    assert bi["term"] == "BI" and bi["unit"] == "deg/h" and "IEEE 952 reading" in bi["note"]
    with pytest.raises(InputError, match="not a gyroscope unit"):
        compare(res, spec, "m/s^2")


def test_term_missing_from_the_fit():
    res = fake_fit(1e-4, 1e-6)
    spec = parse_datasheet({"gyroscope": {"white": "0.1 deg/sqrt(h)",
                                          "random_walk": "1 deg/h/sqrt(h)"}}).sensor("gyroscope")
    rows = {r["term"]: r for r in compare(res, spec, "deg/s")}
    assert rows["RRW"]["verdict"] == "not in the fitted model" and rows["RRW"]["measured"] is None


# ---- --datasheet on fit and report ----------------------------------------------------------------

@pytest.fixture(scope="module")
def imu_csv(tmp_path_factory):
    """Two axes at 100 Hz (2^15 samples) from the ADIS16448 datasheet models (white noise), with a
    time column."""
    d = tmp_path_factory.mktemp("ds")
    sheet = load_datasheet("adis16448")
    rng = np.random.default_rng(11)
    n, fs = 2 ** 15, 100.0
    g = to_model(sheet.sensor("gyroscope"), fs, "deg/s")
    a = to_model(sheet.sensor("accelerometer"), fs, "m/s^2")
    cols = np.column_stack([np.arange(n) / fs, g.model.simulate(g.theta, n, rng),
                            a.model.simulate(a.theta, n, rng)])
    p = d / "imu.csv"
    np.savetxt(p, cols, delimiter=",", header="time,gx,ax", comments="", fmt="%.10g")
    return p


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_fit_with_datasheet_json_text_and_plot(capsys, imu_csv, tmp_path):
    code, out, err = run(capsys, "fit", imu_csv, "WN", "--columns", "gx,ax", "--units",
                         "gx=deg/s", "--units", "ax=m/s^2", "--datasheet", "adis16448", "--json")
    assert code == 0, err
    fits = json.loads(out)["fits"]
    for col, white, unit in (("gx", "ARW", "deg/sqrt(h)"), ("ax", "VRW", "m/s/sqrt(h)")):
        v = fits[col]["datasheet_verdict"]
        assert v["part"] == "ADIS16448" and v["rule"] == VERDICT_RULE
        (row,) = v["rows"]
        assert row["term"] == white and row["unit"] == unit
        # the recording is drawn from the datasheet: its value lies inside the measured interval
        assert row["verdict"] == "within"
        assert row["ci95"][0] < row["datasheet"] < row["ci95"][1]
        # the measured value is the fit's own coefficient, converted to the datasheet's unit
        assert row["measured"] == pytest.approx(fits[col]["datasheet"][white]["value"])
    png = tmp_path / "fit.png"
    code, out, err = run(capsys, "fit", imu_csv, "WN+GM", "--column", "gx", "--units", "deg/s",
                         "--datasheet", "mti-1", "--plot", png)
    assert code in (0, 3) and png.read_bytes().startswith(b"\x89PNG")
    assert "against the gyroscope section of the datasheet Xsens MTi-1" in out
    assert "rule: within" in out and "verdict" in out and "IEEE 952 reading" in out


def test_fit_with_datasheet_needs_units_and_a_matching_section(capsys, imu_csv, tmp_path):
    code, _, err = run(capsys, "fit", imu_csv, "WN", "--column", "gx", "--freq", "100",
                       "--datasheet", "mti-1")
    assert code == 1 and "give the unit of" in err and err.count("\n") == 1
    sheet = tmp_path / "accel_only.yaml"
    sheet.write_text("accelerometer:\n  white: 100 ug/sqrt(Hz)\n")
    code, _, err = run(capsys, "fit", imu_csv, "WN", "--column", "gx", "--units", "deg/s",
                       "--datasheet", sheet)
    assert code == 1 and "no fitted column is of a sensor type it describes" in err


@pytest.mark.slow
def test_report_with_datasheet(capsys, imu_csv, tmp_path):
    outdir = tmp_path / "rep"
    code, _, err = run(capsys, "report", imu_csv, "WN+GM", "--columns", "gx,ax", "--units",
                       "gx=deg/s", "--units", "ax=m/s^2", "--datasheet", "mti-1", "-o", outdir)
    assert code in (0, 3), err
    assert (outdir / "gx_adev.png").read_bytes().startswith(b"\x89PNG")
    md = (outdir / "report.md").read_text()
    assert "Against the gyroscope section of the datasheet Xsens MTi-1" in md
    assert "Against the accelerometer section" in md and "Rule: within" in md
    assert "| ARW | 0.007 |" in md and "deg/s/sqrt(Hz)" in md
    assert "Against the" in (outdir / "report.html").read_text()
