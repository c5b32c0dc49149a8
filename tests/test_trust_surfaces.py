"""One story on every surface (issue 40, part 3): the real moving recordings refused by default
and written under --allow-motion, the "every candidate rejected" hint naming the causes the data
show, and the report's summary table carrying the configuration file's numbers."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import load_benchmark
from gmwm.cli import main
from gmwm.cli.parser import EXIT_NO_CONFIGURATION

bs = load_benchmark("bench_stationarity")
EXTERNAL = bs.EXTERNAL
needs_external = pytest.mark.skipif(not EXTERNAL.is_dir(),
                                    reason="../shared/data/external absent")
FS = 100.0


def _csv(path: Path, x: dict, fs: float = FS, units: dict | None = None) -> Path:
    return bs.write_csv(path, x, fs, units)


def _report(capsys, out: Path, src: Path, *extra: str, model: str = "WN+RW"
            ) -> tuple[int, str]:
    code = main(["report", str(src), model, "-o", str(out), "-q", *extra])
    return code, capsys.readouterr().err


# ---- the report's summary table is the configuration file ------------------------------------
def _md_tables(md: str) -> dict[str, list[list[str]]]:
    """Caption (a heading or a bold line) -> rows (cells) of the Markdown table that follows."""
    out: dict[str, list[list[str]]] = {}
    head = None
    for line in md.splitlines():
        if line.startswith(("#", "**")):
            head = line.lstrip("# ").strip("* ")
        elif line.startswith("|") and head is not None and not set(line) <= set("|-: "):
            out.setdefault(head, []).append([c.strip() for c in line.strip("|").split("|")])
    return out


def _number(cell: str) -> float:
    return float(cell.removeprefix("≤").split()[0])


@pytest.mark.slow
def test_the_summary_table_carries_the_configuration_files_numbers(capsys, tmp_path):
    """One minute of a static MEMS at 100 Hz: the random walks are flagged (not identifiable at
    this length) and written as their 95 % upper bound. The summary's SI tables show, per axis,
    the value each file writes (marked as a bound, the estimate beside it) and, per sensor, the
    value of the Kalibr keys; one unit per column."""
    import yaml

    x = bs.static_imu(0, FS, 60.0, np.random.default_rng([40, 11]))
    src = _csv(tmp_path / "one_minute.csv", x)
    out = tmp_path / "rep"
    code, err = _report(capsys, out, src, "--export", "kalibr,json")
    assert code == 0, err
    keys = yaml.safe_load((out / "imu.yaml").read_text())
    per_axis = json.loads((out / "imu_noise.json").read_text())["axes"]
    tables = _md_tables((out / "report.md").read_text())
    seen_bound = False
    for sensor in ("gyroscope", "accelerometer"):
        caption = next(t for t in tables if t.startswith(f"{sensor.capitalize()}: the values"))
        header, *rows = tables[caption]
        assert header[3].endswith("/sqrt(Hz)]") and "[" in header[5]
        for row in rows[:-1]:
            axis = row[0]
            for col, term in ((3, "noise_density"), (5, "random_walk")):
                want = per_axis[axis][term]
                assert _number(row[col]) == pytest.approx(want["value"], rel=1e-3), (axis, term)
                if want["flag"] is not None:
                    seen_bound = True
                    assert row[col].startswith("≤"), (axis, term, row[col])
                    assert _number(row[col + 1]) == pytest.approx(want["estimate"], rel=1e-3,
                                                                   abs=1e-12)
                    assert _number(row[col + 1]) < _number(row[col])
                else:
                    assert not row[col].startswith("≤")
        last = rows[-1]
        assert last[0] == f"{sensor}_* keys"
        assert _number(last[3]) == pytest.approx(keys[f"{sensor}_noise_density"], rel=1e-3)
        assert _number(last[5]) == pytest.approx(keys[f"{sensor}_random_walk"], rel=1e-3)
    assert seen_bound, "no term was flagged: the test lost its point"
    # the datasheet-unit table is a separate table
    assert any(t.startswith("In datasheet units (") for t in tables)


@pytest.mark.slow
def test_the_summary_shows_a_fast_term_folded_into_the_noise_density(tmp_path):
    """White noise through a one-pole low-pass (phi 0.5) plus white noise, fitted WN + AR1: the
    AR1 is white at the sampling rate, the file writes the white-noise-equivalent density and
    the summary shows that value with the WN term and the AR1's share beside it."""
    from scipy.signal import lfilter

    import gmwm
    from gmwm.datasheet import datasheet
    from gmwm.report import write_report
    from gmwm.verdict import white_equivalent

    rng = np.random.default_rng([42, 1])
    e = rng.standard_normal(2**16)
    x = (lfilter([1.0], [1.0, -0.5], e) + 0.3 * rng.standard_normal(e.size)) * 1e-3
    res = gmwm.fit(x, "WN+AR1+RW", freq=200.0)
    we = white_equivalent(res)
    assert we.changed
    axes = {"gx": {"result": res, "units": "rad/s", "warnings": [],
                   "datasheet": datasheet(res, "rad/s")}}
    write_report(tmp_path, axes, source="x", title="t", targets=("kalibr", "json"))
    row = next(r for r in _md_tables((tmp_path / "report.md").read_text())[
        "Gyroscope: the values the configuration files carry"] if r[0] == "gx")
    written = json.loads((tmp_path / "imu_noise.json").read_text())["axes"]["gx"]
    assert _number(row[3]) == pytest.approx(written["noise_density"]["value"], rel=1e-3)
    assert _number(row[3]) == pytest.approx(we.density, rel=1e-3)
    assert f"(WN {we.white:.4g} + AR1[1] " in row[3] and "in quadrature)" in row[3]


