"""Filter configuration files (gmwm.exports): round trip of every target, known truth, flagged
and absent terms, inflation, bad input."""

from __future__ import annotations

import json
import math
import re
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

import gmwm
from gmwm.errors import InputError
from gmwm.exports import (
    TARGETS,
    Inflation,
    noise_export,
    parse_inflation,
    parse_targets,
    render,
    write_exports,
)
from gmwm.model import Model

FS = 200.0
DEG = math.pi / 180


def fake_result(spec: str, values: dict[str, float], se: dict[str, float] | None = None,
                at_boundary: tuple[str, ...] = (), freq: float = FS):
    """A fit-like object with the attributes the exports read (no WV: no Allan readings)."""
    model = Model(spec, freq=freq)
    theta = np.array([values[n] for n in model.param_names], dtype=float)
    s = np.array([(se or {}).get(n, np.nan) for n in model.param_names])
    return SimpleNamespace(model=model, params=theta, param_names=model.param_names, se=s,
                           cov=np.diag(s ** 2), wv=SimpleNamespace(freq=freq),
                           diagnostics={"at_boundary": list(at_boundary), "warnings": []})


def wn_rw(n: float, k: float, rel_se: float = 0.01, freq: float = FS):
    """WN + RW with continuous densities n, k (signal units) and relative standard errors."""
    s2, g2 = n * n * freq, k * k / freq
    return fake_result("WN+RW", {"WN[1].sigma2": s2, "RW[1].gamma2": g2},
                       {"WN[1].sigma2": rel_se * s2, "RW[1].gamma2": rel_se * g2}, freq=freq)


def flat(text: str) -> str:
    """Comment text with the wrapped continuation lines joined (phrases may span lines)."""
    return re.sub(r"\n\s*#\s+(?=\S)", " ", text)


def read_back(path) -> dict:
    """Parse a written file as its target would: JSON, or YAML (OpenCV's '%YAML:1.0' line off)."""
    text = path.read_text()
    if path.suffix == ".json":
        return json.loads(text)
    if text.startswith("%YAML:1.0"):
        text = text.split("\n", 1)[1]
    return yaml.safe_load(text)


@pytest.fixture
def six_axes():
    """Gyro in deg/s (gy the worst), accelerometer in m/s^2 (az the worst white noise, ax the
    worst walk); densities in signal units."""
    g = {"gx": (0.05, 1e-3), "gy": (0.08, 2e-3), "gz": (0.06, 3e-3)}
    a = {"ax": (2e-2, 4e-3), "ay": (1e-2, 1e-3), "az": (3e-2, 2e-3)}
    per = {k: ("deg/s", wn_rw(*v)) for k, v in g.items()}
    per |= {k: ("m/s^2", wn_rw(*v)) for k, v in a.items()}
    truth = {("gyroscope", "noise_density"): 0.08 * DEG, ("gyroscope", "random_walk"): 3e-3 * DEG,
             ("accelerometer", "noise_density"): 3e-2, ("accelerometer", "random_walk"): 4e-3}
    return per, truth


# ---- inflation and targets: parsing, one-line errors -------------------------------------------


def test_parse_inflation():
    assert parse_inflation("noise=2,walk=10") == Inflation(2.0, 10.0)
    assert parse_inflation(" walk = 5 ") == Inflation(1.0, 5.0)
    assert parse_inflation("3") == Inflation(3.0, 3.0)
    assert parse_inflation(None) == parse_inflation("") == parse_inflation("none") == Inflation()
    assert Inflation().describe() == "none"
    assert "x2" in Inflation(2.0, 10.0).describe() and "x100 on the variances" in \
        Inflation(2.0, 10.0).describe()


@pytest.mark.parametrize("spec", ["noise=0.5", "noise=x", "gain=2", "noise=2,noise=3", "noise",
                                  "noise=inf", "walk=-1", "2,3"])
def test_bad_inflation_is_one_line_input_error(spec):
    with pytest.raises(InputError) as e:
        parse_inflation(spec)
    assert "\n" not in str(e.value) and "inflation" in str(e.value)


