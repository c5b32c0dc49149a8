"""The rules between a calibration and the configuration file (gmwm.verdict)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import gmwm
from gmwm.model import Model
from gmwm.verdict import (
    FAST_TAU_SAMPLES,
    FLAGGED,
    MIN_SAMPLES,
    NOT_WRITTEN,
    WRITTEN,
    decide,
    misfit,
    too_short,
    unit_warning,
    white_equivalent,
)


def _fake(spec: str, values: dict[str, float], freq: float, cov: np.ndarray | None = None):
    m = Model(spec, freq)
    return SimpleNamespace(model=m, params=m.theta(values), cov=cov)


def test_fast_gm_is_folded_into_the_noise_density_by_hand() -> None:
    """WN sigma2 = 1e-4 and a GM of correlation time 0.3 sampling intervals at 100 Hz: the GM's
    long-run variance per sample is sigma2 (1 + phi) / (1 - phi), phi = exp(-1/0.3)."""
    f, tau = 100.0, 0.3 / 100.0
    r = _fake("WN+GM", {"WN[1].sigma2": 1e-4, "GM[1].beta": 1 / tau, "GM[1].sigma2": 4e-4}, f)
    we = white_equivalent(r)
    phi = math.exp(-1 / 0.3)
    lrv = 4e-4 * (1 + phi) / (1 - phi)
    assert we.white == pytest.approx(math.sqrt(1e-4 / f))
    assert we.density == pytest.approx(math.sqrt((1e-4 + lrv) / f))
    assert [t.component for t in we.folded] == ["GM[1]"]
    assert we.folded[0].tau_samples == pytest.approx(0.3)
    assert "2 sampling intervals" in we.rule()
    # a slow GM (bias instability) is not folded
    slow = _fake("WN+GM", {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.01, "GM[1].sigma2": 4e-4}, f)
    assert not white_equivalent(slow).changed
    assert white_equivalent(slow).density == pytest.approx(math.sqrt(1e-4 / f))
    # a GM whose beta is at 0 (phi = 1 in double precision) is a bias, not white: no crash
    flat = _fake("WN+GM", {"WN[1].sigma2": 1e-4, "GM[1].beta": 1e-300, "GM[1].sigma2": 4e-4}, f)
    assert not white_equivalent(flat).changed
    # the threshold itself
    edge = _fake("AR1+WN", {"WN[1].sigma2": 1.0, "AR1[1].phi": math.exp(-1 / FAST_TAU_SAMPLES),
                            "AR1[1].sigma2": 1.0}, 1.0)
    assert white_equivalent(edge).changed


def test_the_delta_interval_by_hand() -> None:
    """With a diagonal covariance the interval is exp(+-1.96 SE / 2) around N on the log scale,
    SE of log N^2 = sqrt(sum g_i^2 var_i) / N^2."""
    cov = np.diag([1e-10, 1e-2, 1e-10])  # WN sigma2, GM beta, GM sigma2 (canonical order)
    m = Model("WN+GM", 100.0)
    assert m.param_names[:1] == ["WN[1].sigma2"]  # the covariance follows this order
    values = {"WN[1].sigma2": 1e-4, "GM[1].beta": 300.0, "GM[1].sigma2": 1e-4}
    r = SimpleNamespace(model=m, params=m.theta(values), cov=cov)
    we = white_equivalent(r)
    lo, hi = we.ci95
    assert lo < we.density < hi and math.log(hi / we.density) == pytest.approx(
        math.log(we.density / lo))


@pytest.fixture(scope="module")
def filtered_noise():
    """White noise through a one-pole low-pass (AR1, phi = 0.5: correlation time 1.44 samples)
    plus a little white noise, 2^16 samples at 200 Hz; true long-run density known."""
    rng = np.random.default_rng([42, 1])
    e = rng.standard_normal(2**16)
    from scipy.signal import lfilter

    x = lfilter([1.0], [1.0, -0.5], e) + 0.3 * rng.standard_normal(e.size)
    truth = math.sqrt((1 / 0.25 + 0.09) / 200.0)
    return x, truth


def test_low_pass_filtered_white_noise_gets_its_long_run_density(filtered_noise) -> None:
    """WN alone fitted to filtered noise gives the wrong (per-sample) level; WN + AR1 gives a
    split the data hardly identify, but the folded density is the long-run one within 5 %."""
    x, truth = filtered_noise
    res = gmwm.fit(x, "WN+AR1", freq=200.0)
    we = white_equivalent(res)
    assert we.changed and we.density == pytest.approx(truth, rel=0.05)
    assert we.ci95[0] <= truth * 1.05 and we.ci95[1] >= truth * 0.95
    assert abs(we.white / truth - 1) > 0.2  # the WN term alone would be far off


def test_misfit_of_a_rejected_model(filtered_noise) -> None:
    x, _ = filtered_noise
    res = gmwm.fit(x, "WN", freq=200.0)
    assert res.gof.rejected()
    mf = misfit(res)
    # white noise fitted to low-passed noise: the fit follows the (precise) short scales, where
    # the per-sample variance is low, so the model WV falls short at the long scales
    assert mf.relative < -0.5 and mf.scale_s > 10.0
    assert "departs" in mf.describe() and mf.outside > 0.5


def test_too_short_and_units() -> None:
    assert too_short(280) is not None and "280 samples" in too_short(280)
    assert too_short(MIN_SAMPLES) is None
    warn = unit_warning("gyroscope", 0.5)
    assert warn is not None and "deg/s read as rad/s" in warn
    assert unit_warning("gyroscope", 1e-3) is None
    assert unit_warning("accelerometer", 5.0) is not None
    assert unit_warning(None, 1e9) is None


def test_decide(filtered_noise) -> None:
    x, _ = filtered_noise
    good = gmwm.fit(x, "WN+AR1", freq=200.0)
    bad = gmwm.fit(x, "WN", freq=200.0)
    v = decide({"gx": good}, n_samples=x.size, kinds={"gx": "gyroscope"})
    assert v.status == FLAGGED and any("noise density includes AR1[1]" in c for c in v.caveats)
    v = decide({"gx": bad}, n_samples=x.size)
    assert v.written and any("REJECTED" in c and "departs" in c for c in v.caveats)
    v = decide({"gx": bad}, n_samples=280)
    assert v.status == NOT_WRITTEN and "NOT written" in v.line() and "280 samples" in v.line()
    v = decide({"gx": bad}, n_samples=x.size, refusals=["the recording moved"])
    assert not v.written
    # deg/s labelled rad/s: 57x the density
    v = decide({"gx": good}, n_samples=x.size, kinds={"gx": "gyroscope"}, to_si={"gx": 57.3 * 4})
    assert any("deg/s read as rad/s" in c for c in v.caveats)
    assert decide({}, n_samples=x.size).status == WRITTEN


def test_caveats_are_the_first_comment_lines_of_every_file(filtered_noise) -> None:
    import json

    from gmwm.exports import TARGETS, noise_export, render

    x, _ = filtered_noise
    good = gmwm.fit(x, "WN+AR1", freq=200.0)
    v = decide({"gx": good}, n_samples=x.size, kinds={"gx": "gyroscope"},
               caveats=["the recording moved: 3.1 % of the samples (12.0-14.5 s) excluded"])
    exp = noise_export({"gx": ("rad/s", good)}, caveats=v.caveats)
    for target in TARGETS:
        text = render(exp, target)
        if target == "json":
            assert json.loads(text)["caveats"] == list(v.caveats)
            continue
        comments = [ln for ln in text.splitlines() if ln.startswith("#")]
        assert comments[0].startswith(f"# CAUTION ({len(v.caveats)})"), target
        assert "recording moved" in comments[1], target
    plain = render(noise_export({"gx": ("rad/s", good)}), "kalibr")
    assert "CAUTION" not in plain
    # the value written is the white-noise-equivalent density, the WN term's beside it
    we = white_equivalent(good)
    term = exp.axes["gx"].noise_density
    assert term.value == pytest.approx(we.density) and term.ci95[0] < we.density < term.ci95[1]
    assert f"{we.white:.4g}" in term.note and "AR1[1]" in term.note
