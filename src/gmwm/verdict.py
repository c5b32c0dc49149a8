"""What a configuration file may say: the checks between a calibration and the file a user keeps.

A filter configuration is copied into Kalibr, OpenVINS, ... long after the terminal that printed
the warnings is gone, so what the tool knows about the numbers has to travel in the file, and a
file whose numbers the tool knows to be meaningless must not be written at all. This module holds
those rules (docs/METHODS.md §10.7); the calibration path applies them and the writers put
:attr:`Verdict.caveats` at the top of every configuration file.

Rules (each a function below, each with its constant):

* **Too short** (:data:`MIN_SAMPLES`): fewer samples than the shortest record on which the white
  noise level's interval and the goodness-of-fit test mean something: no configuration.
* **Not identifiable at this length** (:func:`identifiability`): a component whose predicted 95 %
  interval at the fitted values and this length includes 0 (:func:`gmwm.plan.predict`, the
  rule of ``gmwm plan``) is flagged, with the length from which it would be identifiable.
* **White at the sampling rate** (:func:`white_equivalent`): a GM or AR1 term whose correlation
  time is at most :data:`FAST_TAU_SAMPLES` sampling intervals is white noise for a filter
  running at that rate; its white-noise-equivalent density is added to the white noise's
  (``N_eff^2 = (sigma2_WN + sum_k LRV_k) / f``, ``LRV`` the term's long-run variance per sample,
  the sum of its autocovariances: ``sigma2 (1 + phi) / (1 - phi)`` for a GM of stationary
  variance ``sigma2``, ``s2 / (1 - phi)^2`` for an AR1 of innovation variance ``s2``), with a
  delta-method interval on the log scale.
* **Misfit** (:func:`misfit`): when the goodness-of-fit test rejects the model (the rule on long
  real recordings), its size in the WV's own terms: the largest relative departure of the model
  WV from the estimated WV, and the scale where it occurs.
* **Units** (:func:`unit_warning`): a white-noise density beyond any known sensor of its class
  names the likely mix-up (deg/s read as rad/s, g or mg read as m/s^2).
* **Why every candidate is rejected** (:func:`rejection_causes`): the likely causes in the order
  the data show them: too short, on-board low-pass filtering (the WV falls slower than white
  noise's ``1/tau`` over the shortest scales, :func:`short_scale_slope`), motion and a bias
  following the temperature (what the calibration path's stationarity check found,
  :class:`Evidence`); then those the data do not show.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["FAST_TAU_SAMPLES", "FLAGGED", "LOWPASS_SLOPE", "MAX_DENSITY", "MIN_SAMPLES",
           "NOT_WRITTEN", "WRITTEN", "Cause", "Evidence", "FastTerm", "Misfit", "Verdict",
           "WhiteEquivalent", "causes_text", "decide", "evidence", "identifiability", "misfit",
           "rejection_causes", "short_scale_slope", "too_short", "unit_warning",
           "white_equivalent"]

#: shortest record for a configuration [samples]: 2^12 gives 11 dyadic scales, the white-noise
#: variance to ~3 % (relative SE sqrt(2 / T) at the first scale's ~T/2 coefficients) and a
#: goodness-of-fit test with enough scales to have degrees of freedom left after a WN+GM+RW fit
MIN_SAMPLES = 4096
#: a GM/AR1 whose correlation time is at most this many sampling intervals is white for a filter
#: at that rate (lag-1 autocorrelation <= exp(-1/2) = 0.61, lag 3 <= 0.22)
FAST_TAU_SAMPLES = 2.0
#: white-noise densities beyond every known sensor of the class, SI per sqrt(Hz): consumer MEMS
#: gyroscopes are ~1e-3..1e-2 rad/s/sqrt(Hz), accelerometers ~1e-3..1e-2 m/s^2/sqrt(Hz); a
#: value 10x beyond the noisiest is a unit mix-up, not a sensor
MAX_DENSITY = {"gyroscope": 0.1, "accelerometer": 1.0}
_LIKELY_MIXUP = {"gyroscope": "deg/s read as rad/s (x 57.3)",
                 "accelerometer": "mg read as m/s^2 (x 1000) or g read as m/s^2 (x 9.81 is "
                                  "plausible; x 1000 is not)"}
_Z95 = 1.959963984540054


def too_short(n_samples: int) -> str | None:
    """The one-line reason no configuration can be written from ``n_samples`` samples, or None."""
    if n_samples >= MIN_SAMPLES:
        return None
    return (f"{n_samples} samples used: fewer than the {MIN_SAMPLES} a configuration needs (the "
            "white-noise level's interval and the goodness-of-fit test need at least "
            f"{int(math.log2(MIN_SAMPLES)) - 1} scales)")


# -- white at the sampling rate ------------------------------------------------------------------
@dataclass(frozen=True)
class FastTerm:
    """A GM/AR1 component white at the sampling rate: its correlation time [s] and in sampling
    intervals, and its white-noise-equivalent density [unit/sqrt(Hz)]."""

    component: str
    tau_s: float
    tau_samples: float
    density: float


@dataclass(frozen=True)
class WhiteEquivalent:
    """The white-noise density a filter at the sampling rate should use [unit/sqrt(Hz)]: the WN
    term's own (``white``) and the one with every fast term folded in (``density``, ``ci95``)."""

    white: float
    density: float
    ci95: tuple[float, float]
    folded: tuple[FastTerm, ...] = ()

    @property
    def changed(self) -> bool:
        return bool(self.folded)

    def rule(self) -> str:
        """The rule as the configuration files state it."""
        return (f"a Gauss-Markov/AR1 term with a correlation time of at most "
                f"{FAST_TAU_SAMPLES:g} sampling intervals is white noise for a filter at this "
                "rate: its white-noise-equivalent density (its long-run variance per sample / "
                "rate, square-rooted) is added in quadrature to the white noise's")


