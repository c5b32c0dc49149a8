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
    #: the flagged ranges inside the part used are left out of the estimate (the calibration's
    #: motion policy, gmwm.calibrate); what every surface then says about them
    excluded: bool = False

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
        warning and the alerts; what the estimate uses is said whenever something is flagged
        (and, :attr:`excluded`, that the flagged ranges inside it are left out)."""
        out: list[str] = []
        if self.segments:
            a, b = self.used or (0, self.n)
            inside = self.segments_in(a, b)
            top = sorted(sorted(self.segments, key=lambda s: -s.severity)[:limit],
                         key=lambda s: s.i0)
            share = sum(s.i1 - s.i0 for s in self.segments) / max(self.n, 1)
            head = (f"the recording is not static: {len(self.segments)} flagged range(s), "
                    f"{100 * share:.3g} % of the samples")
            if inside and self.excluded:
                head += "; they are excluded from the estimate"
            elif inside:
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


def _threshold(z0: float, k: int) -> float:
    """Bonferroni quantile z0, inflated for the uncertainty of a robust scale from k values."""
    return z0 * (1.0 + SMALL_SAMPLE / math.sqrt(k))


@dataclass(frozen=True)
class _Scale:
    """One test of one channel at one window length, standardised: the statistic of a value v is
    |v - med| / scale ('mean', 'ceiling': window-mean differences) or (v - med) / scale ('noise':
    log noise levels, upper side only), flagged beyond ``thr``; ``count`` values. Value j sits at
    the boundary k = j + ``offset`` of a grid of ``stride`` samples: its span is ``(k - back)`` to
    ``(k + ahead)`` strides, its peak ``k * stride + shift``; ``order`` ranks the window lengths
    (ties between equal statistics go to the earlier span, then the shorter window)."""

    test: str
    order: int
    window: int
    stride: int
    back: int
    ahead: int
    offset: int
    shift: int
    med: float
    scale: float
    thr: float
    count: int

    def z(self, v: np.ndarray) -> np.ndarray:
        if self.test == "noise":
            return (v - self.med) / self.scale
        return np.abs(v - self.med) / max(self.scale, np.finfo(float).tiny)

    def size(self, v: np.ndarray) -> np.ndarray:
        """The change reported for values ``v`` (signal units; 'noise': a variance ratio)."""
        return np.exp(v - self.med) if self.test == "noise" else np.abs(v - self.med)

    def region(self, j0: int, j1: int, n: int) -> tuple[int, int]:
        """The samples [a, b) the values ``j0:j1`` are computed from."""
        if self.test == "noise":  # u_j: differences j*s .. (j+2)*s - 1
            return j0 * self.stride, min(n, (j1 + 1) * self.stride + 1)
        return j0 * self.stride, min(n, (j1 + 3) * self.stride)  # d_j: blocks j .. j+3


@dataclass(frozen=True)
class _Span:
    """Flagged statistics of one ``test``, channel and window length that touch one another: samples
    ``a:b``; the largest ``ratio`` statistic / threshold (the first such by ``i0``) and its
    ``i0``, window ``order``, ``peak`` sample, ``window``, ``stat`` and ``thr``; the largest
    ``size``."""

    test: str
    a: int
    b: int
    ratio: float
    i0: int
    order: int
    peak: int
    window: int
    stat: float
    thr: float
    size: float


def _spans(sc: _Scale, j0: int, v: np.ndarray) -> list[_Span]:
    """The flagged spans of the values ``v`` (indices ``j0...``) of one test: consecutive flagged
    statistics whose spans touch are one :class:`_Span`."""
    z = sc.z(v)
    idx = np.flatnonzero(z > sc.thr)
    if not idx.size:
        return []
    k = idx + (j0 + sc.offset)
    i0 = (k - sc.back) * sc.stride
    i1 = (k + sc.ahead) * sc.stride
    zs = z[idx]
    ratio = zs / sc.thr
    size = sc.size(v[idx])
    cut = np.flatnonzero(i0[1:] > i1[:-1]) + 1
    out = []
    for a, b in zip(np.r_[0, cut], np.r_[cut, idx.size], strict=True):
        m = int(a + np.argmax(ratio[a:b]))
        out.append(_Span(sc.test, int(i0[a]), int(i1[b - 1]), float(ratio[m]), int(i0[m]), sc.order,
                         int(k[m] * sc.stride + sc.shift), sc.window, float(zs[m]), sc.thr,
                         float(np.max(size[a:b]))))
    return out


def _merge(spans: list[_Span]) -> list[tuple[int, int, _Span, float]]:
    """Spans of one test and channel (any window lengths) merged where they overlap or touch:
    (a, b, the member with the largest ratio, ties to the smallest i0 then order, largest
    size)."""
    out: list[list[Any]] = []
    for s in sorted(spans, key=lambda s: (s.a, s.order)):
        if out and s.a <= out[-1][1]:
            g = out[-1]
            g[1] = max(g[1], s.b)
            if (s.ratio, -s.i0, -s.order) > (g[2].ratio, -g[2].i0, -g[2].order):
                g[2] = s
            g[3] = max(g[3], s.size)
        else:
            out.append([s.a, s.b, s, s.size])
    return [(a, b, s, size) for a, b, s, size in out]


def _union(i0: np.ndarray, i1: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
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


def _scales(sm: _Summary, hs: Sequence[int], w_noise: int, z0: float, freq: float | None,
            sensor: str | None, si: float) -> list[tuple[int, _Scale, _Series]]:
    """The tests of one channel, standardised from its summary, with their statistics:
    window-mean differences per window length ('mean', or 'ceiling' where the static ceiling
    caps the robust scale) and the windowed white-noise level ('noise', upper side only; absent
    when its scale is 0)."""
    q = sm.quantum
    out = []
    for i, (h, series) in enumerate(zip(hs, sm.levels, strict=True)):
        L = 2 * h
        med, s = _robust(series.vals)
        s = max(s, q / math.sqrt(6.0 * L))  # rounding noise of a quantised signal
        test = "mean"
        if sensor is not None and freq is not None:
            cap = ceiling_sd(sensor, L / freq) / si
            if cap < s:
                s, test = cap, "ceiling"
        out.append((i, _Scale(test, i, L, h, 2, 2, 2, 0, med, s, _threshold(z0, series.count),
                              series.count), series))
    nz = sm.noise
    if nz is not None and w_noise and sm.n // (w_noise // 2) - 1 >= MIN_DIFFS:
        med, s = _robust(nz.vals)
        if s > 0:
            h = w_noise // 2
            out.append((len(hs), _Scale("noise", len(hs), w_noise, h, 0, 2, 0, h, med, s,
                                        _threshold(z0, nz.count), nz.count), nz))
    return out


# --------------------------------------------------------------------------------------------------
# per-channel summaries: the statistics of every test of a channel, computed from the signal pushed
# in consecutive pieces (one piece: the whole array), kept whole or, with a source to re-read,
# bounded (a subsample and block extremes)
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
#: bounded summaries (a recording read from a source): a test with more statistics than this takes
#: its median and robust scale from a systematic subsample of at most this many (every r-th)
ROBUST_SAMPLE = 1 << 16
#: bounded summaries: the largest and smallest statistic of at most this many blocks of
#: consecutive ones per test (where to look for flagged ones when the source is re-read)
_EXTREME_BLOCKS = 2048
#: rows processed at a time (bounds the temporaries of a large push)
_PIECE = 1 << 18
_NONE = np.empty(0)


def _block_means(v: np.ndarray, h: int) -> np.ndarray:
    """Means of the consecutive blocks of ``h`` values of ``v`` (``v.size`` a multiple of h), with
    the bits of ``v.reshape(-1, h).mean(axis=1)``: below 8 values NumPy adds a row from left to
    right, which strided additions do faster (tests/test_stationarity_stream.py checks it)."""
    if h >= 8:
        return v.reshape(-1, h).mean(axis=1)
    out = v[0::h] + v[1::h] if h > 1 else v.copy()
    for i in range(2, h):
        out += v[i::h]
    out /= h
    return out


class _Blocks:
    """Means of consecutive blocks of ``h`` values of a series pushed in order: block b holds
    values ``[b h, (b + 1) h)``; the series starts at block ``first`` and stops after block
    ``stop - 1``. :meth:`push` returns the blocks it completes (``keep``: also collected in
    :attr:`out`). Each block is reduced on its own (one row of a reshape), so the means have the
    bits of one reshape-mean of the whole series whatever the pieces."""

    def __init__(self, h: int, stop: int, first: int = 0, keep: bool = False) -> None:
        self.h, self.next, self.stop = h, first, max(stop, first)
        self.rest = _NONE
        self.kept: list[np.ndarray] | None = [] if keep else None

    def push(self, v: np.ndarray) -> np.ndarray:
        if self.next >= self.stop:
            return _NONE
        if self.rest.size:
            v = np.concatenate((self.rest, v))
        m = min(v.size // self.h, self.stop - self.next)
        out = _block_means(v[: m * self.h], self.h) if m else _NONE
        self.next += m
        self.rest = v[m * self.h:].copy() if self.next < self.stop else _NONE
        if self.kept is not None and m:
            self.kept.append(out)
        return out

    @property
    def out(self) -> np.ndarray:
        return np.concatenate(self.kept) if self.kept else _NONE


def _half_sq_diff(x: np.ndarray, prev: Any) -> np.ndarray:
    """diff(x)^2 / 2 of a piece, preceded by the difference to the previous sample ``prev`` (None:
    the first piece), with the bits of ``np.diff(...) ** 2 * 0.5``."""
    if prev is None:
        d = np.diff(x)
    else:
        d = np.empty(x.size)
        d[0] = x[0] - prev
        np.subtract(x[1:], x[:-1], out=d[1:])
    np.square(d, out=d)
    d *= 0.5
    return d


class _Cascade:
    """The window-mean differences of every window length from the block means B_0 over h0 samples
    pushed in order from block ``first``: B_i[m] = (B_{i-1}[2m] + B_{i-1}[2m+1]) / 2 (blocks of
    h0 2^i samples) and d_j = (B_i[j+2] + B_i[j+3] - B_i[j] - B_i[j+1]) / 2 for every j whose four
    blocks were pushed (in the order and with the bits of the whole-array expressions)."""

    def __init__(self, n_levels: int, first: int) -> None:
        self.n_levels = n_levels
        self.next = first  # index of the next B_0 value
        self.tail: list[np.ndarray] = [_NONE] * n_levels  # the last <= 3 values of B_i
        self.odd: list[np.ndarray] = [_NONE] * n_levels  # a B_i value waiting for its pair

    def push(self, v: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
        """The new differences of B_0 values ``v``: (level, index of the first, values)."""
        out = []
        g = self.next  # index of v[0] among the B_i
        self.next += v.size
        for i in range(self.n_levels):
            if not v.size:
                break
            tail = self.tail[i]
            nt, total = tail.size, tail.size + v.size
            if total >= 4:
                d = np.empty(total - 3)
                k = 0
                if nt:  # the differences that reach into the tail
                    c = np.concatenate((tail, v[:3]))
                    k = c.size - 3
                    d[:k] = 0.5 * (c[2:-1] + c[3:] - c[:-3] - c[1:-2])
                if v.size >= 4:  # the rest, in place (the same operations in the same order)
                    dd = d[k:]
                    np.add(v[2:-1], v[3:], out=dd)
                    np.subtract(dd, v[:-3], out=dd)
                    np.subtract(dd, v[1:-2], out=dd)
                    np.multiply(dd, 0.5, out=dd)
                out.append((i, g - nt, d))
            self.tail[i] = v[-3:].copy() if v.size >= 3 else np.concatenate((tail, v))[-3:]
            if i + 1 == self.n_levels:
                break
            odd = self.odd[i]
            if odd.size:  # odd[0] (an even index) pairs with v[0]
                pre, s, g = 0.5 * (odd[0] + v[0]), 1, (g - 1) // 2
            else:  # an odd first index: its pair lies before the first block pushed
                pre, s, g = None, g % 2, (g + g % 2) // 2
            rest = v[s:]
            m = rest.size // 2
            nv = np.empty(m + (pre is not None))
            body = nv[1:] if pre is not None else nv
            if pre is not None:
                nv[0] = pre
            np.add(rest[: 2 * m: 2], rest[1: 2 * m: 2], out=body)
            np.multiply(body, 0.5, out=body)
            self.odd[i] = rest[2 * m:].copy()
            v = nv
        return out


class _Series:
    """The ``count`` values (statistics) of one test of one channel pushed in order. Kept whole
    when ``keep`` is None or not below ``count``; else every r-th (r = ceil(count / keep), for the
    median and robust scale) and the largest and smallest of blocks of ``g`` (a power of two)
    consecutive values, at most min(:data:`_EXTREME_BLOCKS`, ``keep``) blocks (which ones can
    hold a flagged statistic)."""

    def __init__(self, count: int, keep: int | None) -> None:
        self.count = max(count, 0)
        self.r = 1 if keep is None or self.count <= keep else -(-self.count // keep)
        self.vals = np.empty(-(-self.count // self.r))
        self.g = 1
        while -(-self.count // self.g) > min(_EXTREME_BLOCKS, keep or 1):
            self.g *= 2
        nb = -(-self.count // self.g) if self.r > 1 else 0
        self.hi, self.lo = np.full(nb, -np.inf), np.full(nb, np.inf)
        self.pushed = 0

    @property
    def whole(self) -> bool:
        return self.r == 1

    def push(self, j0: int, v: np.ndarray) -> None:
        if j0 != self.pushed or j0 + v.size > self.count:
            raise RuntimeError(f"values {j0}:{j0 + v.size} pushed after {self.pushed} of "
                               f"{self.count}")  # a bug, not an input error
        self.pushed += v.size
        if self.r == 1:
            self.vals[j0: j0 + v.size] = v
            return
        s = (-j0) % self.r
        sub = v[s:: self.r]
        p = (j0 + s) // self.r
        self.vals[p: p + sub.size] = sub
        g = self.g
        starts = np.arange(-(j0 % g), v.size, g)
        starts[0] = 0
        b = j0 // g
        sl = slice(b, b + starts.size)
        np.maximum(self.hi[sl], np.maximum.reduceat(v, starts), out=self.hi[sl])
        np.minimum(self.lo[sl], np.minimum.reduceat(v, starts), out=self.lo[sl])

    def blocks(self, sc: _Scale) -> tuple[float, list[tuple[int, int]]]:
        """The largest statistic and the value ranges (j0, j1) of the blocks that can hold one
        beyond the threshold (none when kept whole: they are read from the values)."""
        if self.whole:
            return float(np.max(sc.z(self.vals))), []
        z = sc.z(self.hi) if sc.test == "noise" else np.maximum(sc.z(self.hi), sc.z(self.lo))
        hit = np.flatnonzero(z > sc.thr)
        return float(np.max(z)), [(int(b) * self.g, min(self.count, (int(b) + 1) * self.g))
                                  for b in hit]


class _Timeline:
    """(time, mean, min, max) per bin of ``ceil(n / bins)`` samples (the last bin may be
    shorter) of a series pushed in pieces; the series itself when ``n <= bins``."""

    def __init__(self, n: int, bins: int) -> None:
        self.w = 0 if n <= bins else -(-n // bins)
        self.parts: list[tuple[np.ndarray, ...]] = []
        self.out = tuple(np.empty(-(-n // self.w) if self.w else 0) for _ in range(4))
        self.k = 0  # bins done
        self.rest = (_NONE, _NONE)

    def push(self, x: np.ndarray, t: np.ndarray) -> None:
        if not self.w:
            self.parts.append((t.copy(), x.copy(), x.copy(), x.copy()))
            return
        if self.rest[0].size:  # complete the open bin (without copying the whole piece)
            k = min(x.size, self.w - self.rest[0].size)
            rx, rt = np.concatenate((self.rest[0], x[:k])), np.concatenate((self.rest[1], t[:k]))
            x, t = x[k:], t[k:]
            if rx.size < self.w:
                self.rest = (rx, rt)
                return
            self._bins(rx, rt)
        m = x.size // self.w * self.w
        if m:
            self._bins(x[:m], t[:m])
        self.rest = (x[m:].copy(), t[m:].copy())

    def _bins(self, x: np.ndarray, t: np.ndarray) -> None:
        edges = np.arange(0, x.size, self.w)
        cnt = np.diff(np.append(edges, x.size))
        sl = slice(self.k, self.k + edges.size)
        np.divide(np.add.reduceat(t, edges), cnt, out=self.out[0][sl])
        np.divide(np.add.reduceat(x, edges), cnt, out=self.out[1][sl])
        np.minimum.reduceat(x, edges, out=self.out[2][sl])
        np.maximum.reduceat(x, edges, out=self.out[3][sl])
        self.k += edges.size

    def finish(self) -> tuple[np.ndarray, ...]:
        if self.w:
            if self.rest[0].size:
                self._bins(*self.rest)
                self.rest = (_NONE, _NONE)
            return tuple(v[: self.k] for v in self.out)
        if not self.parts:
            return tuple(np.empty(0) for _ in range(4))
        if len(self.parts) == 1:
            return self.parts[0]
        return tuple(np.concatenate([p[i] for p in self.parts]) for i in range(4))


@dataclass(frozen=True)
class _Summary:
    """What the tests need of one channel of ``n`` samples: the ``offset`` (median of the first
    4096 samples), the ``quantum`` (smallest non-zero step in the first 65536, 0: continuous),
    per window length the window-mean differences of the offset-free signal (``levels``; empty
    when untested), the log noise levels (``noise``, None when untested), the block means over h0
    samples (``means``, for the median |a|; None for other channels), ``temp_means`` of the
    offset-free signal over n // 64 samples (the temperature check; empty without temperature)
    and the plotting ``timeline``."""

    n: int
    offset: float
    quantum: float
    levels: list[_Series]
    noise: _Series | None
    means: _Series | None
    temp_means: np.ndarray
    timeline: tuple[np.ndarray, ...]


class _ChannelAcc:
    """Builds the :class:`_Summary` of one channel from its samples pushed in order: half-windows
    ``hs`` (empty: untested), noise blocks of ``h_noise`` differences (0: untested), temperature
    windows of ``w_temp`` samples (0: none), statistics kept whole or bounded by ``keep``
    (:class:`_Series`), the block means kept (``means``) for the median |a|."""

    def __init__(self, n: int, hs: Sequence[int], h_noise: int, w_temp: int, keep: int | None,
                 means: bool = False) -> None:
        self.n = n
        self.head: list[np.ndarray] = []  # the first samples, until the offset is known
        self.n_head = 0
        self.offset: float | None = None
        self.pos = 0  # offset-free samples processed
        self.prev: np.ndarray | None = None  # the last offset-free sample (for differences)
        self.qmin = math.inf
        h0 = hs[0] if hs else 0
        self.blocks = _Blocks(h0 or 1, n // h0 if h0 else 0)
        self.cascade = _Cascade(len(hs), 0)
        self.levels = [_Series(n // h - 3, keep) for h in hs]
        self.means = _Series(n // h0, keep) if means and h0 else None
        self.noise_blocks = _Blocks(h_noise or 1, (n - 1) // h_noise if h_noise else 0)
        self.noise = _Series((n - 1) // h_noise - 1, keep) if h_noise else None
        self.b_wait: list[np.ndarray] = []  # noise blocks before the quantum is known
        self.b_last = _NONE  # the last noise block (levels pair adjacent blocks)
        self.temp = _Blocks(w_temp or 1, n // w_temp if w_temp else 0, keep=True)
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

    @property
    def quantum(self) -> float:
        return 0.0 if self.qmin == math.inf else self.qmin

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
        B = self.blocks.push(xo)
        if self.means is not None and B.size:
            self.means.push(self.blocks.next - B.size, B)
        for i, j0, d in self.cascade.push(B):
            self.levels[i].push(j0, d)
        if self.noise is not None:
            b = self.noise_blocks.push(_half_sq_diff(xo, self.prev))
            self.b_wait.append(b)
            if self.pos + xo.size >= min(_QUANTUM_SAMPLES, self.n):  # the quantum is known
                self._noise()
        self.temp.push(xo)
        self.prev = xo[-1]
        self.pos += xo.size

    def _noise(self) -> None:
        c = np.concatenate((self.b_last, *self.b_wait))
        self.b_wait = []
        if c.size >= 2:
            assert self.noise is not None
            self.noise.push(self.noise.pushed, _noise_levels(c, self.quantum))
        self.b_last = c[-1:]

    def finish(self) -> _Summary:
        if self.offset is None:  # fewer samples than the offset needs were announced
            x = np.concatenate(self.head) if self.head else np.empty(0)
            self.head = []
            self.offset = np.median(x[:_OFFSET_SAMPLES]) if x.size else 0.0
            self._centred(x - self.offset)
        if self.pos != self.n:
            raise InputError(f"{self.pos} samples pushed, {self.n} announced")
        if self.noise is not None and self.b_wait:
            self._noise()
        return _Summary(self.n, float(self.offset), self.quantum, self.levels, self.noise,
                        self.means, self.temp.out, self.timeline.finish())


class _Rescan:
    """The flagged statistics of one channel in the samples ``[a, ...)`` re-read from the source:
    the window-mean differences of the window lengths ``scales`` (level -> :class:`_Scale`) and
    the noise levels (``noise``), recomputed with the bits of the first read."""

    def __init__(self, a: int, n: int, offset: float, quantum: float, hs: Sequence[int],
                 h_noise: int, scales: Mapping[int, _Scale], noise: _Scale | None) -> None:
        self.offset, self.quantum, self.scales, self.noise = offset, quantum, scales, noise
        self.spans: list[_Span] = []
        h0 = hs[0] if hs else 1
        s0 = -(-a // h0)  # the first whole block
        self.skip = s0 * h0 - a
        self.blocks = _Blocks(h0, n // h0 if scales else 0, first=s0)
        self.cascade = _Cascade(max(scales) + 1 if scales else 0, s0)
        hn = h_noise or 1
        t0 = -(-a // hn)
        self.skip_n = t0 * hn - a
        self.noise_blocks = _Blocks(hn, (n - 1) // hn if noise is not None else 0, first=t0)
        self.prev: Any = None
        self.b_last = _NONE

    def push(self, x: np.ndarray) -> None:
        xo = x - self.offset
        xm = xo[self.skip:]
        self.skip = max(0, self.skip - xo.size)
        for i, j0, d in self.cascade.push(self.blocks.push(xm)):
            if i in self.scales:
                self.spans += _spans(self.scales[i], j0, d)
        if self.noise is None:
            return
        xn = xo[self.skip_n:]
        self.skip_n = max(0, self.skip_n - xo.size)
        if not xn.size:
            return
        b = self.noise_blocks.push(_half_sq_diff(xn, self.prev))
        self.prev = xn[-1]
        c = np.concatenate((self.b_last, b)) if self.b_last.size else b
        if c.size >= 2:
            self.spans += _spans(self.noise, self.noise_blocks.next - c.size,
                                 _noise_levels(c, self.quantum))
        if c.size:
            self.b_last = c[-1:]


class _TemperatureAcc:
    """Temperature pushed in order: the count, minimum and maximum of its finite values, the block
    means over ``w`` samples of the series with its non-finite values interpolated linearly
    between their finite neighbours (held constant beyond the first and last finite ones; a
    pending gap costs two numbers, not its length) and its timeline (non-finite -> NaN)."""

    def __init__(self, n: int, w: int) -> None:
        self.count, self.lo, self.hi = 0, math.inf, -math.inf
        self.blocks = _Blocks(w or 1, n // w if w else 0, keep=True)
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
    """The stationarity check (``docs/METHODS.md`` §16) of a recording read in consecutive pieces:
    :meth:`push` its rows in order, then :meth:`finish`.

    ``names`` the channels of the rows, ``n`` their total number; ``freq``, ``units``, ``alpha``,
    ``norm`` as in :func:`check_stationarity`; ``temperature`` the name of a column of the rows
    holding the temperature in deg C (NaN where unknown; not tested as a channel), with
    ``temperature_source`` naming it in messages; ``where`` names the recording in messages.
    Times are ``i / freq``.

    Each channel is reduced as it goes to the statistics of its tests (the window-mean differences
    per window length, from the block means over the base half-window h0 = max(8 samples, 0.1 s)
    / 2; the log noise levels; the block means over n / 64 samples when there is a temperature;
    a 1500-bin timeline; the offset and quantum from the first samples).

    Without a ``source`` every statistic is kept: O(n / h0) values per channel (about 16 / h0
    bytes per sample), and the report is that of :func:`check_stationarity` on the whole
    recording, bit for bit, except the median |a| of the accelerometer-norm alert, which is taken
    from the block means instead of the samples.

    With a ``source`` (a :class:`gmwm.stream.Source` holding these rows, see :meth:`for_source`)
    memory is independent of ``n``: a test with at most ``robust_sample`` statistics keeps them
    all, as above; a longer one keeps every r-th (r = ceil(count / robust_sample)) for its median
    and robust scale, and the extremes of at most 2048 blocks of consecutive statistics (at most
    ``robust_sample`` blocks). After the
    read, the blocks whose extremes pass the threshold are re-read from the source and their
    statistics recomputed with the same bits (flagged ranges come out exactly, a static recording
    is read once; one flagged everywhere is read twice). Per channel that is at most
    ``robust_sample`` + 2 x 2048 values per test and window length (log2(n / (131 h0)) window
    lengths: 19 for 2e8 samples at h0 = 4 samples, under 12 MB with the default), plus the pieces
    being processed (:data:`_PIECE` rows) and the flagged ranges found. Thresholds and
    counts are those of the in-memory check; the median and scale of a long test are those of its
    subsample, so a statistic within about 1 / sqrt(robust_sample) (relative) of the threshold may
    be flagged by one and not the other."""

    def __init__(self, names: Sequence[str], n: int, *, freq: float | None = None,
                 units: Mapping[str, str | None] | None = None, alpha: float = ALPHA,
                 norm: bool = True, temperature: str | bool | None = None,
                 temperature_source: str = "", time_s: np.ndarray | None = None,
                 where: str = "signal", source: Any = None,
                 robust_sample: int = ROBUST_SAMPLE) -> None:
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
        if robust_sample < MIN_DIFFS:
            raise InputError(f"robust_sample must be at least {MIN_DIFFS}, got {robust_sample}")
        self.n, self.freq, self.alpha, self.where = int(n), freq, alpha, where
        self.n_src = len(names) + (self.temp_col is not None)
        self.time_s = time_s
        self.temperature_source = temperature_source
        self.source = source
        keep = None if source is None else int(robust_sample)
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
        self.h_noise = half if self.noise_tests and self.hs else 0
        w_temp = n // _TEMP_WINDOWS if temperature is not None and temperature is not False else 0
        self.accs = [_ChannelAcc(n, self.hs, self.h_noise, w_temp if c != NORM else 0, keep,
                                 means=c == NORM) for c in chans]
        self.temp = None if temperature is None or temperature is False else \
            _TemperatureAcc(n, w_temp)
        self.pos = 0

    @classmethod
    def for_source(cls, source: Any, **kwargs: Any) -> StationarityStream:
        """The check of a :class:`gmwm.stream.Source` (its names, length, rate unless ``freq``
        is given, and its name in messages) in memory independent of its length (flagged blocks
        are re-read from it by :meth:`finish`, which must come before it is closed); ``kwargs``
        as the constructor."""
        kwargs.setdefault("freq", source.freq)
        kwargs.setdefault("where", source.where)
        return cls(source.names, source.n_samples, source=source, **kwargs)

    def _columns(self, rows: Any, at: int, check: bool = True
                 ) -> tuple[list[np.ndarray], np.ndarray | None]:
        """The float64 columns of ``rows`` (first row ``at``) in the order of ``names`` and the
        temperature column; ``check``: a NaN or inf in a tested channel is an error."""
        rows = np.asarray(rows)
        if rows.ndim == 1 and self.n_src == 1:
            rows = rows[:, None]
        if rows.ndim != 2 or rows.shape[1] != self.n_src:
            raise InputError(f"{self.where}: rows must be (m, {self.n_src}) arrays, got shape "
                             f"{rows.shape}")
        cols, temp = [], None
        for k in range(self.n_src):
            col = np.ascontiguousarray(rows[:, k], dtype=np.float64)
            if k == self.temp_col:
                temp = col
                continue
            if check and not np.isfinite(col.sum()):  # one pass; the sum is finite iff all are
                bad = ~np.isfinite(col)               # (or overflows: then look)
                if bad.any():
                    i = int(np.argmax(bad))
                    what = "NaN" if np.isnan(col[i]) else "infinite"
                    name = self.names[len(cols)]
                    raise InputError(f"channel '{name}' of {self.where} contains a {what} value "
                                     f"at sample {at + i}; clean or interpolate it first")
            cols.append(col)
        return cols, temp

    def push(self, rows: Any) -> None:
        """The next rows, shape ``(m, C)`` (1-D for one column), any numeric dtype, in order. A
        NaN or inf in a tested channel is an :class:`InputError` naming the channel and
        sample."""
        m = np.shape(rows)[0] if np.ndim(rows) else 0
        if self.pos + m > self.n:
            raise InputError(f"{self.where}: more than the {self.n} samples announced")
        cols, temp = self._columns(rows, self.pos)
        self._push(cols, None, temp)

    def _norm(self, cols: Sequence[np.ndarray]) -> np.ndarray:
        assert self.norm_idx is not None
        return np.sqrt(sum(cols[i] ** 2 for i in self.norm_idx))

    def _push(self, cols: list[np.ndarray], t: np.ndarray | None,
              temp: np.ndarray | None) -> None:
        """Float64 columns in the order of ``names`` (and the temperature), times ``t`` (s since
        the first sample; None: ``i / freq``), in pieces of at most :data:`_PIECE` rows."""
        m = cols[0].size
        a_all = None
        if self.norm_idx is not None and self.pos == 0 and m == self.n:
            a_all = self._norm(cols)  # the whole recording: the median of its samples
            self.norm_g = float(np.median(a_all))
        for i in range(0, m, _PIECE):
            e = min(m, i + _PIECE)
            piece = [c[i:e] for c in cols]
            if self.norm_idx is not None:
                piece.append(a_all[i:e] if a_all is not None else self._norm(piece))
            if t is None:
                tp = np.arange(self.pos, self.pos + e - i, dtype=np.float64)
                tp /= self.freq or 1.0  # the bits of np.arange(n) / freq
            else:
                tp = t[i:e]
            for acc, x in zip(self.accs, piece, strict=True):
                acc.push(x, tp)
            if self.temp is not None and temp is not None:
                self.temp.push(temp[i:e], tp)
            self.pos += e - i

    def _rescan(self, sums: Mapping[str, _Summary],
                todo: Mapping[str, tuple[dict[int, _Scale], _Scale | None, list[tuple[int, int]]]]
                ) -> dict[str, list[_Span]]:
        """The flagged spans of the blocks listed in ``todo`` (channel -> (scales of the levels
        kept bounded, the noise scale, sample ranges to re-read)), re-read from the source: the
        union of the ranges, in order, each read once for all channels."""
        from gmwm.stream import iter_rows

        ranges = sorted(r for _, _, rs in todo.values() for r in rs)
        runs: list[list[int]] = []
        for a, b in ranges:
            if runs and a <= runs[-1][1]:
                runs[-1][1] = max(runs[-1][1], b)
            else:
                runs.append([a, b])
        chunk = _chunk_rows(self.source)
        out: dict[str, list[_Span]] = {c: [] for c in todo}
        for a, b in runs:
            scans = {c: _Rescan(a, self.n, sums[c].offset, sums[c].quantum, self.hs,
                                self.h_noise, sc, nz)
                     for c, (sc, nz, rs) in todo.items() if any(r0 < b and r1 > a for r0, r1 in rs)}
            for t_a, rows in iter_rows(self.source, chunk, a, b):
                cols, _ = self._columns(rows, t_a, check=False)
                for i in range(0, cols[0].size, _PIECE):
                    piece = [c[i:i + _PIECE] for c in cols]
                    if self.norm_idx is not None:
                        piece.append(self._norm(piece))
                    for c, x in zip(self.chans, piece, strict=True):
                        if c in scans:
                            scans[c].push(x)
            for c, s in scans.items():
                out[c] += s.spans
        return out

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
            if g is None:  # pieces: the median of the block means (the samples when few)
                sm = sums[NORM]
                bm = sm.means.vals if sm.means is not None else _NONE
                g = float(np.median(bm + sm.offset if bm.size else sm.timeline[1]))
            g *= self.sensors[NORM][1]
            if not 8.8 <= g <= 10.8:
                alerts.append(f"the median accelerometer norm is {g:.4g} m/s^2, not 1 g (9.81 "
                              "m/s^2) as at rest: wrong unit, or a platform that accelerates "
                              "throughout?")
        per_channel = sum(n // h - 3 for h in hs)
        n_tests = len(self.chans) * (per_channel + self.noise_tests)
        z0 = _z_quantile(alpha / (2.0 * n_tests)) if n_tests else float("inf")
        spans: dict[str, dict[str, list[_Span]]] = {}
        peaks: list[tuple] = []
        todo = {}
        if hs:
            for c, sm in sums.items():
                sensor, si = self.sensors[c]
                spans[c] = {"mean": [], "ceiling": [], "noise": []}
                bounded: dict[int, _Scale] = {}
                noise_sc, ranges = None, []
                for i, sc, series in _scales(sm, hs, self.w_noise, z0, freq, sensor, si):
                    zmax, blocks = series.blocks(sc)
                    peaks.append((c, sc.test, sc.window, sc.count, zmax, sc.thr))
                    if series.whole:
                        spans[c][sc.test] += _spans(sc, 0, series.vals)
                    elif blocks:
                        if sc.test == "noise":
                            noise_sc = sc
                        else:
                            bounded[i] = sc
                        ranges += [sc.region(j0, j1, n) for j0, j1 in blocks]
                if ranges:
                    todo[c] = (bounded, noise_sc, ranges)
        if todo:
            if self.source is None:
                raise RuntimeError("bounded summaries without a source")  # a bug
            for c, found in self._rescan(sums, todo).items():
                for s in found:
                    spans[c][s.test].append(s)
        flags: list[Flag] = []
        for c, by_test in spans.items():
            for test, ss in by_test.items():
                for a, b, best, size in _merge(ss):
                    a, b = min(a, n), min(b, n)
                    flags.append(Flag(c, test, a, b, float(t[a]), _end_time(t, b, freq),
                                      float(t[min(best.peak, n - 1)]),
                                      best.window / (freq or 1.0), best.stat, best.thr, size))
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
                              memory: int | None = None, chunk: int | None = None,
                              robust_sample: int = ROBUST_SAMPLE) -> StationarityReport:
    """:func:`check_stationarity` of a :class:`gmwm.stream.Source` (a file larger than memory)
    read in chunks, in memory independent of its length (:class:`StationarityStream` with a
    source: read once, plus the blocks that hold flagged statistics). ``freq`` defaults to the
    source's rate (None: windows in samples); ``temperature`` names a column of deg C; ``chunk``
    rows per read (default: from ``memory``, bytes, default :data:`gmwm.stream.DEFAULT_MEMORY`);
    ``robust_sample`` as :class:`StationarityStream`. To check while the WV is computed, in the
    same read: ``check = StationarityStream.for_source(src, units=...)``,
    ``wvar_stream(src, observe=check.push)``, ``check.finish()``."""
    from gmwm.stream import iter_rows

    check = StationarityStream.for_source(
        source, **({} if freq is None else {"freq": freq}), units=units, alpha=alpha, norm=norm,
        temperature=temperature, temperature_source=temperature_source,
        robust_sample=robust_sample)
    for _, rows in iter_rows(source, int(chunk or _chunk_rows(source, memory))):
        check.push(rows)
    return check.finish()


def _chunk_rows(source: Any, memory: int | None = None) -> int:
    """Rows per read of ``source``: a quarter of ``memory`` (default
    :data:`gmwm.stream.DEFAULT_MEMORY`) over the chunk read, the one read ahead and its float64
    columns; rows are then processed in pieces of :data:`_PIECE`."""
    from gmwm.stream import DEFAULT_MEMORY

    C = len(source.names)
    per_row = 2 * C * max(int(getattr(source, "itemsize", 8)), 1) + 8 * C
    return max(_PIECE, int(memory or DEFAULT_MEMORY) // (4 * per_row))


def _end_time(t: Any, i1: int, freq: float | None) -> float:
    return float(t[i1]) if i1 < t.size else float(t[-1]) + 1.0 / (freq or 1.0)


def _segments(flags: Sequence[Flag], t: Any, freq: float | None, order: Sequence[str]
              ) -> tuple[Segment, ...]:
    if not flags:
        return ()
    i0 = np.array([f.i0 for f in flags])
    i1 = np.array([f.i1 for f in flags])
    out = []
    for a, b, members in _union(i0, i1):
        fl = [flags[int(j)] for j in members]
        chans = tuple(c for c in order if any(f.channel == c for f in fl))
        tests = tuple(sorted({f.test for f in fl}))
        sev = max(f.stat / f.threshold for f in fl)
        out.append(Segment(a, b, float(t[a]), _end_time(t, b, freq), chans, tests, float(sev)))
    return tuple(out)