def test_parse_targets():
    assert parse_targets("kalibr, OpenVINS,vins") == ["kalibr", "openvins", "vins-fusion"]
    assert parse_targets("all") == list(TARGETS) and len(TARGETS) == 7
    assert parse_targets(["orbslam3", "lio_sam", "fastlio", "json", "kalibr", "kalibr"]) == [
        "orb-slam3", "lio-sam", "fast-lio", "json", "kalibr"]
    with pytest.raises(InputError, match="unknown export target 'rovio'; known: kalibr") as e:
        parse_targets("kalibr,rovio")
    assert "\n" not in str(e.value)


def test_bad_inputs_are_input_errors(six_axes):
    per, _ = six_axes
    with pytest.raises(InputError, match="fitted at 200 Hz but the update rate is 100 Hz"):
        noise_export(per, 100.0)
    with pytest.raises(InputError, match="not a ROS topic name"):
        noise_export(per, topic="imu data")
    with pytest.raises(InputError, match="no axis has a gyroscope or accelerometer unit"):
        noise_export({"x": ("", wn_rw(1.0, 1e-2))})
    with pytest.raises(InputError, match="unknown unit 'volt'"):
        noise_export({"x": ("volt", wn_rw(1.0, 1e-2))})
    with pytest.raises(InputError, match="different sampling frequencies"):
        noise_export({"gx": ("deg/s", wn_rw(0.1, 1e-3)),
                      "gy": ("deg/s", wn_rw(0.1, 1e-3, freq=100.0))})
    with pytest.raises(InputError, match="unknown axis rule"):
        noise_export(per, rule="mean")


# ---- round trip of every written file ----------------------------------------------------------


#: per target: key path -> (sensor, term, map of the continuous SI value and the rate)
CONT = lambda v, r: v
EXPECTED = {
    "kalibr": {("gyroscope_noise_density",): ("gyroscope", "noise_density", CONT),
               ("gyroscope_random_walk",): ("gyroscope", "random_walk", CONT),
               ("accelerometer_noise_density",): ("accelerometer", "noise_density", CONT),
               ("accelerometer_random_walk",): ("accelerometer", "random_walk", CONT)},
    "openvins": {("imu0", "gyroscope_noise_density"): ("gyroscope", "noise_density", CONT),
                 ("imu0", "gyroscope_random_walk"): ("gyroscope", "random_walk", CONT),
                 ("imu0", "accelerometer_noise_density"): ("accelerometer", "noise_density", CONT),
                 ("imu0", "accelerometer_random_walk"): ("accelerometer", "random_walk", CONT)},
    "vins-fusion": {("gyr_n",): ("gyroscope", "noise_density", lambda v, r: v * math.sqrt(2 * r)),
                    ("gyr_w",): ("gyroscope", "random_walk", lambda v, r: v * math.sqrt(r)),
                    ("acc_n",): ("accelerometer", "noise_density",
                                 lambda v, r: v * math.sqrt(2 * r)),
                    ("acc_w",): ("accelerometer", "random_walk", lambda v, r: v * math.sqrt(r))},
    "orb-slam3": {("IMU.NoiseGyro",): ("gyroscope", "noise_density", CONT),
                  ("IMU.GyroWalk",): ("gyroscope", "random_walk", CONT),
                  ("IMU.NoiseAcc",): ("accelerometer", "noise_density", CONT),
                  ("IMU.AccWalk",): ("accelerometer", "random_walk", CONT)},
    "lio-sam": {("lio_sam", "imuGyrNoise"): ("gyroscope", "noise_density", CONT),
                ("lio_sam", "imuGyrBiasN"): ("gyroscope", "random_walk", CONT),
                ("lio_sam", "imuAccNoise"): ("accelerometer", "noise_density", CONT),
                ("lio_sam", "imuAccBiasN"): ("accelerometer", "random_walk", CONT)},
    "fast-lio": {("mapping", "gyr_cov"): ("gyroscope", "noise_density", lambda v, r: v * v * r),
                 ("mapping", "b_gyr_cov"): ("gyroscope", "random_walk", lambda v, r: v * v * r),
                 ("mapping", "acc_cov"): ("accelerometer", "noise_density", lambda v, r: v * v * r),
                 ("mapping", "b_acc_cov"): ("accelerometer", "random_walk",
                                            lambda v, r: v * v * r)},
    "json": {("sensors", s, t, "value"): (s, t, CONT)
             for s in ("gyroscope", "accelerometer") for t in ("noise_density", "random_walk")},
}
TOPIC_KEY = {"kalibr": ("rostopic",), "openvins": ("imu0", "rostopic"),
             "vins-fusion": ("imu_topic",), "lio-sam": ("lio_sam", "imuTopic"),
             "fast-lio": ("common", "imu_topic"), "json": ("rostopic",)}