def _ar1_lrv(process: str, p: np.ndarray, freq: float) -> tuple[float, float, np.ndarray]:
    """(phi, long-run variance per sample, its gradient in the component's parameters)."""
    if process == "GM":
        beta, s2 = float(p[0]), float(p[1])
        phi = math.exp(-beta / freq)
        if not phi < 1:  # beta at 0 (or below double precision): a bias, never white
            return phi, math.inf, np.zeros(2)
        lrv = s2 * (1 + phi) / (1 - phi)
        # d lrv / d beta = s2 * d/dphi[(1+phi)/(1-phi)] * dphi/dbeta = s2 * 2/(1-phi)^2 * (-phi/f)
        g = np.array([s2 * 2 / (1 - phi) ** 2 * (-phi / freq), (1 + phi) / (1 - phi)])
        return phi, lrv, g
    phi, s2 = float(p[0]), float(p[1])
    if not abs(phi) < 1:  # a unit root: a random walk, never white
        return phi, math.inf, np.zeros(2)
    lrv = s2 / (1 - phi) ** 2
    g = np.array([2 * s2 / (1 - phi) ** 3, 1 / (1 - phi) ** 2])
    return phi, lrv, g


def white_equivalent(result: Any, max_tau_samples: float = FAST_TAU_SAMPLES
                     ) -> WhiteEquivalent | None:
    """The white-noise density with every fast GM/AR1 term folded in (module docstring), or None
    if the model has no WN and no fast term. Interval: delta method on ``log N_eff^2`` with the
    fit's covariance (kept positive); the WN's own interval when nothing is folded and the fit
    has no covariance."""
    model, theta = result.model, np.asarray(result.params, float)
    freq = float(model.freq)
    cov = getattr(result, "cov", None)
    total, grad = 0.0, np.zeros(theta.size)
    white = 0.0
    folded = []
    has_wn = False
    for c in model.components:
        name = c.process.name
        p = theta[c.slice]
        if name == "WN":
            has_wn = True
            total += float(p[0])
            white += float(p[0])
            grad[c.start] += 1.0
        elif name in ("GM", "AR1"):
            phi, lrv, g = _ar1_lrv(name, p, freq)
            if not (0 < phi < 1) or not math.isfinite(lrv) or p[1] <= 0:
                continue
            tau_samples = -1.0 / math.log(phi)
            if tau_samples > max_tau_samples:
                continue
            total += lrv
            grad[c.slice] += g
            folded.append(FastTerm(c.name, tau_samples / freq, tau_samples,
                                   math.sqrt(lrv / freq)))
    if not has_wn and not folded:
        return None
    density = math.sqrt(max(total, 0.0) / freq)
    used = grad != 0
    if cov is not None and total > 0 and np.all(np.isfinite(np.asarray(cov)[np.ix_(used, used)])):
        var = float(grad @ np.asarray(cov, float) @ grad)
        se_log = math.sqrt(max(var, 0.0)) / total  # SE of log N_eff^2
        half = 0.5 * _Z95 * se_log  # N = sqrt(N^2): half the log-scale interval
        lo, hi = density * math.exp(-half), density * math.exp(half)
    else:
        lo, hi = (math.nan, math.nan)
    return WhiteEquivalent(math.sqrt(white / freq), density, (lo, hi), tuple(folded))


