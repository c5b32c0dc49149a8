"""A configuration you can trust, or none (issue 40): motion excluded or refused, too little data,
unit mix-ups, the verdict on every surface (the configuration file's first lines, the report,
the terminal's last line and the exit status)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import load_benchmark
from gmwm.cli import main
from gmwm.cli.parser import EXIT_NO_CONFIGURATION

bs = load_benchmark("bench_stationarity")
FS = 100.0


def _csv(path: Path, x: dict, fs: float = FS, units: dict | None = None) -> Path:
    return bs.write_csv(path, x, fs, units)


def _static(seed: int, seconds: float = 240.0) -> dict[str, np.ndarray]:
    return bs.static_imu(0, FS, seconds, np.random.default_rng([40, seed]))


def _report(capsys, tmp_path: Path, src: Path, *extra: str) -> tuple[int, str, Path]:
    out = tmp_path / f"rep_{src.stem}_{len(extra)}"
    code = main(["report", str(src), "WN+RW", "-o", str(out), "-q", *extra])
    return code, capsys.readouterr().err, out


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("trust")
    knock = _static(1, 600.0)
    bs.inject_tilt(knock, FS, 300.0, 2.0, 20.0)  # one 2-s knock in 10 min: < 5 % with padding
    moved = _static(2)
    for t0 in (20.0, 80.0, 140.0):  # three 20-s turns: 25 % of the samples
        bs.inject_turn(moved, FS, t0, 20.0, 90.0)
    return {"knock": _csv(d / "knock.csv", knock), "moved": _csv(d / "moved.csv", moved),
            "static": _csv(d / "static.csv", _static(3)),
            "unknocked": _csv(d / "unknocked.csv", _static(1, 600.0))}


@pytest.mark.slow
def test_a_knock_is_excluded_and_the_files_say_so(capsys, tmp_path, recordings):
    code, err, out = _report(capsys, tmp_path, recordings["knock"])
    assert code == 0, err
    yaml = (out / "imu.yaml").read_text()
    first = yaml.splitlines()[:3]
    assert first[0].startswith("# CAUTION") and "motion excluded" in " ".join(first)
    assert "left out" in yaml and "padded by 1 s" in yaml
    md = (out / "report.md").read_text()
    assert "verdict: configuration written with" in md and "motion excluded" in md
    assert "excluded from the estimate" in md
    assert err.rstrip().splitlines()[-1].startswith("gmwm: verdict: configuration written with")


@pytest.mark.slow
def test_the_excluded_knock_leaves_the_coefficients_as_without_it(capsys, tmp_path, recordings):
    """The white-noise densities with the knock excluded are those of the same recording without
    the knock to within 2 % (the pooled clean parts hold 97 % of its samples)."""
    import yaml

    got = {}
    for name in ("knock", "unknocked"):
        code, err, out = _report(capsys, tmp_path, recordings[name])
        assert code == 0, err
        got[name] = yaml.safe_load((out / "imu.yaml").read_text())
    for key in ("gyroscope_noise_density", "accelerometer_noise_density"):
        assert got["knock"][key] == pytest.approx(got["unknocked"][key], rel=0.02), key
    assert got["knock"]["update_rate"] == FS


@pytest.mark.slow
def test_a_recording_that_moved_gives_no_configuration_unless_allowed(capsys, tmp_path,
                                                                      recordings):
    code, err, out = _report(capsys, tmp_path, recordings["moved"])
    assert code == EXIT_NO_CONFIGURATION
    assert (out / "report.md").exists() and not (out / "imu.yaml").exists()
    last = err.rstrip().splitlines()[-1]
    assert last.startswith("gmwm: verdict: configuration NOT written: the recording moved")
    assert "longest static segment" in last and "--segment longest-static" in last
    assert "--allow-motion" in last and "`" not in last
    assert "No filter configuration file written" in (out / "report.md").read_text()
    code, err, out = _report(capsys, tmp_path, recordings["moved"], "--allow-motion")
    assert code == 0
    yaml = (out / "imu.yaml").read_text()
    assert yaml.startswith("# CAUTION") and "MOVED" in yaml.split("\n\n")[0]
    code, err, out = _report(capsys, tmp_path, recordings["moved"], "--motion-share", "0.5")
    assert code == 0 and "motion excluded" in (out / "imu.yaml").read_text()


@pytest.mark.slow
def test_too_few_samples_give_no_configuration(capsys, tmp_path, recordings):
    """1.4 s at 100 Hz (140 samples) of a static recording: the report, not the file."""
    code, err, out = _report(capsys, tmp_path, recordings["static"], "--end", "1.4")
    assert code == EXIT_NO_CONFIGURATION and not (out / "imu.yaml").exists()
    assert "samples used: fewer than the 4096" in err.rstrip().splitlines()[-1]


@pytest.mark.slow
def test_a_random_walk_a_short_record_cannot_identify_is_flagged(capsys, tmp_path, recordings):
    """4 static minutes of a tactical MEMS: the random walks are not identifiable at this length
    (gmwm plan at the fitted values): each is named with the length that would identify it, and
    the file writes the flagged value (its 95 % upper bound), never the estimate as a
    measurement."""
    import yaml

    code, err, out = _report(capsys, tmp_path, recordings["static"])
    assert code == 0
    text = (out / "imu.yaml").read_text()
    head = text.split("\n\n")[0]
    assert head.startswith("# CAUTION") and "not identifiable at this length (4 min)" in head
    assert "identifiable from" in head
    body = " ".join(ln.strip("# ") for ln in text.splitlines() if ln.startswith("#"))
    assert "written as its 95 % upper bound" in body
    vals = yaml.safe_load(text)
    assert vals["gyroscope_random_walk"] > 0
    assert err.rstrip().splitlines()[-1].startswith("gmwm: verdict: configuration written with")


@pytest.mark.slow
def test_deg_s_labelled_rad_s_is_named(capsys, tmp_path):
    """A gyroscope recorded in deg/s (bias 1.5 deg/s) but labelled rad/s: the stationarity check
    sees 57x the noise as motion, and the verdict names the unit first; with --allow-motion the
    file's caveats name the mix-up too."""
    x = _static(4)
    for c in ("gx", "gy", "gz"):
        x[c] = np.degrees(x[c]) + 1.5
    src = _csv(tmp_path / "degs.csv", x)
    code, err, out = _report(capsys, tmp_path, src)
    last = err.rstrip().splitlines()[-1]
    assert code == EXIT_NO_CONFIGURATION and not (out / "imu.yaml").exists()
    assert "likely a unit mix-up, not motion" in last and "deg/s" in last
    code, err, out = _report(capsys, tmp_path, src, "--allow-motion")
    head = (out / "imu.yaml").read_text().split("\n\n")[0]
    assert code == 0 and "CAUTION" in head and "57.3x" in head