RATE_KEY = {"kalibr": ("update_rate",), "openvins": ("imu0", "update_rate"),
            "orb-slam3": ("IMU.Frequency",), "json": ("update_rate_hz",)}


def _get(d: dict, path: tuple[str, ...]):
    for k in path:
        d = d[k]
    return d


def test_every_target_round_trips(six_axes, tmp_path):
    per, truth = six_axes
    exp = noise_export(per, FS, topic="/imu0", inflation="noise=2,walk=10")
    paths = write_exports(exp, tmp_path, "all")
    assert sorted(p.name for p in paths) == sorted(t.filename for t in TARGETS.values())
    for name, path in zip(TARGETS, paths, strict=True):
        data = read_back(path)
        for key, (sensor, term, conv) in EXPECTED[name].items():
            c = exp.combined[sensor][term]
            factor = 2.0 if term == "noise_density" else 10.0
            # the worst axis of the fixture, inflated after the axis rule
            assert c.value == pytest.approx(factor * truth[sensor, term], rel=1e-12)
            assert _get(data, key) == pytest.approx(conv(c.value, FS), rel=1e-6), (name, key)
        if name in TOPIC_KEY:
            assert _get(data, TOPIC_KEY[name]) == "/imu0"
        if name in RATE_KEY:
            assert _get(data, RATE_KEY[name]) == FS
    assert exp.combined["gyroscope"]["noise_density"].axis == "gy"
    assert exp.combined["accelerometer"]["random_walk"].axis == "ax"
    # the JSON's per-axis continuous and discrete values
    j = read_back(tmp_path / "imu_noise.json")
    gy = j["axes"]["gy"]["noise_density"]
    assert gy["value"] == pytest.approx(0.08 * DEG, rel=1e-9)
    assert gy["discrete"]["value"] == pytest.approx(0.08 * DEG * math.sqrt(FS), rel=1e-9)
    ax = j["axes"]["ax"]["random_walk"]
    assert ax["discrete"]["value"] == pytest.approx(4e-3 / math.sqrt(FS), rel=1e-9)
    assert ax["ci95"][0] < ax["value"] < ax["ci95"][1]
    assert j["inflation"] == {"noise": 2.0, "walk": 10.0}
    assert j["sensors"]["gyroscope"]["noise_density"]["value_before_inflation"] == \
        pytest.approx(0.08 * DEG, rel=1e-9)


def test_opencv_reads_the_opencv_yaml_files(six_axes, tmp_path):
    """OpenVINS, VINS-Fusion and ORB-SLAM3 parse with cv::FileStorage; ORB-SLAM3 also insists
    that its IMU values are reals."""
    cv2 = pytest.importorskip("cv2")
    per, _ = six_axes
    exp = noise_export(per, FS, topic="/imu0")
    for name in ("openvins", "vins-fusion", "orb-slam3"):
        path = write_exports(exp, tmp_path, name)[0]
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        try:
            for key, (sensor, term, conv) in EXPECTED[name].items():
                node = fs.getNode(key[0])
                for k in key[1:]:
                    node = node.getNode(k)
                assert node.isReal(), (name, key)
                want = conv(exp.combined[sensor][term].value, FS)
                assert node.real() == pytest.approx(want, rel=1e-6)
        finally:
            fs.release()
    fs = cv2.FileStorage(str(tmp_path / "orb_slam3_imu.yaml"), cv2.FILE_STORAGE_READ)
    assert fs.getNode("IMU.Frequency").isReal() and fs.getNode("IMU.Frequency").real() == FS
    fs.release()