# -- misfit ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Misfit:
    """Largest relative departure of the model WV from the estimated WV (``model / estimate -
    1``, signed) and the scale where it occurs [s]; ``outside`` the share of scales whose model
    WV lies outside the estimate's 95 % interval."""

    relative: float
    scale_s: float
    outside: float

    def describe(self) -> str:
        more = "above" if self.relative > 0 else "below"
        return (f"the fitted model's WV departs from the data's by up to "
                f"{abs(self.relative) * 100:.3g} % ({more}) at scale {self.scale_s:.4g} s; "
                f"{self.outside * 100:.0f} % of the scales lie outside the WV's 95 % interval")


def misfit(result: Any) -> Misfit:
    """The misfit of a fit in the WV's own terms (:class:`Misfit`)."""
    wv = result.wv
    nu = np.asarray(wv.variance, float)
    model_nu = np.asarray(result.model.wv(result.params, wv.scales), float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = model_nu / nu - 1.0
    ok = np.isfinite(rel)
    if not np.any(ok):
        return Misfit(math.nan, math.nan, math.nan)
    i = int(np.argmax(np.where(ok, np.abs(rel), -1.0)))
    lo, hi = (np.asarray(wv.ci_low, float), np.asarray(wv.ci_high, float)) \
        if hasattr(wv, "ci_low") else (nu, nu)
    outside = float(np.mean((model_nu < lo) | (model_nu > hi)))
    return Misfit(float(rel[i]), float(wv.scales[i] / wv.freq), outside)


# -- identifiability at this length ------------------------------------------------------------------
def identifiability(result: Any, n_samples: int | None = None) -> dict[str, float | None]:
    """Per component NOT identifiable at the length used (:func:`gmwm.plan.predict` at the
    fitted values, the rule of ``gmwm plan``): the length [s] from which it would be (to ~5 %:
    the returned length is identifiable and one 2**(1/16) below it is not; None: not within 30
    days). Identifiable components are absent. Components at the boundary 0 are left to the fit's
    own flags (a zero scale has no length).

    The search (:func:`_identifiable_from`) steps up the lengths once for all weak components
    (each prediction tells every component's identifiability), then closes each bracket by a
    safeguarded interpolation of the log of :attr:`gmwm.plan.Prediction.margin` against the log
    length (the relative SE is close to a power law in the length)."""
    from gmwm.plan import MAX_SEARCH_S, predict

    model, theta = result.model, np.asarray(result.params, float)
    n = int(n_samples if n_samples is not None else result.wv.n_samples)
    at = _Predictions(lambda m: predict(model, theta, m))

    now = at(n)
    if now is None:
        return {}
    weak = [c.name for c in model.components
            if not now.identifiable.get(c.name, True) and theta[c.start + c.process.scale_index] > 0]
    found = _identifiable_from(at, weak, n, int(MAX_SEARCH_S * model.freq))
    return {k: None if v is None else v / model.freq for k, v in found.items()}


#: bracket ratio at which a length search stops (four bisections of an octave, 4.4 %)
_ID_RATIO = 2.0 ** (1.0 / 16.0)


class _Predictions:
    """Predictions by sample count, each made once (None where none can be made)."""

    def __init__(self, fn: Any):
        self.fn, self.store = fn, {}

    def __call__(self, m: int) -> Any:
        if m not in self.store:
            try:
                with np.errstate(all="ignore"):
                    self.store[m] = self.fn(m)
            except Exception:  # noqa: BLE001 - a plan that cannot be made flags nothing
                self.store[m] = None
        return self.store[m]

    def known(self) -> list[int]:
        return sorted(self.store)


def _log_root(margin: Any, c: str, a: int, b: int, known: Sequence[int]) -> float:
    """log of the length where ``margin(., c)`` crosses 1 between ``a`` and ``b``: quadratic in
    log-log through a, b and the nearest other known length with a finite margin, else linear."""
    def pt(m: int) -> tuple[float, float]:
        return math.log(m), math.log(max(margin(m, c), 1e-300))

    (xa, ga), (xb, gb) = pt(a), pt(b)
    lin = xa + (xb - xa) * ga / (ga - gb) if math.isfinite(ga) and ga > gb else 0.5 * (xa + xb)
    others = [m for m in known if m not in (a, b) and math.isfinite(margin(m, c))]
    if not math.isfinite(ga) or not others:
        return lin
    xc, gc = pt(min(others, key=lambda m: min(abs(math.log(m) - xa), abs(math.log(m) - xb))))
    # Newton form through the three points; its root in (xa, xb) nearest the secant's
    d1 = (gb - ga) / (xb - xa)
    d2 = ((gc - gb) / (xc - xb) - d1) / (xc - xa)
    # g(x) = ga + d1 (x - xa) + d2 (x - xa)(x - xb) = d2 u^2 + (d1 - d2 (xb - xa)) u + ga, u = x - xa
    qa, qb = d2, d1 - d2 * (xb - xa)
    if abs(qa) < 1e-12:
        return lin if qb == 0 else xa - ga / qb
    disc = qb * qb - 4 * qa * ga
    if disc < 0:
        return lin
    roots = [xa + (-qb + sgn * math.sqrt(disc)) / (2 * qa) for sgn in (1.0, -1.0)]
    inside = [r for r in roots if xa < r < xb]
    return min(inside, key=lambda r: abs(r - lin)) if inside else lin


def _identifiable_from(at: Any, weak: Sequence[str], n: int, n_max: int) -> dict[str, int | None]:
    """For each component of ``weak`` (not identifiable at ``n`` samples), the smallest sample
    count, to a ratio :data:`_ID_RATIO`, at which it is (``at(m)``: the prediction at m, or None
    where none can be made, which counts as not identifiable; ``at.known()``: the sample counts
    predicted so far); None if not within ``n_max``."""

    def margin(m: int, name: str) -> float:
        p = at(m)
        return math.inf if p is None else p.margin.get(name, math.inf)

    def ok(m: int, name: str) -> bool:
        p = at(m)
        return p is not None and p.identifiable.get(name, False)

    # 1. step up the lengths once for every weak component: by the factor a relative SE ~ 1/sqrt(T)
    #    would need (the worst margin squared, 2x to 16x), until every one is bracketed
    lo = dict.fromkeys(weak, n)
    hi: dict[str, int] = {}
    m, pending = n, list(weak)
    while pending and m < n_max:
        worst = max(margin(m, c) for c in pending)
        step = min(max(2.0, 1.2 * worst**2), 16.0) if math.isfinite(worst) else 2.0
        m = min(round(m * step), n_max)
        for c in pending:
            if ok(m, c):
                hi[c] = m
            else:
                lo[c] = m
        pending = [c for c in pending if c not in hi]
    out: dict[str, int | None] = dict.fromkeys(weak)
    # 2. per component, shrink [lo (not identifiable), hi (identifiable)] to the ratio _ID_RATIO:
    #    the root of log(margin) against log(length), interpolated through the two ends and the
    #    nearest other length known (quadratic; a secant with two), evaluated half a ratio above
    #    and then half a ratio below (the bracket is closed when the root was right to ~2 %)
    half = 0.5 * math.log(_ID_RATIO)
    for c, b in hi.items():
        a = lo[c]
        for _ in range(12):
            if b / a <= _ID_RATIO * (1 + 1e-9) or b - a <= 1:
                break
            xa, xb = math.log(a), math.log(b)
            guard = 0.05 * (xb - xa)   # stay inside the bracket: every step shrinks it
            x = min(max(_log_root(margin, c, a, b, at.known()), xa + guard), xb - guard)
            p = round(math.exp(min(x + half, xb - guard)))
            if not a < p < b:
                break
            if not ok(p, c):
                a = p
                continue
            b = p
            q = round(math.exp(max(x - half, xa + guard)))
            if a < q < b:
                a, b = (a, q) if ok(q, c) else (q, b)
        out[c] = b
    return out


# -- units -----------------------------------------------------------------------------------------
def unit_warning(sensor: str | None, density_si: float) -> str | None:
    """A one-line warning when a white-noise density [SI/sqrt(Hz)] is beyond every known sensor
    of its class, naming the likely unit mix-up; else None."""
    limit = MAX_DENSITY.get(sensor or "")
    if limit is None or not (density_si > limit):
        return None
    unit = "rad/s/sqrt(Hz)" if sensor == "gyroscope" else "m/s^2/sqrt(Hz)"
    return (f"{sensor} white-noise density {density_si:.3g} {unit} is beyond any known "
            f"{sensor} (> {limit:g}): check the input unit; likely {_LIKELY_MIXUP[sensor]}")


# -- the verdict ------------------------------------------------------------------------------------
WRITTEN, FLAGGED, NOT_WRITTEN = "written", "written with flagged terms", "not written"


@dataclass(frozen=True)
class Verdict:
    """What happens to the configuration files: ``status`` (:data:`WRITTEN`, :data:`FLAGGED`,
    :data:`NOT_WRITTEN`), ``reasons`` (why not written, one line each), ``caveats`` (the first
    comment lines of every configuration file written; empty when there is nothing to say)."""

    status: str
    reasons: tuple[str, ...] = ()
    caveats: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())
    #: channel -> {component: length [s] from which it would be identifiable (None: beyond the
    #: plan's range)} for the components not identifiable at the length used
    unidentified: Mapping[str, Mapping[str, float | None]] = field(default_factory=dict)

    @property
    def written(self) -> bool:
        return self.status != NOT_WRITTEN

    def line(self) -> str:
        """The terminal's last line, e.g. ``verdict: configuration not written: ...``."""
        if self.status == NOT_WRITTEN:
            return "verdict: configuration NOT written: " + "; ".join(self.reasons)
        if self.status == FLAGGED:
            return (f"verdict: configuration written with {len(self.caveats)} caveat(s) in its "
                    "first comment lines")
        return "verdict: configuration written"