# ---- the "every candidate rejected" hint -------------------------------------------------------
def _causes(choice) -> list[str]:
    """The causes the hint says the data show, in its order."""
    hint = choice.rejection_hint
    shown = hint.split("; not ruled out:")[0]
    return re.findall(r"\d\. ([a-z -]+):", shown)


def test_low_pass_filtering_is_named_first():
    """White noise through a one-pole low-pass (phi 0.8), fitted by the automatic model without
    Gauss-Markov terms (no candidate can follow the filter: every one is rejected): the WV rises
    over the shortest scales and the hint names the filter first."""
    from scipy.signal import lfilter

    from gmwm.automodel import choose_model
    from gmwm.verdict import short_scale_slope

    rng = np.random.default_rng([40, 21])
    x = lfilter([1.0], [1.0, -0.8], rng.standard_normal(2**15)) * 1e-3
    c = choose_model(x, freq=FS, kind="gyroscope", max_gm=0)
    assert not c.passed
    slope, flat = short_scale_slope(c.result.wv)
    assert flat and slope > 0  # theory for phi 0.8: +0.38 over the first three scales
    assert _causes(c) == ["on-board low-pass filtering"]
    assert "likely causes, in the order the data show them: 1. on-board low-pass" in c.warnings[0]
    assert "motion (not checked)" in c.warnings[0]


def test_white_noise_does_not_look_filtered():
    """The slope rule on white noise: -1 within its intervals, not flagged."""
    from gmwm import wvar
    from gmwm.verdict import short_scale_slope

    x = np.random.default_rng([40, 22]).standard_normal(2**15)
    slope, flat = short_scale_slope(wvar(x, freq=FS))
    assert slope == pytest.approx(-1.0, abs=0.05) and not flat


def test_a_short_record_is_named_first():
    """2000 samples (20 s at 100 Hz) of white noise with a sinusoid no candidate has (SIN
    candidates not tried): the hint names the length first (fewer than
    gmwm.verdict.MIN_SAMPLES)."""
    from gmwm.automodel import choose_model
    from gmwm.model import Model
    from gmwm.verdict import MIN_SAMPLES, causes_text, rejection_causes

    m = Model("WN+RW+SIN", FS)
    th = m.theta({"WN[1].sigma2": 1e-6, "RW[1].gamma2": 1e-12, "SIN[1].alpha": 3e-3,
                  "SIN[1].beta": 0.3})
    x = m.simulate_fast(th, 2000, np.random.default_rng([40, 23]))
    c = choose_model(x, freq=FS, kind="gyroscope", max_gm=1, sin=False)
    assert not c.passed
    assert _causes(c)[0] == "too short"
    causes = rejection_causes(c.result)
    assert causes[0].name == "too short" and causes[0].shown
    assert f"fewer than the {MIN_SAMPLES}" in causes[0].reason
    assert causes_text(causes).startswith("likely causes, in the order the data show them: "
                                          "1. too short: 2000 samples used")


def test_motion_and_temperature_from_the_calibration_path():
    """The calibration path passes what its stationarity check found (gmwm.verdict.evidence):
    a simulated recording with a turn flags motion on the turning axis, inside the estimate,
    which the hint then names; a bias following the temperature is named after it."""
    from gmwm.automodel import choose_model
    from gmwm.readers import read_recording
    from gmwm.stationarity import check_stationarity
    from gmwm.verdict import Evidence, evidence

    x = bs.static_imu(0, FS, 120.0, np.random.default_rng([40, 24]))
    bs.inject_turn(x, FS, 50.0, 20.0, 90.0)
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        rec = read_recording(_csv(Path(d) / "turn.csv", x))
    st = check_stationarity(rec, units=dict(bs.UNITS))
    moved = [c for c in bs.AXES if any(c in s.channels for s in st.segments)]
    assert moved
    ch = moved[0]
    ev = evidence(st, ch)
    assert ev.checked and ev.motion is not None and not ev.motion_excluded
    c = choose_model(x[ch][:2**13], freq=FS, kind="gyroscope", max_gm=0)
    # whatever the test says of this part, the hint with the evidence names the motion
    hinted = c.with_evidence(ev)
    assert "motion" in _causes(hinted)
    assert hinted.rejection_hint.index("motion: flagged at") < hinted.rejection_hint.index(
        "not ruled out")
    hot = c.with_evidence(Evidence(temperature="its bias follows the temperature (r = 0.9)",
                                   checked=True, temperature_checked=True))
    assert "temperature" in _causes(hot) and "motion" not in _causes(hot)
    assert "motion (none flagged)" in hot.rejection_hint
    # excluded motion is not a cause the data show any more
    out = evidence(st, ch, excluded=True)
    assert out.motion_excluded
    assert "motion" not in _causes(c.with_evidence(out))


