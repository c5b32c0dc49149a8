"""Stationarity check of a calibration recording: did it move, step, drift or shake?

A static noise model (WN, QN, RW, GM, DR, ... of ``docs/METHODS.md`` §3) describes a recording
whose increments are stationary. Motion (a flight, a rover, someone picking the IMU up), a step
(a knock, a bias jump) or a burst of vibration violates that, and a fit then turns the motion into
"noise densities". :func:`check_stationarity` looks for such events **before** the wavelet
variance is computed, so a clean part can be selected (``docs/METHODS.md`` §16):

* **window means** (every axis, and the accelerometer norm ``|a|``): the difference of the means
  of two adjacent windows of L samples, on a grid of stride L/2, for window lengths L = L0, 2L0,
  4L0, ... Under a static model these differences are identically distributed with variance
  2 AV(L) (§2.4); each is standardised by a robust standard deviation of all of them (values
  beyond 3 scales of the median excluded, so motion confined to a minority of the windows does
  not inflate it) and flagged beyond a Bonferroni threshold over windows x lengths x channels x
  tests;
* **static ceiling** (axes with a known gyroscope or accelerometer unit): the scale is capped by
  sqrt(2 AV(L)) of the noisiest static MEMS sensor (:data:`STATIC_CEILING`), so a recording that
  moves throughout, whose own scale is inflated, is still flagged;
* **noise bursts**: the mean square of the first differences in windows (the local white-noise
  level), log-standardised by its median and robust scale, flagged upwards (vibration switched
  on);
* **temperature** (when the recording carries it): the windowed bias of each axis against the
  windowed temperature, differenced (a warning, not a motion flag).

The fitted model is not used: the part to fit is chosen before any fit, and a model fitted to a
moving recording absorbs the motion into its own Allan variance.

The result, :class:`StationarityReport`, lists flagged time ranges per channel and overall with
the statistic and threshold of each, offers :meth:`StationarityReport.clean_segment` (the longest
unflagged stretch) and carries a decimated timeline for :func:`gmwm.plots.plot_stationarity`.
Times are seconds since the first sample (samples when the recording has no rate).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["STATIC_CEILING", "Flag", "NonStationaryError", "Segment", "StationarityReport",
           "StationarityStream", "TemperatureCheck", "check_stationarity",
           "check_stationarity_stream"]

#: nominal family-wise false-alarm level of one recording (Bonferroni over all channels, window
#: lengths and tests); the realised rate on simulated static recordings is measured by
#: benchmarks/bench_stationarity.py (docs/stationarity_results.md)
ALPHA = 0.005
#: shortest window: max(8 samples, 0.1 s); motion shorter than that is not "a few seconds"
MIN_WINDOW_S = 0.1
MIN_WINDOW_SAMPLES = 8
#: a window length is tested only when it gives at least this many mean differences (the robust
#: scale of fewer is too uncertain)
MIN_DIFFS = 128
#: threshold inflation for the uncertainty of the robust scale from K differences:
#: z * (1 + SMALL_SAMPLE / sqrt(K)); calibrated on simulated static recordings
#: (benchmarks/bench_stationarity.py)
SMALL_SAMPLE = 2.0
#: noise-burst windows: max(32 samples, 0.5 s)
NOISE_WINDOW_S = 0.5
#: static ceiling per sensor type, SI units: (white noise density, bias-instability level,
#: rate random walk) = (rad/s/sqrt(Hz), rad/s, rad/s/sqrt(s)) for gyroscopes and
#: (m/s^2/sqrt(Hz), m/s^2, m/s^2/sqrt(s)) for accelerometers: about 2.5-4x the noisiest static
#: densities known to the project (a BMI160 measured at 1.2e-3 rad/s/sqrt(Hz) and 2e-2
#: m/s^2/sqrt(Hz), ten times its datasheet); see docs/METHODS.md §16.
STATIC_CEILING: Mapping[str, tuple[float, float, float]] = {
    "gyroscope": (5e-3, 2e-3, 1e-3),
    "accelerometer": (5e-2, 2e-2, 1e-2),
}
#: Allan variance of flicker noise = (2 ln 2 / pi) B^2 ([IEEE-952]; docs/METHODS.md §9.1)
_FLICKER_AV = 2.0 * math.log(2.0) / math.pi
_MAD = 1.482602218505602  # 1 / Phi^-1(3/4): MAD -> standard deviation for Gaussian data
_TRUNC = 3.0
_TRUNC_VAR = 0.9733369246625417  # E[Z^2 | |Z| < 3] for a standard normal Z
_TIMELINE_BINS = 1500
NORM = "|a|"


class NonStationaryError(InputError):
    """The recording moved (``--strict``)."""


@dataclass(frozen=True)
class Flag:
    """One flagged time range of one channel and test.

    ``test``: 'mean' (window means change beyond the recording's own static noise), 'ceiling'
    (beyond what any static sensor of that type shows) or 'noise' (a burst of the white-noise
    level); ``i0:i1`` samples, ``start_s``-``end_s`` seconds; ``peak_s`` where the largest
    statistic ``stat`` (threshold ``threshold``) lies, with window length ``window_s`` (s);
    ``size``: the largest change of adjacent window means (signal units; 'noise': the ratio of the
    windowed noise variance to its median)."""

    channel: str
    test: str
    i0: int
    i1: int
    start_s: float
    end_s: float
    peak_s: float
    window_s: float
    stat: float
    threshold: float
    size: float

    def to_json_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class Segment:
    """A flagged time range of the recording (union over channels): samples ``i0:i1``, seconds
    ``start_s``-``end_s``, the ``channels`` and ``tests`` that flag it, the largest ratio
    statistic / threshold ``severity``."""

    i0: int
    i1: int
    start_s: float
    end_s: float
    channels: tuple[str, ...]
    tests: tuple[str, ...]
    severity: float

    def to_json_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["channels"], d["tests"] = list(self.channels), list(self.tests)
        return d


@dataclass(frozen=True)
class TemperatureCheck:
    """Windowed bias against windowed temperature: temperature ``range_c`` (min, max in deg C);
    per channel ``(r, slope per deg C, p-value, follows)`` from the differenced window means;
    ``window_s`` the window length."""

    range_c: tuple[float, float]
    window_s: float
    channels: dict[str, tuple[float, float, float, bool]]
    source: str = ""

    @property
    def following(self) -> list[str]:
        return [c for c, v in self.channels.items() if v[3]]

    def to_json_dict(self) -> dict[str, Any]:
        return {"range_c": list(self.range_c), "window_s": self.window_s, "source": self.source,
                "channels": {c: {"r": v[0], "slope_per_c": v[1], "p": v[2], "follows": v[3]}
                             for c, v in self.channels.items()}}


@dataclass(frozen=True)
class StationarityReport:
    """What :func:`check_stationarity` found. ``flags`` per channel and test, ``segments`` their
    union; ``notes`` what was not tested and why, ``alerts`` warnings not tied to a time range;
    ``peaks`` per channel, test and window length (channel, test, window samples, number
    of statistics, largest statistic, its threshold); ``used`` the sample range the estimate
    uses (set by the caller with :meth:`using`; None: all); ``timeline`` channel -> (t, mean, min, max) per bin for plots;
    ``temperature_timeline`` (t, deg C) or None."""

    channels: tuple[str, ...]
    units: dict[str, str | None]
    n: int
    freq: float | None
    duration_s: float
    windows: tuple[int, ...]
    alpha: float
    n_tests: int
    threshold: float
    flags: tuple[Flag, ...]
    segments: tuple[Segment, ...]
    temperature: TemperatureCheck | None = None
    notes: tuple[str, ...] = ()
    alerts: tuple[str, ...] = ()
    peaks: tuple[tuple, ...] = ()
    timeline: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict, repr=False)
    temperature_timeline: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    time_s: np.ndarray | None = field(default=None, repr=False)
    used: tuple[int, int] | None = None
    used_how: str = "the whole recording"

    # ---- queries ---------------------------------------------------------------------------

    @property
    def tested(self) -> bool:
        """False when the recording was too short for any window length."""
        return bool(self.windows)

    @property
    def moving(self) -> bool:
        """Some part of the recording is flagged."""
        return bool(self.segments)

    def time_at(self, i: int) -> float:
        """Time of sample ``i`` (s since the first; samples without a rate); ``n``: the end."""
        if self.time_s is None or self.n == 0:
            return float(i) / (self.freq or 1.0)
        return float(self.time_s[min(max(i, 0), self.n - 1)]) if i < self.n else \
            float(self.time_s[-1]) + 1.0 / (self.freq or 1.0)

    def segments_in(self, i0: int = 0, i1: int | None = None) -> list[Segment]:
        """The flagged segments that overlap samples ``i0:i1``."""
        i1 = self.n if i1 is None else i1
        return [s for s in self.segments if s.i1 > i0 and s.i0 < i1]

    @property
    def moving_in_used(self) -> bool:
        a, b = self.used or (0, self.n)
        return bool(self.segments_in(a, b))

    def clean_segment(self, i0: int = 0, i1: int | None = None) -> tuple[int, int]:
        """The longest stretch of samples ``(a, b)`` within ``i0:i1`` (default: all) that no
        flagged segment touches; ``(i0, i0)`` when there is none."""
        i1 = self.n if i1 is None else i1
        edges, start = [], 0
        for s in self.segments:
            if s.i0 > start:
                edges.append((start, s.i0))
            start = max(start, s.i1)
        if start < self.n:
            edges.append((start, self.n))
        edges = [(max(a, i0), min(b, i1)) for a, b in edges]
        edges = [(a, b) for a, b in edges if b > a]
        if not edges:
            return (i0, i0)
        return max(edges, key=lambda e: e[1] - e[0])

    def using(self, i0: int, i1: int, how: str) -> StationarityReport:
        """A copy that records the part of the recording the estimate uses."""
        return replace(self, used=(int(i0), int(i1)), used_how=how)

    # ---- text ------------------------------------------------------------------------------

    def _unit_s(self) -> str:
        return "s" if self.freq else "samples"

    def fmt_time(self, v: float) -> str:
        """A time as text: seconds to 0.01 s, or whole samples without a rate."""
        if not self.freq:
            return str(round(v))
        return f"{v:.2f}".rstrip("0").rstrip(".")

    def span(self, a: float, b: float) -> str:
        """A time range as text with its unit, e.g. '12.5-15.02 s'."""
        return f"{self.fmt_time(a)}-{self.fmt_time(b)} {self._unit_s()}"

    def _range(self, a: float, b: float) -> str:
        return self.span(a, b)

    def used_text(self) -> str:
        """Which part of the recording the estimate uses, in words."""
        a, b = self.used or (0, self.n)
        full = f"{self._range(self.time_at(0), self.time_at(self.n))}"
        if (a, b) == (0, self.n):
            return f"the whole recording ({full}, {self.n} samples)"
        return (f"{self._range(self.time_at(a), self.time_at(b))} ({self.used_how}; samples {a}-{b - 1}, "
                f"{b - a} of {self.n}, {100 * (b - a) / max(self.n, 1):.3g} %) of {full}")

    def _describe(self, s: Segment) -> str:
        fl = [f for f in self.flags if f.i1 > s.i0 and f.i0 < s.i1]
        best = max(fl, key=lambda f: f.stat / f.threshold)
        what = {"mean": "window means change", "ceiling": "window means change",
                "noise": "the noise level rises"}[best.test]
        unit = self.units.get(best.channel) or ""
        if best.test == "noise":
            how = f"{best.size:.3g}x its median"
        else:
            how = f"by {best.size:.3g}{' ' + unit if unit else ''}"
        beyond = ("beyond any static sensor" if best.test == "ceiling" else
                  f"{best.stat:.3g} robust sd, threshold {best.threshold:.3g}")
        what = what.replace("window means", f"window means of {best.channel}").replace(
            "the noise level", f"the noise level of {best.channel}")
        return (f"{self._range(s.start_s, s.end_s)} ({', '.join(s.channels)}): {what} {how} "
                f"({beyond}; window {best.window_s:.3g} {self._unit_s()} at "
                f"{self.fmt_time(best.peak_s)} {self._unit_s()})")

    def warnings(self, limit: int = 5) -> list[str]:
        """One line per flagged range (the ``limit`` most severe, by time), the temperature
        warning and the alerts; what the estimate uses is said whenever something is flagged."""
        out: list[str] = []
        if self.segments:
            a, b = self.used or (0, self.n)
            inside = self.segments_in(a, b)
            top = sorted(sorted(self.segments, key=lambda s: -s.severity)[:limit],
                         key=lambda s: s.i0)
            share = sum(s.i1 - s.i0 for s in self.segments) / max(self.n, 1)
            head = (f"the recording is not static: {len(self.segments)} flagged range(s), "
                    f"{100 * share:.3g} % of the samples")
            if inside:
                head += (f"; the estimate uses {self.used_text()}, which includes "
                         f"{len(inside)} of them: a static noise model turns motion into noise "
                         "(use --segment longest-static or --start/--end)")
            else:
                head += f"; the estimate uses {self.used_text()}, which excludes them"
            out.append(head)
            for s in top:
                out.append("not static " + self._describe(s))
            if len(self.segments) > len(top):
                out.append(f"... and {len(self.segments) - len(top)} more flagged range(s)")
        t = self.temperature
        if t is not None and t.following:
            parts = []
            for c in t.following:
                r, slope, _, _ = t.channels[c]
                u = self.units.get(c) or "units"
                parts.append(f"{c} ({slope:.3g} {u}/degC, r = {r:.2f})")
            out.append(f"the bias follows the temperature ({t.range_c[0]:.3g}-{t.range_c[1]:.3g} "
                       f"degC{', ' + t.source if t.source else ''}): {', '.join(parts)}; a static "
                       "noise model absorbs this as drift or random walk")
        out.extend(self.alerts)
        return out

    def summary(self) -> str:
        """Several lines: the verdict, what was tested, the flagged ranges."""
        if not self.tested:
            return "stationarity not checked: " + "; ".join(self.notes)
        u = self._unit_s()
        w = [f"{L / (self.freq or 1.0):.3g}" for L in self.windows]
        lines = [("MOVING (not static)" if self.moving else "static (no window flagged)")
                 + f": {len(self.channels)} channel(s) ({', '.join(self.channels)}), "
                 f"window lengths {', '.join(w)} {u}; {self.n_tests} tests, family-wise "
                 f"false-alarm level {self.alpha:g} (Bonferroni threshold {self.threshold:.3g} "
                 "robust sd)",
                 f"estimate uses {self.used_text()}"]
        for s in self.segments:
            lines.append("  " + self._describe(s))
        t = self.temperature
        if t is not None:
            lines.append(f"temperature {t.range_c[0]:.3g}-{t.range_c[1]:.3g} degC"
                         + (f" ({t.source})" if t.source else "") + ": bias follows it in "
                         + (", ".join(t.following) if t.following else "no channel"))
        lines.extend(self.alerts)
        lines.extend(self.notes)
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        a, b = self.used or (0, self.n)
        return {
            "static": not self.moving, "tested": self.tested,
            "moving_in_used_part": self.moving_in_used,
            "used": {"i0": a, "i1": b, "start_s": self.time_at(a), "end_s": self.time_at(b),
                     "how": self.used_how},
            "clean_segment": dict(zip(("i0", "i1"), self.clean_segment(), strict=True)),
            "n": self.n, "freq": self.freq, "duration_s": self.duration_s,
            "windows": list(self.windows), "alpha": self.alpha, "n_tests": self.n_tests,
            "threshold": self.threshold,
            "peaks": [dict(zip(("channel", "test", "window", "count", "max_stat", "threshold"), p,
                               strict=True)) for p in self.peaks],
            "segments": [s.to_json_dict() for s in self.segments],
            "flags": [f.to_json_dict() for f in self.flags],
            "temperature": None if self.temperature is None else self.temperature.to_json_dict(),
            "notes": list(self.notes), "warnings": self.warnings(limit=10**6),
        }


# --------------------------------------------------------------------------------------------------
# the statistics
# --------------------------------------------------------------------------------------------------


def _si_factor(unit: str | None) -> tuple[str | None, float]:
    """(sensor type, SI value of one signal unit) of a unit, or (None, nan)."""
    from gmwm.units import SIGNAL_UNITS, parse_unit

    try:
        p = parse_unit(unit)
    except InputError:
        return None, float("nan")
    if p is None:
        return None, float("nan")
    return p[2], SIGNAL_UNITS[p[0]][1] * p[1]


def ceiling_sd(sensor: str, window_s: float) -> float:
    """sqrt(2 AV(L)) of the noisiest static sensor of type ``sensor`` at window ``window_s`` s
    (SI units): the standard deviation of the difference of two adjacent window means."""
    nd, b, k = STATIC_CEILING[sensor]
    av = nd ** 2 / window_s + _FLICKER_AV * b ** 2 + k ** 2 * window_s / 3.0
    return math.sqrt(2.0 * av)


@dataclass
class _Hits:
    """Flagged windows of one channel and test: sample spans, statistics and sizes."""

    i0: list[int] = field(default_factory=list)
    i1: list[int] = field(default_factory=list)
    peak: list[int] = field(default_factory=list)
    window: list[int] = field(default_factory=list)
    stat: list[float] = field(default_factory=list)
    thr: list[float] = field(default_factory=list)
    size: list[float] = field(default_factory=list)


def _z_quantile(p: float) -> float:
    from scipy.special import ndtri

    return float(-ndtri(p))


def _ladder(n: int, freq: float | None) -> list[int]:
    """Half-window lengths h (windows L = 2h) from max(8 samples, 0.1 s) upwards, doubling while
    the grid of stride h holds at least MIN_DIFFS differences."""
    L0 = MIN_WINDOW_SAMPLES if freq is None else max(MIN_WINDOW_SAMPLES,
                                                     math.ceil(MIN_WINDOW_S * freq))
    h = (L0 + 1) // 2
    out = []
    while n // h - 3 >= MIN_DIFFS:
        out.append(h)
        h *= 2
    return out


def _mean_diffs(B: np.ndarray, hs: list[int]) -> list[np.ndarray]:
    """Per half-window h: d_k = mean(x[kh:(k+2)h]) - mean(x[(k-2)h:kh]), k = 2..K-2, from the
    block means ``B`` of x over hs[0] samples (halved upwards by pairs)."""
    out = []
    for i, _h in enumerate(hs):
        if i:
            m = B.size // 2
            B = 0.5 * (B[: 2 * m: 2] + B[1: 2 * m: 2])
        out.append(0.5 * (B[2:-1] + B[3:] - B[:-3] - B[1:-2]))
    return out


def _noise_levels(b: np.ndarray, q: float) -> np.ndarray:
    """log of the mean square of first differences / 2 in windows of w samples, stride w/2, from
    the block means ``b`` of diff(x)^2 / 2 over w/2 samples."""
    v = 0.5 * (b[:-1] + b[1:]) + q * q / 12.0 + 1e-300
    return np.log(v)


def _robust(v: np.ndarray) -> tuple[float, float]:
    """Median and a robust standard deviation of ``v``: the standard deviation of the values
    within 3 scales of the median (Gaussian-consistent: / E[Z^2 | |Z| < 3]), the scale starting
    at 1.4826 MAD and refined twice. Values beyond 3 scales (motion in a minority of the
    windows) do not count; unlike the MAD alone it is nearly efficient and smooth for quantised
    signals, whose window means take few distinct values."""
    med = float(np.median(v))
    dev = np.abs(v - med)
    s = _MAD * float(np.median(dev))
    for _ in range(2):
        if s <= 0:
            break
        kept = dev[dev <= _TRUNC * s]
        s = math.sqrt(float(np.mean(kept * kept)) / _TRUNC_VAR)
    return med, s


@dataclass(frozen=True)
class _Level:
    """One test of one channel at one window length: statistic ``z`` per grid point (window
    boundary ``k * stride``, window ``window`` samples, span ``(k - back) * stride`` to
    ``(k + ahead) * stride``), ``size`` per point, and the test name."""

    test: str
    window: int
    stride: int
    back: int
    ahead: int
    offset: int
    z: np.ndarray
    size: np.ndarray


def _levels(sm: _Summary, hs: list[int], w_noise: int, freq: float | None, sensor: str | None,
            si: float) -> list[_Level]:
    """The standardised statistics of one channel (from its summary): window-mean differences
    per window length ('mean', or 'ceiling' where the static ceiling caps the robust scale) and
    the windowed white-noise level ('noise', upper side only)."""
    q = sm.quantum
    out = []
    for h, d in zip(hs, _mean_diffs(sm.means, hs), strict=True):
        L = 2 * h
        med, s = _robust(d)
        s = max(s, q / math.sqrt(6.0 * L))  # rounding noise of a quantised signal
        test = "mean"
        if sensor is not None and freq is not None:
            cap = ceiling_sd(sensor, L / freq) / si
            if cap < s:
                s, test = cap, "ceiling"
        dev = np.abs(d - med)
        out.append(_Level(test, L, h, 2, 2, 2, dev / max(s, np.finfo(float).tiny), dev))
    if w_noise and sm.n // (w_noise // 2) - 1 >= MIN_DIFFS:
        u = _noise_levels(sm.noise, q)
        med, s = _robust(u)
        if s > 0:
            out.append(_Level("noise", w_noise, w_noise // 2, 0, 2, 0, (u - med) / s,
                              np.exp(u - med)))
    return out


def _threshold(z0: float, k: int) -> float:
    """Bonferroni quantile z0, inflated for the uncertainty of a robust scale from k values."""
    return z0 * (1.0 + SMALL_SAMPLE / math.sqrt(k))


def _channel_hits(sm: _Summary, hs: list[int], w_noise: int, z0: float, freq: float | None,
                  sensor: str | None, si: float) -> tuple[dict[str, _Hits], list[tuple]]:
    """Flagged windows of one channel, for the tests 'mean', 'ceiling' and 'noise', and per
    test and window length (test, window, count, largest statistic, threshold)."""
    hits = {"mean": _Hits(), "ceiling": _Hits(), "noise": _Hits()}
    peaks = []
    for lv in _levels(sm, hs, w_noise, freq, sensor, si):
        thr = _threshold(z0, lv.z.size)
        peaks.append((lv.test, lv.window, int(lv.z.size), float(lv.z.max()), thr))
        idx = np.flatnonzero(lv.z > thr)
        if not idx.size:
            continue
        hh = hits[lv.test]
        k = idx + lv.offset  # boundary index on the grid of stride lv.stride
        hh.i0 += list((k - lv.back) * lv.stride)
        hh.i1 += list((k + lv.ahead) * lv.stride)
        hh.peak += list(k * lv.stride + (lv.stride if lv.test == "noise" else 0))
        hh.window += [lv.window] * idx.size
        hh.stat += list(lv.z[idx])
        hh.thr += [thr] * idx.size
        hh.size += list(lv.size[idx])
    return hits, peaks


def _merge(i0: np.ndarray, i1: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Merge overlapping spans; per merged span the indices of its members."""
    order = np.argsort(i0, kind="stable")
    out: list[tuple[int, int, list[int]]] = []
    for j in order:
        a, b = int(i0[j]), int(i1[j])
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b), out[-1][2] + [int(j)])
        else:
            out.append((a, b, [int(j)]))
    return [(a, b, np.asarray(m)) for a, b, m in out]