@pytest.mark.slow
def test_a_refused_recording_is_not_fitted_and_every_surface_says_so(capsys, tmp_path,
                                                                      recordings):
    """Refused for motion (no --allow-motion): no fit, but the report with each axis's WV of the
    part used; the verdict line, the JSON and the page say the axes were not fitted; exit
    status 5 as before."""
    import json

    import gmwm

    src = recordings["moved"]
    out = tmp_path / "rep"
    code = main(["report", str(src), "auto", "-o", str(out), "-q", "--json"])
    captured = capsys.readouterr()
    assert code == EXIT_NO_CONFIGURATION
    last = captured.err.rstrip().splitlines()[-1]
    assert last.startswith("gmwm: verdict: configuration NOT written: the recording moved")
    assert last.endswith("the axes were not fitted: refused for motion, a fit would describe "
                         "the motion, not the sensor at rest")
    obj = json.loads(captured.out)
    assert obj["fits"] == {} and obj["seconds"]["axes"] == {}
    assert obj["verdict"]["status"] == "not written"
    assert "gmwm: " + obj["verdict"]["line"] == last
    nf = obj["not_fitted"]
    assert "not fitted" in nf["reason"] and list(nf["axes"]) == list(bs.AXES)
    data = np.loadtxt(src, delimiter=",", skiprows=1)
    for i, c in enumerate(bs.AXES):  # the WV the fit would have used: the whole recording
        want = gmwm.wvar(data[:, 1 + i], freq=FS).variance
        np.testing.assert_allclose(nf["axes"][c]["wv"]["variance"], want, rtol=1e-12)
        assert nf["axes"][c]["units"] == bs.UNITS[c]
        assert (out / f"{c}_wv.png").exists()
    md = (out / "report.md").read_text()
    assert "The axes were not fitted: refused for motion" in md
    assert "No filter configuration file written" in md and not (out / "imu.yaml").exists()
    assert md.count("Not fitted: the wavelet variance of the part used") == len(bs.AXES)
    assert "the axes were not fitted" in (out / "report.html").read_text()
