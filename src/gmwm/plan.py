"""Plan a static recording: the precision the default GMWM fit will have, as a function of the
recording length, for a sensor described by a model at known parameter values (e.g. a datasheet,
:mod:`gmwm.sensor_datasheet`). docs/METHODS.md §17.3.

For a recording of ``T`` samples the predicted covariance of the estimate is the sandwich the fit
reports as its standard errors (docs/METHODS.md §5.9), evaluated at the model's own values instead
of an estimate: the model WV ``nu(theta)`` on the default scales ``tau_j = 2^j``,
``j = 1..floor(log2 T) - 1``; ``V`` the exact covariance of the WV estimate (§4); the default
weights of :func:`gmwm.fit` computed by :func:`gmwm.inference.weight_matrix` from a WV equal to
``nu(theta)`` with its default interval; ``A`` the analytic Jacobian. Datasheet coefficients follow
by the delta method on the log scale (§10.3), so their 95 % intervals stay positive.

Identifiability rule: a component is identifiable at length T when the predicted 95 % Wald
interval of every one of its parameters excludes 0, i.e. each relative SE is at most 1/1.96
(51 %) — otherwise the fit at that length would typically warn that the component is not
distinguishable from zero (§5.8). For an AR1 the relative SE of its time constant -1/ln(phi) is
used instead of phi's.
"""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from statistics import NormalDist
from typing import Any

import numpy as np

from gmwm._once import OnceMemo
from gmwm.errors import InputError

__all__ = ["DEFAULT_DURATIONS", "IDENTIFIABLE_RSE", "Plan", "Prediction", "format_duration",
           "make_plan", "parse_duration", "parse_target", "predict"]

#: relative SE at which the 95 % Wald interval of a parameter touches 0
IDENTIFIABLE_RSE = 1.0 / NormalDist().inv_cdf(0.975)
#: recording lengths of the table when none are asked for
DEFAULT_DURATIONS = ("10min", "30min", "1h", "2h", "6h", "12h", "1d", "3d")
#: longest length searched for a minimum length or a target [s] (30 days)
MAX_SEARCH_S = 30 * 86400.0
_Z = NormalDist().inv_cdf(0.975)
_DURATION = re.compile(r"^\s*(?P<num>\d+(?:\.\d*)?|\.\d+)(?:[eE](?P<exp>[-+]?\d+))?\s*"
                       r"(?P<unit>s|sec|m|min|h|hr|d|day|days|w)?\s*$", re.IGNORECASE)
_DURATION_S = {"s": 1.0, "sec": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0, "hr": 3600.0,
               "d": 86400.0, "day": 86400.0, "days": 86400.0, "w": 604800.0}


# --------------------------------------------------------------------------------------------------
# durations and targets
# --------------------------------------------------------------------------------------------------


def parse_duration(text: str) -> float:
    """'30min', '2h', '1.5d', '90s', '1w' -> seconds. A bare number is an error (say the unit)."""
    m = _DURATION.match(str(text))
    if m is None or m.group("unit") is None:
        raise InputError(f"duration {text!r}: give a number and a unit, e.g. 30min, 2h, 1d, 90s")
    value = float(m.group("num") + (f"e{m.group('exp')}" if m.group("exp") else ""))
    seconds = value * _DURATION_S[m.group("unit").lower()]
    if not (math.isfinite(seconds) and seconds > 0):
        raise InputError(f"duration {text!r} must be positive")
    return seconds