def decide(axes: Mapping[str, Any], *, n_samples: int,
           kinds: Mapping[str, str | None] | None = None,
           to_si: Mapping[str, float] | None = None,
           refusals: Sequence[str] = (), caveats: Sequence[str] = (),
           identified: Mapping[str, Mapping[str, float | None]] | None = None) -> Verdict:
    """The verdict for the per-axis fits ``axes`` (channel -> result or choice) of a record of
    ``n_samples`` used samples; ``kinds``: channel -> sensor kind, ``to_si``: channel -> factor
    from its signal unit to SI (for the unit check; 1 when absent). ``refusals``: reasons the
    caller already has for not writing
    (motion beyond the excluded share, an ambiguous rate); ``caveats``: lines it already has
    (ranges excluded, motion allowed); ``identified``: channel -> :func:`identifiability` at
    ``n_samples`` where the caller already has it (computed beside the fit). Adds: too short (refusal), every candidate rejected with
    the misfit, terms not identifiable at this length, fast terms folded into the noise density,
    unit mix-ups."""
    reasons = list(refusals)
    short = too_short(n_samples)
    if short:
        reasons.append(short)
    lines = list(caveats)
    kinds = dict(kinds or {})
    unidentified: dict[str, dict[str, float | None]] = {}
    for ch, obj in axes.items():
        try:
            res = getattr(obj, "result", obj)
            gof = getattr(res, "gof", None)
            if gof is not None and gof.rejected():
                from gmwm.gof import fmt_p  # here: a verdict without fits needs no scipy

                lines.append(f"{ch}: model {res.model.spec} REJECTED by the goodness-of-fit test "
                             f"(p {fmt_p(gof.p_value)}): {misfit(res).describe()}")
            if identified is not None and ch in identified:
                weak = dict(identified[ch])
            else:
                weak = identifiability(res, n_samples) if n_samples >= MIN_SAMPLES else {}
            for comp, need in weak.items():
                from gmwm.plan import format_duration

                lines.append(f"{ch}: {comp} not identifiable at this length ("
                             f"{format_duration(n_samples / res.model.freq)}); "
                             + (f"identifiable from {format_duration(need)}" if need else
                                "not within 30 days") + ": a filter term it gives is written as its "
                             "95 % upper bound, not as a measurement")
            if weak:
                unidentified[ch] = dict(weak)
            we = white_equivalent(res)
            if we is not None and we.changed:
                parts = ", ".join(f"{t.component} (correlation time {t.tau_samples:.2g} samples)"
                                  for t in we.folded)
                lines.append(f"{ch}: noise density includes {parts}: {we.rule()}")
            if we is not None:
                warn = unit_warning(kinds.get(ch), we.density * float((to_si or {}).get(ch, 1.0)))
                if warn:
                    lines.append(f"{ch}: {warn}")
        except Exception as exc:  # noqa: BLE001 - a check that fails must say so, not crash
            lines.append(f"{ch}: the configuration checks failed ({type(exc).__name__}: "
                         f"{str(exc).strip().splitlines()[0] if str(exc).strip() else exc!r}): "
                         "treat its values with care and report this")
    if reasons:
        return Verdict(NOT_WRITTEN, tuple(reasons), tuple(lines), unidentified=unidentified)
    return Verdict(FLAGGED if lines else WRITTEN, (), tuple(lines), unidentified=unidentified)



