"""Time you can trust: the unit of a recording's time stamps, its sampling rate, jitter and gaps,
and what a gap does to the wavelet variance.

* :func:`time_column` tells a time column by its name and reads a unit from it (``timestamp
  [ns]``, ``time_us``, ``t (ms)``; ``%time`` and ``field.header.stamp`` of ``rostopic echo -p``
  are nanoseconds by that tool's definition).
* :func:`time_base` finds the unit of unlabelled stamps from their magnitude (epoch stamps:
  about 1.7e9 s = 1.7e12 ms = 1.7e15 us = 1.7e18 ns) and the rate each candidate unit implies
  (an IMU samples within :data:`RATE_RANGE` Hz); two candidates is an error naming the column
  and both rates. It then measures the rate (the mean rate between gaps), the jitter, the
  gaps (steps longer than 1.5 median steps), the samples they dropped and the clean segments;
  :attr:`TimeBase.rate_ambiguity` says when jitter or gaps leave the rate ambiguous, and
  :func:`drop_duplicate_rows` drops exact duplicate rows (a repeated stamp with other values is
  an error).
* :func:`decide_gaps` and :func:`signal_for_wv` apply the gap policy (``docs/recordings.md``):
  the wavelet variance never runs across a gap. ``"auto"`` (default) keeps the longest clean
  segment when it holds at least :data:`LONGEST_SHARE` of the samples (a contiguous signal, so
  the fit's weights and standard errors are those of one record); otherwise it pools the Haar
  coefficients of every clean segment (:func:`segments_wv`): the WV at scale tau_j is a mean of
  squared coefficients, so the sums of squares and counts of the segments add up exactly to the
  WV of all coefficients that do not straddle a gap. ``"longest"``, ``"combine"`` force one of
  them, ``"error"`` refuses a recording with gaps. Every choice is announced in a warning.

Stamps are handled as int64 when they are integers: nanoseconds since 1970 (~1.7e18) exceed the
integers float64 holds exactly (2**53 ~ 9e15).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["GAP_POLICIES", "GAP_SHARE_LIMIT", "JITTER_LIMIT", "LONGEST_SHARE", "RATE_RANGE",
           "RATE_SPREAD_LIMIT", "TIME_UNITS", "GapDecision", "TimeBase", "decide_gaps",
           "drop_duplicate_rows", "segments_wv", "signal_for_wv", "time_base", "time_column",
           "time_from_freq"]

#: Seconds per unit of a time stamp.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: Sampling rates [Hz] that identify the unit of unlabelled stamps (an IMU samples at 1 Hz to
#: 10 kHz): a unit implying another rate is not a candidate.
RATE_RANGE = (1.0, 1e4)
#: A labelled unit implying a rate outside this range [Hz] is an error (ns read as s: 2e-7 Hz).
LABELLED_RANGE = (1e-3, 1e6)
#: A step longer than this many median steps is a gap.
GAP_FACTOR = 1.5
#: ``"auto"`` keeps the longest clean segment when it holds at least this share of the samples.
LONGEST_SHARE = 0.9
#: Limits beyond which the rate of a recording is ambiguous (:attr:`TimeBase.rate_ambiguity`):
#: the jitter of the regular steps relative to the step (beyond 10 % a jittered step passes the
#: 1.5-step gap threshold within 5 standard deviations, so the gaps found may be jitter), ...
JITTER_LIMIT = 0.10
#: ... the share of the time lost in gaps (dropped samples, or a slower clock?) ...
GAP_SHARE_LIMIT = 0.05
#: ... and the relative difference between the rate and the median-step rate.
RATE_SPREAD_LIMIT = 0.01
GAP_POLICIES = ("auto", "longest", "combine", "error")
_EPOCH_S = (9.46e8, 4.1e9)  # 2000-01-01 .. 2099: stamps since 1970 in seconds
_UNIT_WORDS = {"ns": "ns", "nsec": "ns", "nanoseconds": "ns", "us": "us", "usec": "us", "µs": "us",
               "μs": "us", "microseconds": "us", "ms": "ms", "msec": "ms", "milliseconds": "ms",
               "s": "s", "sec": "s", "secs": "s", "seconds": "s"}
_TIME_NAME = re.compile(
    r"^\s*#?\s*(?P<base>%time|field\.header\.stamp|header\.stamp|time_?stamps?|times?|t|stamps?"
    r"|secs?|seconds?|elapsed|epoch)"
    r"(?:\s*[_ ]?\s*[\[(]?\s*(?P<unit>[a-zµμ]+)\s*[\])]?)?\s*$", re.IGNORECASE)


def time_column(name: Any) -> tuple[bool, str | None]:
    """``(is a time column, unit or None)`` of a column name: ``timestamp [ns]`` -> (True, 'ns'),
    ``time`` -> (True, None), ``%time`` / ``field.header.stamp`` -> (True, 'ns'), ``gx`` ->
    (False, None). A name such as ``time_days`` is not taken for a time column."""
    m = _TIME_NAME.match(str(name))
    if m is None:
        return False, None
    if m.group("unit"):
        unit = _UNIT_WORDS.get(m.group("unit").lower())
        if unit is None:
            return False, None
        return True, unit
    base = m.group("base").lower()
    if base in ("%time", "field.header.stamp"):
        return True, "ns"
    if base in ("sec", "secs", "second", "seconds"):
        return True, "s"
    return True, None


@dataclass(frozen=True)
class TimeBase:
    """Sampling of a recording. ``freq`` [Hz] and where it came from (``source``): measured, the
    mean rate between gaps = the number of steps that are not gaps / their total time (without
    gaps (n - 1) / (t_last - t_first)), the rate the wavelet variance's time scale assumes;
    ``median_rate`` 1 / the median step and ``overall_rate`` (n - 1) / duration (gaps included),
    shown when they differ; ``rate_given`` True when ``freq`` is the user's ``--freq`` settling an
    ambiguous rate; ``unit`` of the stamps (None when the rate was given, not measured);
    ``start_s`` first stamp [s];
    ``duration_s`` last minus first stamp [s]; ``step_s`` nominal step = 1 / ``freq``; ``jitter``
    the standard deviation of the regular steps relative to the step; ``n_gaps`` steps longer than
    1.5 median steps, ``longest_gap_s`` the longest step, ``gap_share`` the share of the duration
    lost in gaps, ``dropped`` the samples the gaps miss; ``segments`` the clean runs of samples as
    ``(start, stop)`` indices; ``notes`` what the user should know."""

    freq: float
    source: str
    n: int
    unit: str | None = None
    start_s: float | None = None
    duration_s: float = 0.0
    jitter: float = 0.0
    n_gaps: int = 0
    longest_gap_s: float = 0.0
    gap_share: float = 0.0
    dropped: int = 0
    n_short: int = 0
    segments: tuple[tuple[int, int], ...] = ()
    notes: tuple[str, ...] = field(default=())
    median_rate: float | None = None
    overall_rate: float | None = None
    rate_given: bool = False

    @property
    def step_s(self) -> float:
        return 1.0 / self.freq

    @property
    def rate_ambiguity(self) -> str | None:
        """Why the measured rate is ambiguous (jitter beyond :data:`JITTER_LIMIT`, gaps beyond
        :data:`GAP_SHARE_LIMIT` of the time, the median-step rate more than
        :data:`RATE_SPREAD_LIMIT` away), or None: not measured, within the limits, or settled
        by ``--freq``."""
        if self.unit is None or self.rate_given:
            return None
        why = []
        if self.jitter > JITTER_LIMIT:
            why.append(f"step jitter {100 * self.jitter:.2g} % (limit {100 * JITTER_LIMIT:g} %)")
        if self.gap_share > GAP_SHARE_LIMIT:
            why.append(f"{self.n_gaps} gaps take {100 * self.gap_share:.2g} % of the time (limit "
                       f"{100 * GAP_SHARE_LIMIT:g} %)")
        if self.median_rate and abs(self.median_rate / self.freq - 1.0) > RATE_SPREAD_LIMIT:
            why.append(f"the median step gives {self.median_rate:.6g} Hz (limit "
                       f"{100 * RATE_SPREAD_LIMIT:g} % apart)")
        if not why:
            return None
        return (f"the sampling rate of {self.source} is ambiguous: {self.freq:.6g} Hz between "
                f"gaps, but {'; '.join(why)}")

    @property
    def longest_segment(self) -> tuple[int, int]:
        return max(self.segments or ((0, self.n),), key=lambda s: s[1] - s[0])

    def summary(self) -> str:
        """One line: rate, its source, duration, jitter and gaps."""
        text = f"{self.freq:.6g} Hz from {self.source}, {self.n} samples, {self.duration_s:.6g} s"
        if self.unit is None:
            return text
        others = [f"{what} {r:.6g} Hz" for what, r in (("median step", self.median_rate),
                                                      ("with gaps", self.overall_rate))
                  if r and abs(r / self.freq - 1.0) > 1e-3]
        if others:
            text += f" ({', '.join(others)})"
        text += f", jitter {100 * self.jitter:.2g} % of the step"
        if self.n_gaps:
            text += (f", {self.n_gaps} gap(s) (longest {self.longest_gap_s:.4g} s, "
                     f"{100 * self.gap_share:.2g} % of the time, {self.dropped} samples dropped)")
        else:
            text += ", no gaps"
        return text

    def to_dict(self) -> dict[str, Any]:
        return {"freq": self.freq, "source": self.source, "n": self.n, "unit": self.unit,
                "start_s": self.start_s, "duration_s": self.duration_s, "jitter": self.jitter,
                "n_gaps": self.n_gaps, "longest_gap_s": self.longest_gap_s,
                "gap_share": self.gap_share, "dropped": self.dropped, "n_short": self.n_short,
                "n_segments": len(self.segments), "notes": list(self.notes),
                "median_rate": self.median_rate, "overall_rate": self.overall_rate,
                "rate_given": self.rate_given, "rate_ambiguity": self.rate_ambiguity}


def time_from_freq(freq: float, n: int, source: str = "--freq") -> TimeBase:
    """The time base of a recording without stamps, sampled at ``freq`` Hz."""
    freq = float(freq)
    if not (np.isfinite(freq) and freq > 0):
        raise InputError(f"sampling frequency must be a positive number of Hz, got {freq}")
    return TimeBase(freq=freq, source=source, n=int(n), duration_s=(n - 1) / freq,
                    segments=((0, int(n)),))


def _as_stamps(t: Any, where: str) -> np.ndarray:
    a = np.asarray(t)
    if a.dtype.kind in "iu":
        return a.astype(np.int64, copy=False).reshape(-1)
    if a.dtype.kind != "f":
        raise InputError(f"{where} does not hold numbers (dtype {a.dtype})")
    a = a.astype(np.float64, copy=False).reshape(-1)
    if not np.all(np.isfinite(a)):
        first = int(np.argmax(~np.isfinite(a)))
        raise InputError(f"{where} holds NaN or inf (first at row {first + 1})")
    if a.size and np.all(a == np.round(a)) and np.max(np.abs(a)) < 2.0 ** 53:
        return a.astype(np.int64)
    return a


def _rate(step_raw: float, unit: str) -> float:
    return 1.0 / (step_raw * TIME_UNITS[unit])


def _plausible(rate: float) -> bool:
    return RATE_RANGE[0] <= rate <= RATE_RANGE[1]


def _detect_unit(t: np.ndarray, step: float, where: str) -> tuple[str, str]:
    """Unit of unlabelled stamps: by an epoch magnitude, else by the only plausible rate."""
    first = float(t[0])
    epoch = [u for u, k in TIME_UNITS.items() if _EPOCH_S[0] <= first * k <= _EPOCH_S[1]]
    if len(epoch) == 1 and _plausible(_rate(step, epoch[0])):
        return epoch[0], "by the magnitude of its stamps (time since 1970)"
    cands = [u for u in TIME_UNITS if _plausible(_rate(step, u))]
    if len(cands) == 1:
        return cands[0], "by the rate its steps imply"
    rates = ", ".join(f"{_rate(step, u):.6g} Hz if {u}" for u in (cands or TIME_UNITS))
    if not cands:
        raise InputError(f"{where} has no unit in its name and no unit gives a sampling rate "
                         f"between {RATE_RANGE[0]:g} and {RATE_RANGE[1]:g} Hz ({rates}); "
                         "give --freq")
    raise InputError(f"{where} has no unit in its name and its steps fit several units "
                     f"({rates}); give --time-unit or --freq")


def time_base(t: Any, *, name: str = "time", unit: str | None = None, where: str | None = None,
              source: str | None = None) -> TimeBase:
    """Measure the sampling of stamps ``t`` (1-D, in ``unit``; None: from ``name``, else from the
    magnitude). Raises :class:`InputError` for fewer than 2 stamps, NaN, a repeated or decreasing
    stamp (naming its row), an implausible rate for a labelled unit, or an ambiguous unit."""
    where = where or f"time column '{name}'"
    t = _as_stamps(t, where)
    if t.size < 2:
        raise InputError(f"{where} must hold at least 2 time stamps, got {t.size}")
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        i = int(bad[0])
        what = "repeats a stamp" if d[i] == 0 else "goes back in time"
        raise InputError(f"{where} is not strictly increasing: it {what} at row {i + 2} "
                         f"({bad.size} such step(s))")
    step = float(np.median(d))
    how = "given"
    if unit is None:
        unit = time_column(name)[1]
        how = "from its name" if unit is not None else how
    if unit is None:
        unit, how = _detect_unit(t, step, where)
    elif unit not in TIME_UNITS:
        raise InputError(f"unknown time unit {unit!r}; use one of {', '.join(TIME_UNITS)}")
    else:
        rate = _rate(step, unit)
        if not LABELLED_RANGE[0] <= rate <= LABELLED_RANGE[1]:
            alt = [f"{_rate(step, u):.6g} Hz if {u}" for u in TIME_UNITS
                   if u != unit and _plausible(_rate(step, u))]
            raise InputError(f"{where} in {unit} ({how}) gives a sampling rate of {rate:.6g} Hz, "
                             f"outside {LABELLED_RANGE[0]:g}-{LABELLED_RANGE[1]:g} Hz"
                             + (f" ({', '.join(alt)}): check its unit" if alt else ""))
    k = TIME_UNITS[unit]
    regular = (d > 0.5 * step) & (d <= GAP_FACTOR * step)
    gaps = np.flatnonzero(d > GAP_FACTOR * step)
    n_short = int(np.count_nonzero(d <= 0.5 * step))
    if regular.sum() < 0.5 * d.size:
        raise InputError(f"{where} is too irregular to give a sampling rate: only "
                         f"{int(regular.sum())} of {d.size} steps lie within 0.5-1.5 median steps")
    dr = d[regular].astype(np.float64)
    mean_step = float(dr.mean())
    jitter = float(dr.std() / mean_step)
    # the rate: the mean rate between gaps (steps that are not gaps over their time, short
    # steps included), the spacing the wavelet variance of every clean segment assumes
    inside = d[d <= GAP_FACTOR * step]
    freq = float(f"{inside.size / (float(inside.sum()) * k):.9g}")
    span = float(t[-1] - t[0])
    dg = d[gaps].astype(np.float64)
    dropped = int(np.sum(np.maximum(np.round(dg / mean_step) - 1, 0))) if gaps.size else 0
    cuts = np.concatenate(([0], gaps + 1, [t.size]))
    segments = tuple((int(a), int(b)) for a, b in itertools.pairwise(cuts))
    notes = []
    if jitter > 0.05:
        notes.append(f"irregular sampling in {where}: step jitter {100 * jitter:.2g} % of the "
                     f"{mean_step * k:.6g} s step")
    if gaps.size:
        notes.append(f"irregular sampling in {where}: {gaps.size} gap(s) longer than "
                     f"{GAP_FACTOR:g} steps (longest {float(d.max()) * k:.4g} s, {dropped} "
                     "samples dropped)")
    if n_short:
        notes.append(f"{where}: {n_short} step(s) shorter than half the median step")
    src = source or f"{where} ({unit}, {how})"
    tb = TimeBase(freq=freq, source=src, n=int(t.size), unit=unit, start_s=float(t[0]) * k,
                    duration_s=span * k, jitter=jitter, n_gaps=int(gaps.size),
                    longest_gap_s=float(d.max()) * k if gaps.size else 0.0,
                    gap_share=float((dg - mean_step).sum() / span) if gaps.size else 0.0,
                    dropped=dropped, n_short=n_short, segments=segments, notes=tuple(notes),
                    median_rate=float(f"{1.0 / (step * k):.9g}"),
                    overall_rate=float(f"{(t.size - 1) / (span * k):.9g}"))
    why = tb.rate_ambiguity
    if why is not None:  # said now; a configuration file needs --freq or --gaps
        tb = replace(tb, notes=(*tb.notes, f"{why}; a configuration file needs --freq or --gaps"))
    return tb


def drop_duplicate_rows(stamps: Any, columns: dict[str, np.ndarray], where: str
                        ) -> tuple[np.ndarray | None, str | None]:
    """Exact duplicate rows: a stamp repeated by the next row with the same value in every one of
    ``columns`` (vendor exports repeat rows). Returns (the rows to keep, a note giving their
    count), or (None, None) when there is none. A stamp repeated with a different value is an
    :class:`InputError` naming the row (two samples claim one instant: which is right?)."""
    t = np.asarray(stamps).reshape(-1)
    if t.size < 2:
        return None, None
    same = np.flatnonzero(t[1:] == t[:-1])
    if same.size == 0:
        return None, None
    for name, x in columns.items():
        x = np.asarray(x).reshape(-1)
        differ = same[x[same + 1] != x[same]]
        if differ.size:
            i = int(differ[0])
            raise InputError(f"{where} repeats a stamp at row {i + 2} with a different "
                             f"{name} ({x[i]:.9g} then {x[i + 1]:.9g}): two samples at one "
                             "instant; fix the file")
    keep = np.ones(t.size, dtype=bool)
    keep[same + 1] = False
    return keep, (f"{where}: {same.size} exact duplicate row(s) (same stamp, same values) "
                  "dropped")


# --------------------------------------------------------------------------------------------------
# gap policy
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GapDecision:
    """What the wavelet variance of a recording is computed on: ``policy`` 'none' (no gap: the
    whole signal), 'longest' (the longest clean segment ``segments[0]``) or 'combine' (the pooled
    Haar coefficients of ``segments``); ``used`` samples of ``n``; ``message`` the warning."""

    policy: str
    segments: tuple[tuple[int, int], ...]
    used: int
    n: int
    message: str | None = None


def decide_gaps(tb: TimeBase, policy: str = "auto", min_segment: int = 4) -> GapDecision:
    """Apply the gap ``policy`` (see the module docstring) to the time base ``tb``."""
    if policy not in GAP_POLICIES:
        raise InputError(f"unknown gap policy {policy!r}; use one of {', '.join(GAP_POLICIES)}")
    if tb.n_gaps == 0:
        return GapDecision("none", ((0, tb.n),), tb.n, tb.n)
    what = (f"{tb.n_gaps} gap(s) in the time stamps (longest {tb.longest_gap_s:.4g} s, "
            f"{tb.dropped} samples dropped, {100 * tb.gap_share:.2g} % of the time)")
    if policy == "error":
        raise InputError(f"{what}; the wavelet variance must not run across a gap: use "
                         "--gaps longest or --gaps combine")
    a, b = tb.longest_segment
    if policy == "longest" or (policy == "auto" and (b - a) >= LONGEST_SHARE * tb.n):
        if b - a < min_segment:
            raise InputError(f"{what}: the longest clean segment has only {b - a} samples")
        return GapDecision("longest", ((a, b),), b - a, tb.n,
                           f"{what}: the wavelet variance uses the longest clean segment, "
                           f"samples {a}-{b - 1} ({b - a} of {tb.n}, "
                           f"{100 * (b - a) / tb.n:.3g} %)")
    segs = tuple(s for s in tb.segments if s[1] - s[0] >= min_segment)
    used = sum(s[1] - s[0] for s in segs)
    if not segs:
        raise InputError(f"{what}: no clean segment has {min_segment} samples")
    return GapDecision("combine", segs, used, tb.n,
                       f"{what}: the wavelet variance pools the Haar coefficients of the "
                       f"{len(segs)} clean segments ({used} of {tb.n} samples); none straddles "
                       "a gap")


def segments_wv(x: np.ndarray, segments: tuple[tuple[int, int], ...], levels: int | None = None,
                freq: float = 1.0, alpha: float = 0.05, ci: str = "mixture"):
    """Haar WV of the coefficients of ``x`` inside each ``(start, stop)`` segment, pooled: per
    level the sums of squared coefficients and their counts add over segments (a segment shorter
    than the scale gives none). Default levels: floor(log2 longest segment) - 1. Returns a
    :class:`gmwm.wv.WaveletVariance` whose ``n`` are the pooled counts, with the interval ``ci``
    of :func:`gmwm.wv.wvar` (default ``"mixture"``) computed from the pooled counts and the
    samples used, as for one contiguous signal with that many coefficients (the segments are
    independent, so this slightly overstates the estimator's variance: on the safe side)."""
    from gmwm.wv import WaveletVariance, wvar
    from gmwm.wv import wv_ci as _wv_ci

    x = np.asarray(x, dtype=np.float64)
    longest = max(b - a for a, b in segments)
    jmax = longest.bit_length() - 1
    if jmax < 1:
        raise InputError("no clean segment is long enough for one wavelet scale")
    J = jmax - 1 if levels is None else int(levels)
    if J > jmax or J < 1:
        raise InputError(f"the longest clean segment ({longest} samples) allows at most "
                         f"{jmax} levels; {J} requested")
    ss = np.zeros(J)
    n = np.zeros(J, dtype=np.int64)
    for a, b in segments:
        T = b - a
        jk = min(J, T.bit_length() - 1)
        if jk < 1:
            continue
        # only the sums are pooled: the cheap eta_3 interval (the mixture one costs ~10 ms a call)
        wk = wvar(x[a:b], levels=jk, freq=freq, alpha=alpha, ci="eta3")
        ss[:jk] += wk.variance * wk.n
        n[:jk] += wk.n
    lev = np.arange(1, J + 1)
    scales = 2.0 ** lev
    variance = ss / n
    used = sum(b - a for a, b in segments)
    edof, low, high = _wv_ci(ci, variance, scales, n, int(used), alpha)
    return WaveletVariance(lev, scales, variance, low, high, n, int(used), float(freq), alpha,
                           ci_kind=ci, ci_edof=edof)


def signal_for_wv(x: np.ndarray, decision: GapDecision, levels: int | None = None,
                  freq: float = 1.0, alpha: float = 0.05):
    """The input of the WV and the fit under ``decision``: the signal itself, its longest clean
    segment (a view), or the pooled :class:`~gmwm.wv.WaveletVariance` of its segments."""
    if decision.policy == "none":
        return x
    if decision.policy == "longest":
        a, b = decision.segments[0]
        return x[a:b]
    return segments_wv(x, decision.segments, levels, freq, alpha)