def test_a_bias_following_the_temperature_is_named():
    """A warm-up (10 degC over the first minutes) the gx bias follows at 2e-3 rad/s per degC:
    the stationarity check links them, gmwm.verdict.evidence passes it on and the hint names the
    temperature among the causes the data show, ahead of those it does not."""
    import gmwm
    from gmwm.stationarity import check_stationarity
    from gmwm.verdict import causes_text, evidence, rejection_causes

    x = bs.static_imu(0, FS, 600.0, np.random.default_rng([40, 27]))
    n = x["gx"].size
    temp = 25.0 + 10.0 * (1 - np.exp(-np.arange(n) / (FS * 200.0)))
    x["gx"] += 2e-3 * (temp - 25.0)
    st = check_stationarity(x, freq=FS, units=dict(bs.UNITS), temperature=temp)
    ev = evidence(st, "gx")
    assert ev.temperature_checked and ev.temperature is not None
    assert "follows the temperature" in ev.temperature
    fit = gmwm.fit(x["gx"], "WN+RW", freq=FS)
    assert fit.gof.rejected()
    text = causes_text(rejection_causes(fit, evidence=ev))
    assert text.startswith("likely causes, in the order the data show them: 1. temperature: "
                           "its bias follows the temperature (")
    assert "motion (none flagged)" in text
    assert evidence(st, "gy").temperature is None  # gy does not follow it


@pytest.mark.slow
def test_the_calibration_path_gives_the_hint_the_motion_it_saw(capsys, tmp_path):
    """gmwm report with the automatic model on a recording with a 20-s turn, written under
    --allow-motion: every candidate is rejected and the hint names the motion the stationarity
    check flagged first (a random walk the length cannot identify is weaker evidence)."""
    x = bs.static_imu(0, FS, 164.0, np.random.default_rng([40, 25]))
    bs.inject_turn(x, FS, 60.0, 20.0, 90.0)
    src = _csv(tmp_path / "turn.csv", x)
    code, err = _report(capsys, tmp_path / "rep", src, "--columns", "gz", "--allow-motion",
                        "--export", "kalibr", model="auto")
    assert code == 0, err
    hint = next(ln for ln in err.splitlines() if "every candidate model is rejected" in ln)
    assert "likely causes, in the order the data show them: 1. motion: flagged at " in hint
    assert "inside the estimate" in hint and "not ruled out: on-board low-pass" in hint
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "1. motion: flagged at" in md


# ---- the real moving recordings ---------------------------------------------------------------
REAL = {  # file -> its longest static segment is long enough for a configuration
    "px4-pyulog-sample/sample.ulg": True,  # handled 0.87-8.4 s, then still: 8.4-68.88 s
    "ros1-rl-husky/test1.bag": False,  # 14.9 s at 30 Hz
    "ros1-imutools-phidgets/phidgets_imu_upside_down.bag": False,  # 2.7 s
    "euroc-kimera-v101/mav0/imu0/data.csv": False,  # 1.4 s
}


@needs_external
@pytest.mark.slow
@pytest.mark.parametrize("rel", bs.EXTERNAL_FILES)
def test_a_real_moving_recording_gives_no_configuration_unless_allowed(capsys, tmp_path, rel):
    """Each of the four moving recordings: by default the report but no configuration (exit
    status 5) and one verdict line naming the longest static segment and, when it is long
    enough for a configuration, how to calibrate it (else that it is too short); with
    --allow-motion a configuration whose first comment lines say the recording moved."""
    src = EXTERNAL / rel
    if not src.exists():
        pytest.skip(f"{src} absent")
    code, err = _report(capsys, tmp_path / "default", src, "--export", "kalibr")
    last = err.rstrip().splitlines()[-1]
    assert code == EXIT_NO_CONFIGURATION, last
    assert (tmp_path / "default" / "report.md").exists()
    assert not (tmp_path / "default" / "imu.yaml").exists()
    assert last.startswith("gmwm: verdict: configuration NOT written: the recording moved: ")
    assert "padded by 1 s), more than the 5 % that may be excluded" in last
    assert "the longest static segment is " in last and "--allow-motion" in last
    assert ("--segment longest-static" in last) == REAL[rel], last
    assert ("too short for a configuration" in last) != REAL[rel], last
    code, err = _report(capsys, tmp_path / "allowed", src, "--export", "kalibr",
                        "--allow-motion")
    last = err.rstrip().splitlines()[-1]
    assert code == 0, last
    assert last.startswith("gmwm: verdict: configuration written with")
    text = (tmp_path / "allowed" / "imu.yaml").read_text()
    head = text.split("\n\n")[0]
    assert head.startswith("# CAUTION") and "the recording MOVED" in head
    assert "these values describe the motion, not the sensor at rest" in " ".join(
        ln.strip("# ") for ln in head.splitlines())