def test_every_text_file_states_units_convention_rule_interval(six_axes):
    per, _ = six_axes
    exp = noise_export(per, FS, inflation="walk=10")
    for name, target in TARGETS.items():
        if name == "json":
            conv = json.loads(target.render(exp))["conventions"]
            assert {"continuous", "discrete", "interval", "axis_rule", "inflation"} <= set(conv)
            continue
        text = flat(target.render(exp))
        assert "Axis rule: one value per sensor = the largest value" in text
        assert "Inflation: noise densities x1, random walks x10" in text
        assert "95 % CI [" in text and "Per axis" in text
        assert ("continuous-time" in text) != (name in ("vins-fusion", "fast-lio")) or \
            "discrete-time" in text
        assert "rad/s" in text and "m/s^2" in text


def test_vins_continuous_convention_writes_densities(six_axes):
    from gmwm.exports import vins_fusion_text

    exp = noise_export(six_axes[0], FS)
    data = yaml.safe_load(vins_fusion_text(exp, "continuous").split("\n", 1)[1])
    assert data["gyr_n"] == pytest.approx(0.08 * DEG, rel=1e-6)
    assert data["acc_w"] == pytest.approx(4e-3, rel=1e-6)
    with pytest.raises(InputError, match="unknown VINS-Fusion convention"):
        vins_fusion_text(exp, "discrete")


# ---- flagged and absent terms: never a silent 0 ------------------------------------------------

_NUMBER_LINE = re.compile(r"^\s*[A-Za-z_.]+:\s*(?P<v>[-+]?[0-9.]+(?:e[-+]?[0-9]+)?)\s*(#.*)?$")


def zero_keys(text: str) -> list[str]:
    """Lines of ``text`` that set a key to the number 0."""
    return [ln for ln in text.splitlines()
            if (m := _NUMBER_LINE.match(ln)) and float(m.group("v")) == 0.0]


def test_weak_term_written_as_upper_bound_with_comment(tmp_path):
    weak = fake_result("WN+RW", {"WN[1].sigma2": 1e-6 * FS, "RW[1].gamma2": 1e-12},
                       {"WN[1].sigma2": 1e-8 * FS, "RW[1].gamma2": 1e-12})
    per = {"gx": ("rad/s", weak), "gy": ("rad/s", wn_rw(1e-3, 1e-6))}
    exp = noise_export(per, FS)
    t = exp.axes["gx"].random_walk
    assert t.flag == "weak" and t.value == t.ci95[1] > t.estimate
    c = exp.combined["gyroscope"]["random_walk"]
    assert c.axis == "gx" and c.flag == "weak" and c.flagged == ("gx",)
    text = render(exp, "kalibr")
    block = flat(text.split("gyroscope_random_walk [")[1].split("\ngyroscope_random_walk:")[0])
    assert "not distinguishable from zero" in block and "95 % upper bound" in block
    assert "longer recording" in block
    assert yaml.safe_load(text)["gyroscope_random_walk"] == pytest.approx(t.value, rel=1e-6)
    # the estimate policy keeps the estimate, still flagged
    est = noise_export(per, FS, flagged="estimate")
    assert est.axes["gx"].random_walk.value == pytest.approx(t.estimate)


def test_boundary_term_from_a_real_fit_is_its_upper_bound(tmp_path):
    """White noise fitted with WN+RW: the RW vanishes; the file carries its 95 % upper bound with
    a comment, never a 0."""
    x = np.random.default_rng(5).standard_normal(2**13) * 1e-3 * math.sqrt(FS)
    res = gmwm.fit(x, Model("WN+RW", freq=FS))
    assert "RW[1]" in res.diagnostics["at_boundary"]
    exp = noise_export({"gz": ("rad/s", res)}, topic="/imu/data")
    t = exp.axes["gz"].random_walk
    assert t.flag == "boundary" and t.estimate == 0.0 and t.ci95[0] == 0.0
    assert t.value == t.ci95[1] > 0
    for name in TARGETS:
        if name == "json":
            continue
        text = render(exp, name)
        assert [ln for ln in zero_keys(text) if "time_offset" not in ln] == [], name
        assert "at the boundary 0" in flat(text) and "95 % upper bound" in flat(text), name
    data = yaml.safe_load(render(exp, "kalibr"))
    assert data["gyroscope_random_walk"] == pytest.approx(t.value, rel=1e-6)
    assert data["rostopic"] == "/imu/data"
    # the accelerometer has no axis: its keys are left out, with the reason
    assert "accelerometer_noise_density" not in data
    assert "NOT WRITTEN (no accelerometer axis)" in flat(render(exp, "kalibr"))