# -- why every candidate is rejected -------------------------------------------------------------
#: the WV's log-log slope over the shortest scales above which (with the intervals agreeing)
#: the samples are correlated as an on-board low-pass filter makes them: white noise falls as
#: ``tau^-1``, quantisation noise as ``tau^-2``; a one-pole filter of pole ``phi`` makes it
#: flatter (``phi`` 0.3: -0.42 between the first two scales, 0.5: -0.09, 0.8: +0.33)
LOWPASS_SLOPE = -0.8
#: how many of the shortest scales the slope spans
SLOPE_SCALES = 3


def short_scale_slope(wv: Any, n_scales: int = SLOPE_SCALES) -> tuple[float, bool]:
    """(log-log slope of the WV between its first and ``n_scales``-th scale, whether it falls
    significantly slower than white noise's ``tau^-1``: above :data:`LOWPASS_SLOPE` and the
    longer scale's lower 95 % bound times its scale above the first's upper bound times its
    scale). NaN and False with fewer than two positive scales."""
    nu = np.asarray(wv.variance, float)
    tau = np.asarray(wv.scales, float)
    k = min(n_scales, nu.size) - 1
    if k < 1 or not (nu[0] > 0 and nu[k] > 0):
        return math.nan, False
    slope = float(math.log(nu[k] / nu[0]) / math.log(tau[k] / tau[0]))
    lo = np.asarray(getattr(wv, "ci_low", nu), float)
    hi = np.asarray(getattr(wv, "ci_high", nu), float)
    sure = bool(lo[k] * tau[k] > hi[0] * tau[0])
    return slope, bool(slope > LOWPASS_SLOPE and sure)