def format_duration(seconds: float) -> str:
    """Seconds as a short human length: '45 s', '12.5 min', '2.1 h', '3.4 d'."""
    s = float(seconds)
    if not math.isfinite(s):
        return "-"
    for unit, size in (("d", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= size:
            v = s / size
            return f"{v:.3g} {unit}"
    return f"{s:.3g} s"


def parse_target(text: str) -> tuple[str, float]:
    """'RRW=20%' or 'RW[1].gamma2=0.1' -> (name, relative SE)."""
    if "=" not in str(text):
        raise InputError(f"target {text!r}: write NAME=PRECISION, e.g. RRW=20%")
    name, value = (t.strip() for t in str(text).rsplit("=", 1))
    try:
        rse = float(value[:-1]) / 100.0 if value.endswith("%") else float(value)
    except ValueError:
        raise InputError(f"target {text!r}: {value!r} is not a precision such as 20% "
                         "or 0.2") from None
    if not (math.isfinite(rse) and 0 < rse < 10):
        raise InputError(f"target {text!r}: the relative standard error must be in (0, 10)")
    if not name:
        raise InputError(f"target {text!r}: name the coefficient, e.g. RRW=20%")
    return name, rse


# --------------------------------------------------------------------------------------------------
# one length
# --------------------------------------------------------------------------------------------------


@dataclass
class Prediction:
    """Predicted precision of the default fit for one recording of ``n_samples`` samples.

    ``se`` / ``rse``: standard error and relative SE of each parameter (names as in
    :func:`gmwm.fit`); ``cov``: the sandwich covariance behind them (parameter order of
    ``se``; for joint statements about several parameters); ``coefficients``: datasheet coefficients (``value``, ``unit``, ``rse``,
    ``ci95``); ``identifiable``: per component, the rule of the module docstring; ``margin``: per
    component, the largest relative SE of its parameters (an AR1's time constant for its phi)
    over :data:`IDENTIFIABLE_RSE` (identifiable when <= 1; ``inf`` when an SE is not finite; a
    continuous measure for length searches, not part of :meth:`to_dict`)."""

    n_samples: int
    seconds: float
    levels: int
    se: dict[str, float]
    rse: dict[str, float]
    coefficients: dict[str, dict[str, Any]]
    identifiable: dict[str, bool]
    condition_number: float
    cov: np.ndarray | None = field(default=None, repr=False)
    margin: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"seconds": self.seconds, "duration": format_duration(self.seconds),
                "n_samples": self.n_samples, "levels": self.levels, "se": self.se,
                "relative_se": self.rse, "coefficients": self.coefficients,
                "identifiable": self.identifiable, "condition_number": self.condition_number}


def default_fit_options() -> tuple[str, str]:
    """The default ``weights`` and ``method`` of :func:`gmwm.fit` (read from
    :class:`gmwm.settings.FitSettings`, so a plan follows a change of the defaults)."""
    from gmwm.settings import FitSettings

    d = FitSettings()
    return str(d.weights), str(d.method)


def _default_levels(n_samples: int) -> int:
    """The levels a plan predicts at ``n_samples`` samples: J = floor(log2 T) - 1."""
    return math.floor(math.log2(n_samples)) - 1


def _expected_wv(model: Any, theta: np.ndarray, n_samples: int, levels: int | None = None) -> Any:
    """The WV a recording of ``n_samples`` samples has on average: ``nu(theta)`` on the default
    scales, with the eta_3 interval (the one the default ``ci`` weights read; the ``ci-mixture``
    weights compute theirs from the WV, so no prediction reads the WV's own interval, and the
    mixture interval's EDF costs ~40 % of a plan)."""
    from gmwm.wv import WaveletVariance

    jmax = math.floor(math.log2(n_samples))
    J = _default_levels(n_samples) if levels is None else int(levels)
    if not 1 <= J <= jmax:
        raise InputError(f"{n_samples} samples allow 1 to {jmax} levels, got {J}")
    scales = 2.0 ** np.arange(1, J + 1)
    with np.errstate(all="ignore"):
        nu = model.wv(theta, scales)
    if not np.all(np.isfinite(nu)) or np.any(nu <= 0):
        raise InputError(f"the model WV of {model.spec} is not positive and finite on {J} scales")
    return WaveletVariance.from_table(scales, nu, n_samples=int(n_samples), freq=model.freq,
                                      ci="eta3")


def _coefficients(model: Any, theta: np.ndarray, cov: np.ndarray, wv: Any, unit: str | None,
                  bi: str | None) -> dict[str, dict[str, Any]]:
    """Datasheet coefficients with log-scale delta-method intervals (gmwm.datasheet.datasheet on
    the predicted covariance), plus the bias instability (``bi``: the component standing for it)."""
    from types import SimpleNamespace

    from gmwm.datasheet import datasheet
    from gmwm.units import unit_system

    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    fake = SimpleNamespace(model=model, params=theta, param_names=model.param_names, se=se, cov=cov,
                           wv=wv)
    out: dict[str, dict[str, Any]] = {}
    for term, e in datasheet(fake, unit).items():
        parts = [("", e)] if "value" in e else list(e.items())
        for what, v in parts:
            if not isinstance(v, Mapping) or "value" not in v:
                continue
            name = term if not what else f"{term}.{what}"
            value, ci = v["value"], v.get("ci95")
            if ci is None or not value:
                rse = None
            elif value > 0:
                rse = math.log(ci[1] / value) / _Z
            else:  # a signed coefficient (an AR1's negative phi): its interval is linear
                rse = (ci[1] - ci[0]) / (2 * _Z * abs(value))
            out[name] = {"value": value, "unit": v["unit"], "rse": rse, "ci95": ci}
    if bi is not None:  # the bias instability a GM stands for: its AD peak / 0.6643
        from gmwm.sensor_datasheet import bi_of_gauss_markov

        c = next(c for c in model.components if c.name == bi)
        i = c.start + c.process.scale_index
        label, factor = unit_system(unit).level
        value = factor * bi_of_gauss_markov(theta[i])
        rse = 0.5 * se[i] / theta[i] if theta[i] > 0 and np.isfinite(se[i]) else None
        ci = None if rse is None or _Z * rse > 700 else [value * math.exp(-_Z * rse),
                                                          value * math.exp(_Z * rse)]
        out["BI"] = {"value": value, "unit": label, "rse": rse, "ci95": ci}
    return out


def _component_rse(model: Any, theta: np.ndarray, se: np.ndarray) -> dict[str, np.ndarray]:
    """Per component, the relative SEs the identifiability rule reads (module docstring)."""
    out = {}
    for c in model.components:
        p, s = theta[c.slice], se[c.slice]
        rel = np.abs(s / p)
        if c.process.name == "AR1":  # the time constant -1/ln(phi), not phi itself
            phi = abs(p[0])
            rel[0] = s[0] / (phi * abs(math.log(phi))) if 0 < phi < 1 else np.inf
        out[c.name] = rel
    return out


def _identifiable(rels: Mapping[str, np.ndarray]) -> dict[str, bool]:
    return {k: bool(np.all(np.isfinite(rel)) and np.all(rel <= IDENTIFIABLE_RSE))
            for k, rel in rels.items()}


def _margin(rels: Mapping[str, np.ndarray]) -> dict[str, float]:
    return {k: float(np.max(rel)) / IDENTIFIABLE_RSE if np.all(np.isfinite(rel)) else math.inf
            for k, rel in rels.items()}


def predict(model: Any, theta: Any, n_samples: int, *, unit: str | None = None,
            levels: int | None = None, bi: str | None = None, weights: str | None = None,
            method: str | None = None) -> Prediction:
    """Predicted precision of the default :func:`gmwm.fit` of ``model`` on a recording of
    ``n_samples`` samples whose true parameters are ``theta`` (module docstring). ``unit``: the
    signal unit (labels of the datasheet coefficients); ``bi``: the component standing for a
    datasheet's bias instability (adds the coefficient ``BI``); ``weights``/``method``: override
    the fit's defaults."""
    from gmwm.inference import Problem, model_wv_cov, omega_from_cov, weight_matrix
    from gmwm.model import as_model

    model = as_model(model)
    theta = np.asarray(theta if not isinstance(theta, Mapping) else model.theta(theta), float)
    n = int(n_samples)
    if n < 4:
        raise InputError(f"a recording of {n} samples is too short for a WV (at least 4)")
    d_weights, d_method = default_fit_options()
    weights, method = weights or d_weights, method or d_method
    wv = _expected_wv(model, theta, n, levels)
    if model.n_params > wv.n_levels:
        raise InputError(f"{n} samples give {wv.n_levels} scales, fewer than the "
                         f"{model.n_params} parameters of {model.spec}")
    V = model_wv_cov(model, theta, wv)
    if weights == "efficient":  # two-step weights converge to the inverse model covariance
        omega = omega_from_cov(V, wv.variance, method)
    else:
        omega = weight_matrix(wv, weights, method)
    cov, se, cond = Problem(model, wv, omega, method).sandwich(theta, V)
    names = model.param_names
    with np.errstate(all="ignore"):
        rse = np.abs(se / theta)
    coefs = _coefficients(model, theta, cov, wv, unit, bi)
    with np.errstate(all="ignore"):
        rels = _component_rse(model, theta, se)
    return Prediction(n, n / model.freq, wv.n_levels, dict(zip(names, map(float, se), strict=True)),
                      dict(zip(names, map(float, rse), strict=True)), coefs,
                      _identifiable(rels), float(cond), cov, _margin(rels))


# --------------------------------------------------------------------------------------------------
# lengths
# --------------------------------------------------------------------------------------------------


@dataclass
class Plan:
    """A recording plan: predictions at the asked lengths, the length from which each component
    is identifiable, and the length each target needs."""

    model: Any
    theta: np.ndarray
    unit: str | None
    predictions: list[Prediction]
    min_length: dict[str, float | None]
    targets: dict[str, dict[str, Any]]
    labels: dict[str, str]
    notes: list[str] = field(default_factory=list)
    bi: str | None = None
    weights: str = "ci"
    method: str = "gmwm"

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model.spec, "freq": self.model.freq, "units": self.unit,
                "params": self.model.as_dict(self.theta), "weights": self.weights,
                "method": self.method, "notes": self.notes,
                "identifiable_rule": ("each parameter's predicted 95 % Wald interval excludes 0 "
                                      f"(relative SE <= {IDENTIFIABLE_RSE:.3f})"),
                "lengths": [p.to_dict() for p in self.predictions],
                "min_length": {k: {"term": self.labels.get(k, k), "seconds": v,
                                   "duration": f"> {format_duration(MAX_SEARCH_S)}" if v is None
                                   else format_duration(v)}
                               for k, v in self.min_length.items()},
                "targets": self.targets}