# --------------------------------------------------------------------------------------------------
# per-channel summaries: what the tests need of a channel, O(n / h0) values, built from the signal
# pushed in consecutive pieces (one piece: the whole array)
# --------------------------------------------------------------------------------------------------

#: the offset removed before averaging (exactness of the means, docs/METHODS.md §2.3) is the
#: median of this many first samples
_OFFSET_SAMPLES = 1 << 12
#: the quantum of a quantised signal is measured on this many first samples
_QUANTUM_SAMPLES = 1 << 16
#: temperature check: the recording in this many equal windows
_TEMP_WINDOWS = 64
#: interpolated temperature values generated at a time (bounded memory over a long gap)
_EMIT = 1 << 20


class _Blocks:
    """Means of the first ``n_blocks`` consecutive blocks of ``h`` values of a series pushed in
    pieces. Each block is reduced on its own (one row of a reshape), so the means have the bits of
    one reshape-mean of the whole series whatever the pieces."""

    def __init__(self, h: int, n_blocks: int) -> None:
        self.h, self.out, self.k = h, np.empty(max(n_blocks, 0)), 0
        self.rest = np.empty(0)

    def push(self, v: np.ndarray) -> None:
        if self.k >= self.out.size:
            return
        if self.rest.size:
            v = np.concatenate((self.rest, v))
        m = min(v.size // self.h, self.out.size - self.k)
        if m:
            self.out[self.k:self.k + m] = v[: m * self.h].reshape(m, self.h).mean(axis=1)
            self.k += m
        self.rest = v[m * self.h:].copy() if self.k < self.out.size else np.empty(0)


class _Timeline:
    """(time, mean, min, max) per bin of ``ceil(n / bins)`` samples (the last bin may be
    shorter) of a series pushed in pieces; the series itself when ``n <= bins``."""

    def __init__(self, n: int, bins: int) -> None:
        self.w = 0 if n <= bins else -(-n // bins)
        self.parts: list[tuple[np.ndarray, ...]] = []
        self.rest = (np.empty(0), np.empty(0))

    def push(self, x: np.ndarray, t: np.ndarray) -> None:
        if not self.w:
            self.parts.append((t.copy(), x.copy(), x.copy(), x.copy()))
            return
        if self.rest[0].size:
            x, t = np.concatenate((self.rest[0], x)), np.concatenate((self.rest[1], t))
        m = x.size // self.w * self.w
        if m:
            self.parts.append(self._bins(x[:m], t[:m]))
        self.rest = (x[m:].copy(), t[m:].copy())

    def _bins(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, ...]:
        edges = np.arange(0, x.size, self.w)
        cnt = np.diff(np.append(edges, x.size))
        return (np.add.reduceat(t, edges) / cnt, np.add.reduceat(x, edges) / cnt,
                np.minimum.reduceat(x, edges), np.maximum.reduceat(x, edges))

    def finish(self) -> tuple[np.ndarray, ...]:
        if self.w and self.rest[0].size:
            self.parts.append(self._bins(*self.rest))
            self.rest = (np.empty(0), np.empty(0))
        if not self.parts:
            return tuple(np.empty(0) for _ in range(4))
        if len(self.parts) == 1:
            return self.parts[0]
        return tuple(np.concatenate([p[i] for p in self.parts]) for i in range(4))


@dataclass(frozen=True)
class _Summary:
    """What the tests need of one channel of ``n`` samples: the ``offset`` (median of the first
    4096 samples), the ``quantum`` (smallest non-zero step in the first 65536, 0: continuous),
    the block ``means`` of the offset-free signal over h0 samples (the base half-window of the
    window-mean test; empty when untested), the block means ``noise`` of diff(x)^2 / 2 over
    w_noise / 2 samples, ``temp_means`` of the offset-free signal over n // 64 samples (the
    temperature check; empty without temperature) and the plotting ``timeline``."""

    n: int
    offset: float
    quantum: float
    means: np.ndarray
    noise: np.ndarray
    temp_means: np.ndarray
    timeline: tuple[np.ndarray, ...]


class _ChannelAcc:
    """Builds the :class:`_Summary` of one channel from its samples pushed in order."""

    def __init__(self, n: int, h0: int, h_noise: int, w_temp: int) -> None:
        self.n = n
        self.head: list[np.ndarray] = []  # the first samples, until the offset is known
        self.n_head = 0
        self.offset: float | None = None
        self.pos = 0  # offset-free samples processed
        self.prev: np.ndarray | None = None  # the last offset-free sample (for differences)
        self.qmin = math.inf
        self.means = _Blocks(h0, n // h0 if h0 else 0)
        self.noise = _Blocks(h_noise or 1, (n - 1) // h_noise if h_noise else 0)
        self.temp = _Blocks(w_temp or 1, n // w_temp if w_temp else 0)
        self.timeline = _Timeline(n, _TIMELINE_BINS)

    def push(self, x: np.ndarray, t: np.ndarray) -> None:
        self.timeline.push(x, t)
        if self.offset is None:
            self.head.append(x)
            self.n_head += x.size
            if self.n_head < min(_OFFSET_SAMPLES, self.n):
                return
            x = np.concatenate(self.head) if len(self.head) > 1 else self.head[0]
            self.head = []
            self.offset = np.median(x[:_OFFSET_SAMPLES])
        self._centred(x - self.offset)

    def _centred(self, xo: np.ndarray) -> None:
        if xo.size == 0:
            return
        prev = () if self.prev is None else (self.prev,)
        if self.pos < _QUANTUM_SAMPLES:
            seg = xo[: _QUANTUM_SAMPLES - self.pos]
            d = np.abs(np.diff(np.concatenate((prev, seg)) if prev else seg))
            d = d[d > 0]
            if d.size:
                self.qmin = min(self.qmin, float(d.min()))
        self.means.push(xo)
        if self.noise.out.size:
            self.noise.push(np.diff(np.concatenate((prev, xo)) if prev else xo) ** 2 * 0.5)
        self.temp.push(xo)
        self.prev = xo[-1]
        self.pos += xo.size

    def finish(self) -> _Summary:
        if self.offset is None:  # fewer samples than the offset needs were announced
            x = np.concatenate(self.head) if self.head else np.empty(0)
            self.head = []
            self.offset = np.median(x[:_OFFSET_SAMPLES]) if x.size else 0.0
            self._centred(x - self.offset)
        if self.pos != self.n:
            raise InputError(f"{self.pos} samples pushed, {self.n} announced")
        return _Summary(self.n, float(self.offset), 0.0 if self.qmin == math.inf else self.qmin,
                        self.means.out, self.noise.out, self.temp.out, self.timeline.finish())


class _TemperatureAcc:
    """Temperature pushed in order: the count, minimum and maximum of its finite values, the block
    means over ``w`` samples of the series with its non-finite values interpolated linearly
    between their finite neighbours (held constant beyond the first and last finite ones; a
    pending gap costs two numbers, not its length) and its timeline (non-finite -> NaN)."""

    def __init__(self, n: int, w: int) -> None:
        self.count, self.lo, self.hi = 0, math.inf, -math.inf
        self.blocks = _Blocks(w or 1, n // w if w else 0)
        self.timeline = _Timeline(n, _TIMELINE_BINS)
        self.pos = 0
        self.gap = 0  # non-finite values pending before self.pos
        self.last: tuple[int, float] | None = None  # the last finite (index, value)

    def push(self, v: np.ndarray, t: np.ndarray) -> None:
        ok = np.isfinite(v)
        self.timeline.push(np.where(ok, v, np.nan), t)
        s = self.pos
        self.pos += v.size
        fi = np.flatnonzero(ok)
        if not fi.size:
            self.gap += v.size
            return
        fin = v[fi]
        self.count += fi.size
        self.lo, self.hi = min(self.lo, float(fin.min())), max(self.hi, float(fin.max()))
        self._fill(s + int(fi[0]), self.gap + int(fi[0]), v[fi[0]])
        seg = v[fi[0]: fi[-1] + 1]
        if fi.size < seg.size:  # gaps inside this piece
            seg = np.where(ok[fi[0]: fi[-1] + 1], seg,
                           np.interp(np.arange(s + fi[0], s + fi[-1] + 1), s + fi, fin))
        self.blocks.push(seg)
        self.last = (s + int(fi[-1]), v[fi[-1]])
        self.gap = v.size - 1 - int(fi[-1])

    def _fill(self, a: int, k: int, va: Any) -> None:
        """The ``k`` non-finite values before sample ``a`` (finite value ``va``), interpolated
        from the last finite value (constant ``va`` when there is none)."""
        for b in range(a - k, a, _EMIT):
            e = min(a, b + _EMIT)
            if self.last is None:
                self.blocks.push(np.full(e - b, va, dtype=np.float64))
            else:
                self.blocks.push(np.interp(np.arange(b, e), [self.last[0], a],
                                           [self.last[1], va]))

    def finish(self) -> None:
        if self.gap and self.last is not None:  # constant beyond the last finite value
            for b in range(0, self.gap, _EMIT):
                self.blocks.push(np.full(min(self.gap - b, _EMIT), self.last[1],
                                         dtype=np.float64))
            self.gap = 0


class _Uniform:
    """The times ``i / freq`` of ``n`` samples (seconds; samples without a rate), indexed like
    the array they stand for."""

    def __init__(self, n: int, freq: float | None) -> None:
        self.size, self.f = n, freq or 1.0

    def __getitem__(self, i: int) -> float:
        return (i + self.size if i < 0 else i) / self.f


def _temperature_check(axes: Mapping[str, np.ndarray], temp: _TemperatureAcc, n: int,
                       window_s: float, alpha: float, source: str) -> TemperatureCheck | None:
    """Differenced window means of each axis (``axes``: their block means over n // 64
    samples) against those of the temperature: Pearson r with a t-test whose degrees of freedom
    are reduced by Bartlett's factor (both series are autocorrelated), Bonferroni over the
    channels; 'follows' also needs |r| >= 0.5."""
    from scipy.stats import t as student

    if temp.count < 0.5 * n:
        return None
    if n // _TEMP_WINDOWS < 4:
        return None
    rng = (temp.lo, temp.hi)
    Tm = np.diff(temp.blocks.out)
    res: dict[str, tuple[float, float, float, bool]] = {}
    level = alpha / max(len(axes), 1)
    for c, means in axes.items():
        b = np.diff(means)
        if np.std(Tm) == 0 or np.std(b) == 0:
            res[c] = (0.0, 0.0, 1.0, False)
            continue
        r = float(np.corrcoef(b, Tm)[0, 1])
        f = 1.0
        bc, tc = b - b.mean(), Tm - Tm.mean()
        for lag in range(1, 4):  # Bartlett: var(r) ~ (1 + 2 sum rho_b rho_T) / K
            rb = float(np.dot(bc[:-lag], bc[lag:]) / np.dot(bc, bc))
            rt = float(np.dot(tc[:-lag], tc[lag:]) / np.dot(tc, tc))
            f += 2.0 * rb * rt
        dof = max((b.size - 2) / max(f, 1.0), 1.0)
        tstat = r * math.sqrt(dof / max(1e-12, 1.0 - r * r))
        p = float(2.0 * student.sf(abs(tstat), dof))
        slope = float(np.dot(bc, tc) / np.dot(tc, tc))
        res[c] = (r, slope, p, bool(p < level and abs(r) >= 0.5))
    return TemperatureCheck(rng, window_s, res, source)


# --------------------------------------------------------------------------------------------------
# entry points
# --------------------------------------------------------------------------------------------------


class StationarityStream:
    """The stationarity check (``docs/METHODS.md`` §16) of a recording read in consecutive pieces,
    in bounded memory: :meth:`push` its rows in order, then :meth:`finish`.

    ``names`` the channels of the rows, ``n`` their total number; ``freq``, ``units``, ``alpha``,
    ``norm`` as in :func:`check_stationarity`; ``temperature`` the name of a column of the rows
    holding the temperature in deg C (NaN where unknown; not tested as a channel), with
    ``temperature_source`` naming it in messages; ``where`` names the recording in messages.
    Times are ``i / freq``.

    Each channel is reduced to its summary as it goes: the block means of the offset-free signal
    over the base half-window h0 = max(8 samples, 0.1 s) / 2, of diff(x)^2 / 2 over half the
    noise window, of the signal over n / 64 samples when there is a temperature, a 1500-bin
    timeline, the offset and the quantum from the first samples: O(n / h0) values per channel
    (8 / h0 bytes per sample), plus one piece. The report is that of :func:`check_stationarity`
    on the whole recording, bit for bit, except the median |a| of the accelerometer-norm alert,
    which is taken from the window means instead of the samples."""

    def __init__(self, names: Sequence[str], n: int, *, freq: float | None = None,
                 units: Mapping[str, str | None] | None = None, alpha: float = ALPHA,
                 norm: bool = True, temperature: str | bool | None = None,
                 temperature_source: str = "", time_s: np.ndarray | None = None,
                 where: str = "signal") -> None:
        names = [str(c) for c in names]
        self.temp_col = None
        if isinstance(temperature, str):
            if temperature not in names:
                raise InputError(f"temperature column '{temperature}' not among the channels "
                                 f"({', '.join(names)})")
            self.temp_col = names.index(temperature)
            names = [c for c in names if c != temperature]
        if not names:
            raise InputError("the stationarity check needs at least one channel")
        if not 0 < alpha < 1:
            raise InputError(f"alpha must lie in (0, 1), got {alpha}")
        self.n, self.freq, self.alpha, self.where = int(n), freq, alpha, where
        self.n_src = len(names) + (self.temp_col is not None)
        self.time_s = time_s
        self.temperature_source = temperature_source
        units = dict(units or {})
        notes: list[str] = []
        sensors = {c: _si_factor(units.get(c)) for c in names}  # unknown/missing unit: no ceiling
        chans = list(names)
        acc = [c for c in names if sensors[c][0] == "accelerometer"]
        self.norm_idx: list[int] | None = None
        if norm and len(acc) == 3 and len({units.get(c) for c in acc}) == 1:
            self.norm_idx = [names.index(c) for c in acc]
            chans.append(NORM)
            units[NORM] = units.get(acc[0])
            sensors[NORM] = sensors[acc[0]]
        self.norm_g: float | None = None  # median |a| of the samples (set for a whole push)
        self.names, self.chans, self.units, self.sensors = names, chans, units, sensors
        no_ceiling = [c for c in chans if sensors[c][0] is None]
        if freq is None:
            notes.append("no sampling rate: windows in samples and no static ceiling")
        elif no_ceiling and len(no_ceiling) == len(chans):
            notes.append("no gyroscope/accelerometer unit: only relative tests (a recording that "
                         "moves throughout can pass; give --units)")
        n = self.n
        self.hs = _ladder(n, freq)
        w_noise = max(32, 2 * math.ceil(NOISE_WINDOW_S * freq / 2)) if freq else 32
        self.w_noise = w_noise + w_noise % 2
        if not self.hs:
            notes.append(f"too short for a stationarity check ({n} samples; at least "
                         f"{(MIN_DIFFS + 3) * ((MIN_WINDOW_SAMPLES + 1) // 2)} needed)")
        self.notes = notes
        half = self.w_noise // 2
        self.noise_tests = (n // half - 1) if n // half - 1 >= MIN_DIFFS else 0
        w_temp = n // _TEMP_WINDOWS if temperature is not None and temperature is not False else 0
        h0 = self.hs[0] if self.hs else 0
        self.accs = [_ChannelAcc(n, h0, half if self.noise_tests else 0,
                                 w_temp if c != NORM else 0) for c in chans]
        self.temp = None if temperature is None or temperature is False else \
            _TemperatureAcc(n, w_temp)
        self.pos = 0

    @classmethod
    def for_source(cls, source: Any, **kwargs: Any) -> StationarityStream:
        """The check of a :class:`gmwm.stream.Source` (its names, length, rate unless ``freq``
        is given, and its name in messages); ``kwargs`` as the constructor."""
        kwargs.setdefault("freq", source.freq)
        kwargs.setdefault("where", source.where)
        return cls(source.names, source.n_samples, **kwargs)

    def push(self, rows: Any) -> None:
        """The next rows, shape ``(m, C)`` (1-D for one column), any numeric dtype, in order. A
        NaN or inf in a tested channel is an :class:`InputError` naming the channel and
        sample."""
        rows = np.asarray(rows)
        if rows.ndim == 1 and self.n_src == 1:
            rows = rows[:, None]
        if rows.ndim != 2 or rows.shape[1] != self.n_src:
            raise InputError(f"{self.where}: rows must be (m, {self.n_src}) arrays, got shape "
                             f"{rows.shape}")
        if self.pos + rows.shape[0] > self.n:
            raise InputError(f"{self.where}: more than the {self.n} samples announced")
        cols, temp = [], None
        for k in range(self.n_src):
            col = np.ascontiguousarray(rows[:, k], dtype=np.float64)
            if k == self.temp_col:
                temp = col
                continue
            bad = ~np.isfinite(col)
            if bad.any():
                i = int(np.argmax(bad))
                what = "NaN" if np.isnan(col[i]) else "infinite"
                name = self.names[len(cols)]
                raise InputError(f"channel '{name}' of {self.where} contains a {what} value at "
                                 f"sample {self.pos + i}; clean or interpolate it first")
            cols.append(col)
        self._push(cols, None, temp)

    def _push(self, cols: list[np.ndarray], t: np.ndarray | None,
              temp: np.ndarray | None) -> None:
        """Float64 columns in the order of ``names`` (and the temperature), times ``t`` (s since
        the first sample; None: ``i / freq``)."""
        m = cols[0].size
        if t is None:
            t = np.arange(self.pos, self.pos + m) / (self.freq or 1.0)
        if self.norm_idx is not None:
            a = np.sqrt(sum(cols[i] ** 2 for i in self.norm_idx))
            if self.pos == 0 and m == self.n:  # the whole recording: the median of its samples
                self.norm_g = float(np.median(a))
            cols = [*cols, a]
        for acc, x in zip(self.accs, cols, strict=True):
            acc.push(x, t)
        if self.temp is not None and temp is not None:
            self.temp.push(temp, t)
        self.pos += m

    def finish(self) -> StationarityReport:
        """The report of the recording pushed (all ``n`` samples)."""
        if self.pos != self.n:
            raise InputError(f"{self.where}: {self.pos} samples pushed, {self.n} announced")
        n, freq, alpha, hs = self.n, self.freq, self.alpha, self.hs
        sums = {c: acc.finish() for c, acc in zip(self.chans, self.accs, strict=True)}
        self.accs = []
        t: Any = self.time_s if self.time_s is not None else _Uniform(n, freq)
        notes, alerts = list(self.notes), []
        if self.norm_idx is not None:
            g = self.norm_g
            if g is None:  # pieces: the median of the window means (the samples when few)
                sm = sums[NORM]
                g = float(np.median(sm.means + sm.offset if sm.means.size else sm.timeline[1]))
            g *= self.sensors[NORM][1]
            if not 8.8 <= g <= 10.8:
                alerts.append(f"the median accelerometer norm is {g:.4g} m/s^2, not 1 g (9.81 "
                              "m/s^2) as at rest: wrong unit, or a platform that accelerates "
                              "throughout?")
        per_channel = sum(n // h - 3 for h in hs)
        n_tests = len(self.chans) * (per_channel + self.noise_tests)
        z0 = _z_quantile(alpha / (2.0 * n_tests)) if n_tests else float("inf")
        flags: list[Flag] = []
        peaks: list[tuple] = []
        if hs:
            for c, sm in sums.items():
                sensor, si = self.sensors[c]
                hits, pk = _channel_hits(sm, hs, self.w_noise if self.noise_tests else 0, z0,
                                         freq, sensor, si)
                peaks += [(c, *p) for p in pk]
                for test, hh in hits.items():
                    if not hh.i0:
                        continue
                    i0 = np.minimum(np.asarray(hh.i0), n)
                    i1 = np.minimum(np.asarray(hh.i1), n)
                    for a, b, members in _merge(i0, i1):
                        ratio = np.asarray(hh.stat)[members] / np.asarray(hh.thr)[members]
                        j = int(members[int(np.argmax(ratio))])
                        size = float(np.max(np.asarray(hh.size)[members]))
                        flags.append(Flag(c, test, a, b, float(t[a]), _end_time(t, b, freq),
                                          float(t[min(hh.peak[j], n - 1)]),
                                          hh.window[j] / (freq or 1.0), float(hh.stat[j]),
                                          float(hh.thr[j]), size))
        flags.sort(key=lambda f: (f.i0, f.channel, f.test))
        segments = _segments(flags, t, freq, self.chans)
        temp_check = None
        temp_line = None
        tp = self.temp
        if tp is not None:
            tp.finish()
            if tp.count == 0 or tp.lo == tp.hi:
                notes.append("temperature constant or absent: not compared with the bias")
            else:
                w = n // _TEMP_WINDOWS
                window_s = float(t[w] - t[0]) if n > w else float(w)
                axes = {c: sums[c].temp_means for c in self.names}
                temp_check = _temperature_check(axes, tp, n, window_s, alpha,
                                                self.temperature_source)
                temp_line = tp.timeline.finish()[:2]
        timeline = {c: sm.timeline for c, sm in sums.items()}
        return StationarityReport(
            channels=tuple(self.chans), units={c: self.units.get(c) for c in self.chans}, n=n,
            freq=freq, duration_s=float(t[-1]) if n else 0.0, windows=tuple(2 * h for h in hs),
            alpha=alpha, n_tests=n_tests, threshold=z0, flags=tuple(flags), segments=segments,
            peaks=tuple(peaks), temperature=temp_check, notes=tuple(notes), alerts=tuple(alerts),
            timeline=timeline, temperature_timeline=temp_line, time_s=self.time_s)


def check_stationarity(data: Any, *, freq: float | None = None, time_s: Any = None,
                       units: Mapping[str, str | None] | None = None,
                       temperature: Any = None, temperature_source: str = "",
                       alpha: float = ALPHA, norm: bool = True) -> StationarityReport:
    """Check a recording for motion, steps, drifts and noise bursts (``docs/METHODS.md`` §16).

    ``data``: a :class:`gmwm.readers.recording.Recording` (rate, stamps, units and temperature
    are taken from it) or a mapping name -> 1-D signal. ``freq`` Hz (None: windows
    in samples, no static ceiling); ``time_s`` seconds of each sample (default ``i / freq``);
    ``units`` signal units (a known gyroscope/accelerometer unit marks the sensor type and
    enables the static ceiling); ``temperature`` deg C per
    sample (NaN where unknown); ``alpha`` the family-wise false-alarm level of one recording;
    ``norm``: also test |a| when three accelerometer axes share a unit. Recordings too large
    for memory: :func:`check_stationarity_stream`."""
    if hasattr(data, "channels") and hasattr(data, "time"):
        rec = data
        chans = dict(rec.channels)
        freq = rec.freq if freq is None else freq
        units = dict(rec.units) if units is None else dict(units)
        if time_s is None:
            time_s = getattr(rec, "time_s", None)
        if temperature is None and getattr(rec, "temperature", None) is not None:
            temperature = rec.temperature
            temperature_source = getattr(rec, "temperature_source", "") or temperature_source
    else:
        chans = {str(k): np.asarray(v, dtype=np.float64) for k, v in dict(data).items()}
        units = dict(units or {})
    if not chans:
        raise InputError("the stationarity check needs at least one channel")
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha}")
    sizes = {np.asarray(v).size for v in chans.values()}
    if len(sizes) != 1:
        raise InputError(f"the channels have different lengths ({sorted(sizes)})")
    n = sizes.pop()
    t = (np.arange(n) / (freq or 1.0)) if time_s is None else \
        np.asarray(time_s, dtype=np.float64) - float(np.asarray(time_s)[0])
    if t.size != n:
        raise InputError(f"{t.size} time stamps for {n} samples")
    temp = None
    if temperature is not None:
        temp = np.asarray(temperature, dtype=np.float64)
        if temp.size != n:
            raise InputError(f"{temp.size} temperature values for {n} samples")
    check = StationarityStream(list(chans), n, freq=freq, units=units, alpha=alpha, norm=norm,
                               temperature=temp is not None,
                               temperature_source=temperature_source, time_s=t)
    if n:  # one piece: the whole recording
        check._push([np.asarray(chans[c], dtype=np.float64) for c in check.names], t, temp)
    return check.finish()


def check_stationarity_stream(source: Any, *, freq: float | None = None,
                              units: Mapping[str, str | None] | None = None,
                              alpha: float = ALPHA, norm: bool = True,
                              temperature: str | None = None, temperature_source: str = "",
                              memory: int | None = None, chunk: int | None = None
                              ) -> StationarityReport:
    """:func:`check_stationarity` of a :class:`gmwm.stream.Source` (a file larger than memory)
    read once in chunks: the same report (see :class:`StationarityStream`). ``freq`` defaults
    to the source's rate (None: windows in samples); ``temperature`` names a column of deg C;
    ``chunk`` rows per read (default: from ``memory``, bytes, default
    :data:`gmwm.stream.DEFAULT_MEMORY`). To check while the WV is computed, in the same read:
    ``check = StationarityStream.for_source(src, units=...)``,
    ``wvar_stream(src, observe=check.push)``, ``check.finish()``."""
    from gmwm.stream import DEFAULT_MEMORY, iter_rows

    check = StationarityStream.for_source(
        source, **({} if freq is None else {"freq": freq}), units=units, alpha=alpha, norm=norm,
        temperature=temperature, temperature_source=temperature_source)
    if chunk is None:
        C = len(source.names)
        per_row = 2 * C * max(int(getattr(source, "itemsize", 8)), 1) + 32 * (C + 1)
        chunk = max(_OFFSET_SAMPLES, int(memory or DEFAULT_MEMORY) // per_row)
    for _, rows in iter_rows(source, int(chunk)):
        check.push(rows)
    return check.finish()


def _end_time(t: Any, i1: int, freq: float | None) -> float:
    return float(t[i1]) if i1 < t.size else float(t[-1]) + 1.0 / (freq or 1.0)


def _segments(flags: Sequence[Flag], t: Any, freq: float | None, order: Sequence[str]
              ) -> tuple[Segment, ...]:
    if not flags:
        return ()
    i0 = np.array([f.i0 for f in flags])
    i1 = np.array([f.i1 for f in flags])
    out = []
    for a, b, members in _merge(i0, i1):
        fl = [flags[int(j)] for j in members]
        chans = tuple(c for c in order if any(f.channel == c for f in fl))
        tests = tuple(sorted({f.test for f in fl}))
        sev = max(f.stat / f.threshold for f in fl)
        out.append(Segment(a, b, float(t[a]), _end_time(t, b, freq), chans, tests, float(sev)))
    return tuple(out)