@dataclass(frozen=True)
class Evidence:
    """What the calibration path knows of one channel beyond its WV: where the stationarity
    check flagged motion in the part used (``motion``; None: none flagged) and whether it was
    excluded from the estimate, how the bias follows the temperature (``temperature``; None:
    it does not); ``checked``/``temperature_checked``: whether each was looked at (a WV alone,
    or a recording without temperature, cannot say)."""

    motion: str | None = None
    motion_excluded: bool = False
    temperature: str | None = None
    checked: bool = False
    temperature_checked: bool = False


def evidence(stationarity: Any, channel: str, excluded: bool = False) -> Evidence:
    """The :class:`Evidence` of ``channel`` in a :class:`gmwm.stationarity.StationarityReport`
    (its ``used`` range; None: nothing checked); ``excluded``: the flagged motion was left out
    of the estimate."""
    st = stationarity
    if st is None or not getattr(st, "tested", True):
        return Evidence()
    from gmwm.formatting import spans

    a, b = st.used or (0, st.n)
    segs = [s for s in st.segments_in(a, b) if channel in s.channels]
    t = getattr(st, "temperature", None)
    temp = None
    if t is not None and channel in t.following:
        r, slope, _, _ = t.channels[channel]
        unit = (getattr(st, "units", None) or {}).get(channel) or "units"
        temp = (f"its bias follows the temperature ({slope:.3g} {unit}/degC, r = {r:.2f}, "
                f"{t.range_c[0]:.3g}-{t.range_c[1]:.3g} degC)")
    return Evidence(spans(st, segs) if segs else None, bool(segs) and excluded, temp, True,
                    t is not None)