class _Cache:
    """Predictions by sample count (the searches revisit lengths). Threads may share it: a
    length asked for while another thread predicts it waits for that prediction."""

    def __init__(self, fn: Callable[[int], Prediction]):
        self.fn, self._memo = fn, OnceMemo()

    def __call__(self, n: int) -> Prediction:
        return self._memo.get(n, lambda: self.fn(n))


def _grid(n_lo: int, n_hi: int) -> list[int]:
    """The lengths :func:`_search` evaluates first: one per octave from ``n_lo``, and ``n_hi``."""
    return sorted({round(n_lo * 2.0 ** k) for k in range(64) if n_lo * 2.0 ** k < n_hi} | {n_hi})


def _prefetch_covariances(model: Any, theta: np.ndarray, lengths: Sequence[int]) -> Any:
    """Start computing the WV covariances :func:`predict` will ask for at ``lengths`` (default
    levels) in two threads, into :func:`gmwm.wvcov.wv_covariance`'s memo, and return the thread
    pool (None when nothing was started; the caller shuts it down). The predictions do not wait
    for the whole batch: each finds its covariance in the memo, or waits for the thread computing
    it, so their Python side and SciPy's import run beside the compiled kernel (which releases
    the GIL). The same numbers, computed side by side; the lengths go in the order the plan asks
    for them. Nothing on one core; a length that fails here is left to :func:`predict`, which
    reports it."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    from gmwm.inference import nonzero_part
    from gmwm.wvcov import MEMO_SIZE, wv_covariance

    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    sub, sub_theta = nonzero_part(model, theta)
    # the costliest ones, while the memo holds them beside the ones computed later
    keep = set(sorted(set(lengths), reverse=True)[:MEMO_SIZE // 2])
    todo = [n for n in dict.fromkeys(lengths) if n in keep]  # first asked, first computed
    if cores < 2 or sub is None or len(todo) < 2:
        return None

    def one(n: int) -> None:
        scales = 2.0 ** np.arange(1, _default_levels(n) + 1)  # the scales _expected_wv predicts
        if scales.size:
            with np.errstate(all="ignore"), contextlib.suppress(Exception):
                wv_covariance(sub, sub_theta, scales, n)

    pool = ThreadPoolExecutor(max_workers=2)
    for n in todo:
        pool.submit(one, n)
    return pool


def _search(cache: _Cache, ok: Callable[[Prediction], bool], n_lo: int, n_hi: int
            ) -> int | None:
    """Smallest n (to ~2 %) from which ``ok`` holds at every point of a grid of one length per
    octave up to ``n_hi``; None if it fails at ``n_hi``."""
    grid = _grid(n_lo, n_hi)
    good = [ok(cache(n)) for n in grid]
    if not good[-1]:
        return None
    bad = [i for i, g in enumerate(good) if not g]
    if not bad:
        return grid[0]
    lo, hi = grid[bad[-1]], grid[bad[-1] + 1]
    while hi / lo > 1.02:  # bisection on the log scale
        mid = round(math.sqrt(lo * hi))
        if mid in (lo, hi):
            break
        lo, hi = (lo, mid) if ok(cache(mid)) else (mid, hi)
    return hi


def _lookup(pred: Prediction, name: str) -> float | None:
    if name in pred.coefficients:
        return pred.coefficients[name]["rse"]
    if name in pred.rse:
        return pred.rse[name]
    return None


def make_plan(model: Any, theta: Any, durations_s: Sequence[float], *, unit: str | None = None,
              targets: Sequence[tuple[str, float]] = (), bi: str | None = None,
              notes: Sequence[str] = (), labels: Mapping[str, str] | None = None,
              max_search_s: float = MAX_SEARCH_S) -> Plan:
    """Predictions at ``durations_s`` [s], the length from which each component is identifiable
    (searched up to ``max_search_s``), and for each ``(name, rse)`` target the length from which
    the coefficient or parameter ``name`` has a relative SE of at most ``rse``. ``labels`` renames
    components in the output (e.g. ``{"GM[1]": "BI (as GM[1])"}``)."""
    from gmwm.model import as_model

    model = as_model(model)
    theta = np.asarray(theta if not isinstance(theta, Mapping) else model.theta(theta), float)
    weights, method = default_fit_options()
    cache = _Cache(lambda n: predict(model, theta, n, unit=unit, bi=bi))
    n_min = 2 ** (model.n_params + 1)  # the default levels reach the number of parameters
    n_hi = max(round(max_search_s * model.freq), n_min)
    pool = _prefetch_covariances(model, theta, [round(float(s) * model.freq) for s in durations_s
                                                if round(float(s) * model.freq) >= n_min]
                                 + _grid(n_min, n_hi))
    try:
        return _make_plan(model, theta, durations_s, cache, n_min, n_hi, pool, unit=unit,
                          targets=targets, bi=bi, notes=notes, labels=labels,
                          max_search_s=max_search_s, weights=weights, method=method)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def _make_plan(model: Any, theta: np.ndarray, durations_s: Sequence[float], cache: _Cache,
               n_min: int, n_hi: int, pool: Any, *, unit: str | None,
               targets: Sequence[tuple[str, float]], bi: str | None, notes: Sequence[str],
               labels: Mapping[str, str] | None, max_search_s: float, weights: str,
               method: str) -> Plan:
    """:func:`make_plan` once the covariances are under way (in ``pool``, None: one thread)."""
    from concurrent.futures import ThreadPoolExecutor

    preds = []
    for s in durations_s:
        n = round(float(s) * model.freq)
        if n < n_min:
            raise InputError(f"a {format_duration(s)} recording at {model.freq:g} Hz has {n} "
                             f"samples; {model.spec} needs at least {n_min}")
        preds.append(cache(n))
    known = set(preds[0].coefficients if preds else cache(n_hi).coefficients) | set(
        model.param_names)
    for name, _ in targets:
        if name not in known:
            raise InputError(f"target {name!r} is not a coefficient or parameter of this plan; "
                             f"use one of {', '.join(sorted(known))}")
    oks: list[Callable[[Prediction], bool]] = [
        lambda p, c=c.name: p.identifiable[c] for c in model.components]
    for name, rse in targets:
        def ok(p: Prediction, name: str = name, rse: float = rse) -> bool:
            v = _lookup(p, name)
            return v is not None and math.isfinite(v) and v <= rse
        oks.append(ok)
    for n in _grid(n_min, n_hi):  # every search starts on this grid
        cache(n)
    if pool is not None and len(oks) > 1:
        # the bisections side by side: their covariances are computed outside the GIL
        with ThreadPoolExecutor(max_workers=len(oks)) as searches:
            found = list(searches.map(lambda ok: _search(cache, ok, n_min, n_hi), oks))
    else:
        found = [_search(cache, ok, n_min, n_hi) for ok in oks]
    min_len: dict[str, float | None] = {
        c.name: None if n is None else n / model.freq
        for c, n in zip(model.components, found, strict=False)}
    out_targets: dict[str, dict[str, Any]] = {}
    for (name, rse), n in zip(targets, found[len(model.components):], strict=True):
        out_targets[f"{name}={rse:g}"] = {
            "name": name, "relative_se": rse, "seconds": None if n is None else n / model.freq,
            "duration": (f"> {format_duration(max_search_s)}" if n is None
                         else format_duration(n / model.freq))}
    return Plan(model, theta, unit, preds, min_len, out_targets, dict(labels or {}), list(notes),
                bi, weights, method)


def curve(plan: Plan, points_per_octave: int = 2, lo_s: float | None = None,
          hi_s: float | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Relative SE of every coefficient over a log grid of lengths [s] (for plots)."""
    model = plan.model
    n_min = 2 ** (model.n_params + 1)
    asked = [p.seconds for p in plan.predictions] or [3600.0]
    lo = max(lo_s or min(asked) / 8.0, n_min / model.freq)
    hi = hi_s or max(asked) * 8.0
    secs = np.geomspace(lo, hi, max(2, int(points_per_octave * math.log2(hi / lo)) + 1))
    preds = [predict(model, plan.theta, round(s * model.freq), unit=plan.unit, bi=plan.bi)
             for s in secs]
    names = list(preds[-1].coefficients)
    return secs, {k: np.array([np.nan if p.coefficients.get(k, {}).get("rse") is None
                               else p.coefficients[k]["rse"] for p in preds]) for k in names}