def test_boundary_without_upper_bound_and_absent_term_are_left_out():
    at0 = fake_result("WN+RW", {"WN[1].sigma2": 1e-6 * FS, "RW[1].gamma2": 0.0},
                      {"WN[1].sigma2": 1e-8 * FS}, at_boundary=("RW[1]",))
    wn_only = fake_result("WN", {"WN[1].sigma2": 1e-4 * FS}, {"WN[1].sigma2": 1e-6 * FS})
    exp = noise_export({"gx": ("rad/s", at0), "ax": ("m/s^2", wn_only)})
    assert exp.axes["gx"].random_walk.flag == "boundary"
    assert exp.combined["gyroscope"]["random_walk"].value is None
    assert exp.combined["accelerometer"]["random_walk"].missing == ("ax",)
    for name in ("kalibr", "lio-sam", "fast-lio"):
        text = render(exp, name)
        assert "NOT WRITTEN" in text
        assert zero_keys(text) == []
    data = yaml.safe_load(render(exp, "kalibr"))
    assert "gyroscope_random_walk" not in data and "accelerometer_random_walk" not in data
    assert data["gyroscope_noise_density"] == pytest.approx(1e-3, rel=1e-9)
    text = flat(render(exp, "kalibr"))
    assert "the model of ax has no RW component" in text
    assert "at the boundary 0 with no upper bound available" in text
    j = json.loads(render(exp, "json"))
    assert j["sensors"]["accelerometer"]["random_walk"]["value"] is None
    assert j["axes"]["ax"]["random_walk"]["estimate"] is None


def test_terms_without_a_field_are_comments_with_values():
    gm = fake_result("WN+GM+RW", {"WN[1].sigma2": 1e-6 * FS, "GM[1].beta": 0.1,
                                  "GM[1].sigma2": 1e-6, "RW[1].gamma2": 1e-12 / FS},
                     {"WN[1].sigma2": 1e-8 * FS, "GM[1].beta": 0.01, "GM[1].sigma2": 1e-7,
                      "RW[1].gamma2": 1e-13 / FS})
    exp = noise_export({"gx": ("rad/s", gm)})
    text = render(exp, "kalibr")
    line = next(ln for ln in text.splitlines() if "gx GM[1]" in ln)
    assert "correlation time 10 s" in line and "sigma 0.001 rad/s" in line
    assert "GM[1]" in json.loads(render(exp, "json"))["axes"]["gx"]["other_terms"]


def test_rms_rule_and_unitless_axes_skipped(six_axes):
    per, _ = six_axes
    per = {**per, "temp": ("", wn_rw(1.0, 0.1))}
    exp = noise_export(per, FS, rule="rms")
    want = math.sqrt((0.05 ** 2 + 0.08 ** 2 + 0.06 ** 2) / 3) * DEG
    c = exp.combined["gyroscope"]["noise_density"]
    assert c.value == pytest.approx(want, rel=1e-12) and c.axis is None
    assert c.ci95[0] < c.value < c.ci95[1]
    text = flat(render(exp, "kalibr"))
    assert "root mean square" in text and "temp: no unit given" in text


# ---- known truth: simulate, fit, export --------------------------------------------------------