@dataclass(frozen=True)
class Cause:
    """One likely cause of a rejected fit: ``name``, whether the data ``shown`` it, and the
    ``reason`` (what in the data shows it, or why it is not ruled out)."""

    name: str
    shown: bool
    reason: str


def rejection_causes(result: Any, *, n_samples: int | None = None,
                     evidence: Evidence | None = None,
                     weak: Mapping[str, float | None] | None = None) -> list[Cause]:
    """The likely causes of a fit the goodness-of-fit test rejects, those the data show first,
    each group in the order: too short (below :data:`MIN_SAMPLES`; a random walk or
    Gauss-Markov term not identifiable at this length, :func:`identifiability`, is weaker
    evidence and comes after the other causes shown), on-board low-pass filtering
    (:func:`short_scale_slope`), motion, temperature (``evidence``, from the calibration path);
    last always "a process outside the candidates". ``weak``: :func:`identifiability` at this
    length where the caller already has it."""
    ev = evidence or Evidence()
    wv = result.wv
    n = int(n_samples if n_samples is not None else getattr(wv, "n_samples", 0))
    causes: list[Cause] = []
    short = too_short(n)
    with np.errstate(divide="ignore", invalid="ignore"):  # a term at 0 has no relative SE
        weak = {} if short else (dict(weak) if weak is not None
                                 else identifiability(result, n))
    if short:
        causes.append(Cause("too short", True, short))
    elif weak:
        from gmwm.plan import format_duration

        names = ", ".join(f"{c} (from {format_duration(v)})" if v else c for c, v in weak.items())
        causes.append(Cause("too short", True, f"{names} not identifiable at this length "
                            f"({n} samples, {len(wv.scales)} scales)"))
    else:
        causes.append(Cause("too short", False, f"{n} samples, {len(wv.scales)} scales"))
    slope, steep = short_scale_slope(wv)
    k = min(SLOPE_SCALES, len(wv.scales))
    shape = (f"the WV falls as tau^{slope:.2f} over the first {k} scales, white noise as tau^-1"
             if math.isfinite(slope) else "too few scales to tell")
    causes.append(Cause("on-board low-pass filtering", steep,
                        shape + (": neighbouring samples are correlated as a filter on the "
                                 "sensor makes them" if steep else "")))
    if ev.motion is not None:
        causes.append(Cause("motion", not ev.motion_excluded,
                            f"flagged at {ev.motion}" + (" and excluded; what the check could not "
                                                         "see may remain" if ev.motion_excluded
                                                         else ", inside the estimate")))
    else:
        causes.append(Cause("motion", False, "none flagged" if ev.checked else "not checked"))
    if ev.temperature is not None:
        causes.append(Cause("temperature", True, ev.temperature))
    else:
        causes.append(Cause("temperature", False, "no link to the temperature found"
                            if ev.temperature_checked else
                            "not checked: the recording has no temperature"))
    # a term the length cannot identify is weaker evidence than the others: after them
    lead = [] if short or not causes[0].shown else [causes.pop(0)]
    shown = [c for c in causes if c.shown] + lead
    return (shown + [c for c in causes if not c.shown]
            + [Cause("a process outside the candidates", False, "")])


def causes_text(causes: Sequence[Cause]) -> str:
    """One phrase for a warning: the causes the data show, numbered, then the others."""
    shown = [c for c in causes if c.shown]
    rest = [c for c in causes if not c.shown]
    part = "; ".join(f"{i}. {c.name}: {c.reason}" for i, c in enumerate(shown, 1))
    other = ", ".join(f"{c.name} ({c.reason})" if c.reason else c.name for c in rest)
    if not shown:
        return f"no likely cause shows in the data; not ruled out: {other}"
    return f"likely causes, in the order the data show them: {part}; not ruled out: {other}"