def test_known_truth_six_axis_imu(tmp_path):
    """Six axes with known densities (gyroscope in deg/s, accelerometer in g): the exported SI
    intervals cover the truth (at most 2 misses of 12 95 % intervals: 0.6 expected, more than 2
    has probability 0.02; a unit or conversion error misses all), none is flagged, and the Kalibr
    file carries the worst axis."""
    n, rng = 2**17, np.random.default_rng(20)
    gyro = {"gx": (1e-3, 5e-4), "gy": (1.5e-3, 4e-4), "gz": (1e-3, 8e-4)}    # rad/s, SI
    acc = {"ax": (2e-2, 1e-2), "ay": (2e-2, 8e-3), "az": (3e-2, 1.2e-2)}     # m/s^2, SI
    model = Model("WN+RW", freq=FS)
    per, truth = {}, {}
    for axes, unit, si in ((gyro, "deg/s", DEG), (acc, "g", 9.80665)):
        for name, (nd, rw) in axes.items():
            N, K = nd / si, rw / si  # in signal units
            theta = model.theta({"WN[1].sigma2": N * N * FS, "RW[1].gamma2": K * K / FS})
            per[name] = (unit, gmwm.fit(model.simulate(theta, n, rng), model))
            truth[name] = (nd, rw)
    exp = noise_export(per, topic="/imu0")
    misses = []
    for name, (nd, rw) in truth.items():
        a = exp.axes[name]
        for term, true in (("noise_density", nd), ("random_walk", rw)):
            t = a.term(term)
            assert t.flag is None and t.value == t.estimate, (name, term)
            assert true / 2 < t.ci95[0] < t.ci95[1] < 2 * true, (name, term, t)  # informative
            if not t.ci95[0] <= true <= t.ci95[1]:
                misses.append((name, term))
    assert len(misses) <= 2, misses
    data = read_back(write_exports(exp, tmp_path, "kalibr")[0])
    assert data["gyroscope_noise_density"] == pytest.approx(1.5e-3, rel=0.03)
    assert data["accelerometer_noise_density"] == pytest.approx(3e-2, rel=0.03)
    c = exp.combined["gyroscope"]["random_walk"]
    assert c.axis == max(("gx", "gy", "gz"), key=lambda k: exp.axes[k].random_walk.value)
    assert data["gyroscope_random_walk"] == pytest.approx(c.value, rel=1e-6)
    assert data["gyroscope_random_walk"] == pytest.approx(8e-4, rel=0.2)


# ---- the report writes the Kalibr file through the exports --------------------------------------


def test_report_writes_config_files_with_topic_and_inflation(tmp_path, one_process):
    from gmwm.report import write_report

    model = Model("WN+RW", freq=FS)
    rng = np.random.default_rng(3)
    axes = {}
    for name, unit in (("gx", "rad/s"), ("ax", "m/s^2")):
        x = model.simulate(model.theta({"WN[1].sigma2": 1e-6 * FS, "RW[1].gamma2": 1e-6 / FS}),
                           2**12, rng)
        res = gmwm.fit(x, model)
        axes[name] = {"result": res, "units": unit, "warnings": res.warnings,
                      "datasheet": res.datasheet(unit)}
    files = write_report(tmp_path / "r", axes, source="x.bag", title="t", topic="/imu0",
                         targets="kalibr,json", inflation="noise=2")
    assert {p.name for p in files} >= {"imu.yaml", "imu_noise.json", "report.md"}
    data = read_back(tmp_path / "r" / "imu.yaml")
    assert data["rostopic"] == "/imu0" and data["update_rate"] == FS
    assert "Inflation: noise densities x2" in flat((tmp_path / "r" / "report.md").read_text())
    with pytest.raises(InputError, match="unknown export target"):
        write_report(tmp_path / "r2", axes, source="x", title="t", targets="rovio")
    assert not (tmp_path / "r2" / "report.md").exists()
    # no sensor unit: no configuration file, and the report says why
    plain = {"x": {**axes["gx"], "units": ""}}
    files = write_report(tmp_path / "r3", plain, source="x", title="t")
    assert not any(p.suffix in (".yaml", ".json") for p in files)
    assert "no axis has a gyroscope or accelerometer unit" in flat((tmp_path / "r3" /
                                                                    "report.md").read_text())
