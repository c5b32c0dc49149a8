"""Datasheet coefficients of a fitted error model and the IEEE 952 Allan-deviation readings.

:func:`datasheet` turns the discrete, per-sample parameters of a GMWM fit into the continuous
coefficients a datasheet prints, in the user's units (docs/METHODS.md §10.3):

==========  ==================  ===========================================================
term        from                value (``u`` = signal unit, ``f_s`` = sampling frequency)
==========  ==================  ===========================================================
ARW / VRW   ``WN[k].sigma2``    N = sqrt(sigma2 / f_s) [u sqrt(s) = u/sqrt(Hz)]
RRW / AccRW ``RW[k].gamma2``    K = sqrt(gamma2 f_s) [u/sqrt(s)]
QN          ``QN[k].Q2``        Q = sqrt(Q2) / f_s [u s]
RR          ``DR[k].omega``     R = omega f_s [u/s] (rate ramp)
GM[k]       ``AR1``/``GM``      correlation time 1/beta = -1/(f_s ln phi) [s], stationary sigma [u]
SIN[k]      ``SIN``             frequency beta f_s / (2 pi) [Hz], amplitude alpha [u]
==========  ==================  ===========================================================

then scaled to the datasheet units of :data:`gmwm.units.UNIT_SYSTEMS` (e.g. deg/sqrt(h),
deg/h/sqrt(h) for a gyroscope in deg/s). Which row a process gives is its class's
``datasheet_kind`` (:mod:`gmwm.processes`); a process with none is an error, never a missing row. Confidence intervals are the images of the parameters' intervals
(:mod:`gmwm.intervals`: inside the parameter space, reaching 0 exactly for a component not
distinguishable from zero), so the datasheet and the parameter table agree. The module imports only
NumPy at load (fast CLI start).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from gmwm.errors import InputError, ModelError
from gmwm.units import BI_AD_FACTOR, COEFFICIENT_KINDS, unit_system

__all__ = ["allan_readings", "datasheet", "fit_readings"]

# --------------------------------------------------------------------------------------------------
# datasheet coefficients of a fit
# --------------------------------------------------------------------------------------------------


def _split(name: str) -> tuple[str, int, str]:
    comp, par = name.split(".", 1)
    ctype, k = comp[:-1].split("[")
    return ctype, int(k), par


def _entry(value: float | None, unit: str, ci: tuple[float, float] | None, params: Sequence[str]
           ) -> dict[str, Any]:
    ok = ci is not None and not (math.isnan(ci[0]) or math.isnan(ci[1]))
    return {"value": None if value is None or not np.isfinite(value) else float(value), "unit": unit,
            "ci95": [float(ci[0]), float(ci[1])] if ok else None, "parameters": list(params)}


def _intervals(result: Any, alpha: float) -> np.ndarray:
    """(p, 2) parameter intervals inside the domain: the result's own ``conf_int`` (a GMWM fit:
    :func:`gmwm.intervals.fit_intervals`), else the rule of :func:`gmwm.intervals.param_intervals`
    from ``model``, ``params``, ``cov``/``se`` (NaN where there is no SE)."""
    if callable(getattr(result, "conf_int", None)):
        return np.asarray(result.conf_int(alpha), dtype=float)
    from gmwm.intervals import param_intervals

    cov = getattr(result, "cov", None)
    return param_intervals(result.model, result.params, cov, alpha,
                           se=getattr(result, "se", None))


def _fit_cov(result: Any, idx: list[int]) -> np.ndarray | None:
    cov = getattr(result, "cov", None)
    if cov is not None:
        cov = np.asarray(cov, float)
        if cov.ndim == 2 and cov.shape[0] > max(idx):
            return cov[np.ix_(idx, idx)]
    se = getattr(result, "se", None)
    if se is None:
        return None
    return np.diag(np.asarray(se, float)[idx] ** 2)


def datasheet(result: Any, units: str | None = None, alpha: float = 0.05) -> dict[str, dict]:
    """Continuous datasheet coefficients of a fit (see the module table), keyed by term.

    ``result`` has ``model``, ``params``, ``param_names``, ``se`` (and ``cov``), ``wv.freq`` [Hz]
    and, as every result, ``conf_int(alpha)``; ``units`` is the signal unit ('deg/s', 'rad/s',
    'm/s^2', 'g' or any label). Returns e.g. ``{"ARW": {"value", "unit", "ci95", "parameters"},
    "GM[1]": {"correlation_time": {...}, "sigma": {...}}, "SIN[1]": {"frequency": {...},
    "amplitude": {...}}}``; ``ci95`` (at level ``1 - alpha``) is None when the fit has no
    interval for the parameter (no standard error).

    Intervals: a coefficient that is a monotone function of one parameter takes the image of that
    parameter's interval (:func:`gmwm.intervals.image_interval`), so the datasheet agrees with the
    parameter table by construction and reaches 0 exactly where the parameter's interval does (a
    component not distinguishable from zero, or at the boundary 0). The AR1 stationary sigma
    (phi and the innovation variance) uses the delta method with the same rule on the stationary
    variance (:func:`gmwm.intervals.function_interval`).
    """
    from gmwm.intervals import function_interval, image_interval
    from gmwm.processes import AR1, GaussMarkov, Sinusoid, process

    us = unit_system(units)
    freq = float(result.wv.freq)
    names = list(result.param_names)
    theta_all = np.asarray(result.params, float)
    ci_all = _intervals(result, alpha)
    comps: dict[tuple[str, int], dict[str, int]] = {}
    for i, name in enumerate(names):
        ctype, k, par = _split(name)
        comps.setdefault((ctype, k), {})[par] = i
    counts: dict[str, int] = {}
    for ctype, _ in comps:
        counts[ctype] = counts.get(ctype, 0) + 1
    out: dict[str, dict] = {}

    def image(fn, i: int, label_factor: tuple[str, float]) -> dict[str, Any]:
        """The entry of ``factor * fn(theta_i)``, ``fn`` monotone."""
        label, factor = label_factor
        ci = image_interval(lambda t: factor * fn(t), ci_all[i])
        return _entry(factor * fn(theta_all[i]), label, ci, [names[i]])

    def blank_shape(entry: dict[str, Any], size: str, shape: str) -> dict[str, Any]:
        # a component estimated at 0 has no identifiable time scale or frequency
        if entry[size]["value"] == 0.0:
            entry[shape].update(value=None, ci95=None, note=f"not identified: {size} is 0")
        return entry

    def ar1_sigma(idx: list[int]) -> dict[str, Any]:
        """The stationary sigma sqrt(sigma2 / (1 - phi^2)) of an AR1 [signal units]."""
        label, factor = us.level
        i_s2 = idx[1]
        theta = theta_all[idx]

        def var(t: np.ndarray) -> float:
            return AR1.stationary_variance(t[0], t[1])

        reaches_zero = ci_all[i_s2, 0] == 0.0
        phi_lo, phi_hi = ci_all[idx[0]]
        cov = _fit_cov(result, idx)
        ci = (float("nan"), float("nan"))
        cov_ok = cov is not None and bool(np.all(np.isfinite(cov)))
        if cov_ok and -1.0 < phi_lo and phi_hi < 1.0:
            ci = function_interval(var, theta, cov, alpha, weak=bool(reaches_zero))
        elif not cov_ok and reaches_zero:
            # at the boundary 0 (no covariance): the variance's interval at the reported phi
            ci = image_interval(lambda s2: var(np.array([theta[0], s2])), ci_all[i_s2])
        if math.isnan(ci[0]) and not np.isnan(ci_all[i_s2]).any():
            # phi's interval reaches +-1 (the linearisation fails there) or the delta method
            # failed: the image of the box of the two intervals (the stationary variance grows
            # with sigma2 and |phi|), unbounded above when phi may be +-1
            if np.isnan([phi_lo, phi_hi]).any():
                phi_lo = phi_hi = theta[0]
            p2_lo = 0.0 if phi_lo <= 0.0 <= phi_hi else min(phi_lo**2, phi_hi**2)
            p2_hi = max(phi_lo**2, phi_hi**2)
            s2_lo, s2_hi = ci_all[i_s2]
            lo = s2_lo / (1.0 - p2_lo) if p2_lo < 1.0 else (0.0 if s2_lo == 0 else math.inf)
            ci = (lo, s2_hi / (1.0 - p2_hi) if p2_hi < 1.0 else math.inf)
        ci = image_interval(lambda v: factor * math.sqrt(v), ci)
        return _entry(factor * math.sqrt(var(theta)), label, ci, [names[i] for i in idx])

    gm_k = 0
    for (ctype, k), pars in comps.items():
        proc = process(ctype)
        kind = proc.datasheet_kind
        suffix = f"[{k}]" if counts[ctype] > 1 else ""
        if kind in COEFFICIENT_KINDS:
            name, label_factor = us.coefficient(kind)
            out[name + suffix] = image(lambda v, c=proc.coefficient: c(v, freq),
                                       pars[proc.param_names[proc.scale_index]], label_factor)
        elif kind == "sinusoid":
            ia, ib = pars["alpha"], pars["beta"]
            entry = {"frequency": image(lambda b: Sinusoid.frequency_hz(b, freq), ib, ("Hz", 1.0)),
                     "amplitude": image(abs, ia, us.level)}
            for e in entry.values():
                e["parameters"] = [names[ia], names[ib]]
            out[f"SIN[{k}]"] = blank_shape(entry, "amplitude", "frequency")
        elif kind == "gauss_markov":
            gm_k += 1
            ib, i2 = pars["beta"], pars["sigma2"]
            entry = {"correlation_time": image(GaussMarkov.correlation_time, ib, ("s", 1.0)),
                     "sigma": image(lambda s2: math.sqrt(max(s2, 0.0)), i2, us.level)}
            for e in entry.values():
                e["parameters"] = [names[ib], names[i2]]
            out[f"GM[{gm_k}]"] = blank_shape(entry, "sigma", "correlation_time")
        elif kind == "ar1":
            idx = [pars["phi"], pars["sigma2"]]
            phi = theta_all[idx[0]]
            if 0.0 < phi < 1.0:  # a Gauss-Markov process sampled at f_s
                gm_k += 1
                entry = {"correlation_time": image(lambda p: AR1.correlation_time(p, freq), idx[0],
                                                   ("s", 1.0)),
                         "sigma": ar1_sigma(idx)}
                entry["correlation_time"]["parameters"] = [names[i] for i in idx]
                out[f"GM[{gm_k}]"] = blank_shape(entry, "sigma", "correlation_time")
            else:  # phi <= 0 has no continuous-time counterpart: report the AR1 itself
                out[f"AR1[{k}]"] = {"sigma": ar1_sigma(idx),
                                    "phi": image(lambda p: p, idx[0], ("", 1.0))}
        else:  # a process whose class does not say what it gives: never a silent gap
            raise ModelError(f"the datasheet does not know process {ctype} (datasheet_kind "
                             f"{kind!r}): set datasheet_kind on its class in gmwm.processes")
    return out


# --------------------------------------------------------------------------------------------------
# IEEE 952 Allan-deviation readings
# --------------------------------------------------------------------------------------------------


_LINE_NOISE = {-0.5: "WN", 0.0: "FN", 0.5: "RW"}   # AD slope -> power law with that WV slope


def _slope_runs(local: np.ndarray, slope: float, tol: float, min_points: int
                ) -> list[tuple[int, int]]:
    """Maximal runs ``[a, b)`` of at least ``min_points`` adjacent points whose local log-log
    slope is within ``tol`` of ``slope``."""
    runs, start = [], None
    for i, flag in enumerate([*(np.abs(local - slope) <= tol), False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            runs.append((start, i))
            start = None
    return [r for r in runs if r[1] - r[0] >= min_points]


def _inv_trigamma_half(v: float) -> float:
    """The ``eta`` with ``trigamma(eta / 2) = v`` (the chi-square EDF whose log has variance v)."""
    from scipy.special import polygamma

    lo, hi = 1e-3, 1e12                # trigamma(eta / 2) decreases from ~4e6 to ~2e-12
    for _ in range(100):
        mid = math.sqrt(lo * hi)
        if float(polygamma(1, mid / 2.0)) > v:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def _line_value(tau: np.ndarray, adev: np.ndarray, var_i: np.ndarray, slope: float,
                tau_read: float, run: tuple[int, int]) -> float:
    """The fixed-slope line's reading at ``tau_read``: the inverse-variance (``var_i`` of ln AD
    over the run) weighted mean intercept of ``ln AD - slope ln tau`` over ``run = [a, b)``."""
    a, b = run
    w = (1.0 / var_i) / np.sum(1.0 / var_i)
    c = float(w @ (np.log(adev[a:b]) - slope * np.log(tau[a:b])))
    return math.exp(c + slope * math.log(tau_read))


def _reading_runs(local: np.ndarray, edof: np.ndarray, i_min: int, tol: float
                  ) -> dict[str, tuple[int, int] | None]:
    """The run of points each reading uses (:func:`allan_readings`): N and K the heaviest (by
    summed edof) run of at least 2 points of their slope; B the slope-0 points within two levels
    of the minimum when a flat run of at least 3 contains it (None: no such run)."""
    out: dict[str, tuple[int, int] | None] = {}
    for key, slope in (("N", -0.5), ("K", 0.5)):
        runs = _slope_runs(local, slope, tol, 2)     # one point is no slope region
        out[key] = max(runs, key=lambda r: float(edof[r[0]:r[1]].sum())) if runs else None
    flat = [r for r in _slope_runs(local, 0.0, tol, 3) if r[0] <= i_min < r[1]]
    out["B"] = (max(flat[0][0], i_min - 2), min(flat[0][1], i_min + 3)) if flat else None
    return out


#: perturbed curves behind a K or B interval (:func:`_resampled_interval`)
RESAMPLED_DRAWS = 200
_RESAMPLED: dict[tuple, list[float] | None] = {}   # recent intervals by their inputs
_READ_AT = {"N": (-0.5, 1.0), "K": (0.5, 3.0)}


@functools.lru_cache(maxsize=16)
def _level_corr(kind: str, levels: tuple[int, ...], n_samples: int) -> np.ndarray:
    """Correlation of the levels' WV (AV) estimates under the power law ``kind`` (cached: the
    axes of one recording share their levels and length)."""
    from gmwm.wvci import power_law_wv_cov

    C = power_law_wv_cov(kind, np.asarray(levels), n_samples)
    d = np.sqrt(np.diag(C))
    return C / np.outer(d, d)


def _level_cov_chol(kind: str, levels: tuple[int, ...], n_samples: int, sd: np.ndarray
                    ) -> np.ndarray:
    """Cholesky factor of the covariance of ln AD over ``levels``: the points' SDs ``sd`` and the
    correlation of the levels' estimates under the power law ``kind``."""
    S = _level_corr(kind, levels, n_samples) * np.outer(sd, sd)
    return np.linalg.cholesky(S + 1e-12 * np.diag(np.diag(S)))


def _resampled_interval(key: str, tau: np.ndarray, adev: np.ndarray, edof: np.ndarray,
                        levels: np.ndarray, n_samples: int, tol: float, alpha: float
                        ) -> list[float] | None:
    """Percentile interval of the ``key`` reading (K or B) over :data:`RESAMPLED_DRAWS` Allan
    deviation curves drawn around the observed one (ln AD_i with its chi-square variance
    ``trigamma(eta_i / 2) / 4`` and the levels' correlation under the reading's own noise type,
    RW for K, flicker for B), each read again by the same rule: the interval then carries the
    choice of the run and, for K, the read-out far outside it, which a line's own interval does
    not (docs/METHODS.md §9.3). Seeded (the same curve gives the same interval); None when fewer
    than half of the curves give the reading."""
    from scipy.special import polygamma

    # the report and the filter exports read the same AV: the second call reuses the draws
    memo_key = (key, tau.tobytes(), adev.tobytes(), edof.tobytes(), levels.tobytes(),
                int(n_samples), tol, alpha)
    if memo_key in _RESAMPLED:
        hit = _RESAMPLED[memo_key]
        return list(hit) if hit is not None else None
    var_i = np.asarray(polygamma(1, edof / 2.0), dtype=np.float64) / 4.0
    L = _level_cov_chol("RW" if key == "K" else "FN", tuple(int(v) for v in levels),
                        int(n_samples), np.sqrt(var_i))
    rng = np.random.default_rng(0)
    E = rng.standard_normal((RESAMPLED_DRAWS, adev.size)) @ L.T
    lt = np.log10(tau)
    vals = []
    for e in E:
        ad = adev * np.exp(e)
        runs = _reading_runs(np.gradient(np.log10(ad), lt), edof, int(np.argmin(ad)), tol)
        run = runs[key]
        if run is None:
            continue
        slope, at = _READ_AT.get(key, (0.0, float(tau[int(np.argmin(ad))])))
        vals.append(_line_value(tau, ad, var_i[run[0]:run[1]], slope, at, run))
    ci = None
    if len(vals) >= RESAMPLED_DRAWS // 2:
        lo, hi = np.quantile(np.log(vals), [alpha / 2.0, 1.0 - alpha / 2.0])
        ci = [float(math.exp(lo)), float(math.exp(hi))]
    if len(_RESAMPLED) >= 64:
        _RESAMPLED.clear()
    _RESAMPLED[memo_key] = ci
    return list(ci) if ci is not None else None


def _line_reading(tau: np.ndarray, adev: np.ndarray, edof: np.ndarray, levels: np.ndarray,
                  n_samples: int, slope: float, tau_read: float, run: tuple[int, int],
                  alpha: float) -> dict[str, Any]:
    """Fixed-slope line through the points ``run = [a, b)``, read at ``tau_read`` [s]; weights =
    inverse variances of ln AD_i, ``trigamma(eta_i / 2) / 4`` for a chi-square AV estimate with
    ``eta_i`` edof (the delta method's ``1 / (2 eta_i)`` is too small at the last levels). CI:
    chi-square form with the effective edof whose log-chi-square has the reading's variance, that
    from each point's and the correlation between the levels' WV estimates under the line's own
    noise type (WN for slope -1/2, flicker for 0, RW for +1/2;
    :func:`gmwm.wvci.power_law_wv_cov`): exactly one point's chi-square interval when the run is
    one point, narrower as points add information."""
    from scipy.special import chdtri, polygamma

    from gmwm.wvci import power_law_wv_cov

    a, b = run
    var_i = np.asarray(polygamma(1, edof[a:b] / 2.0), dtype=np.float64) / 4.0   # Var(ln AD_i)
    w = (1.0 / var_i) / np.sum(1.0 / var_i)
    value = _line_value(tau, adev, var_i, slope, tau_read, run)
    cov = power_law_wv_cov(_LINE_NOISE[slope], levels[a:b], n_samples)
    d = np.sqrt(np.diag(cov))
    sd = np.sqrt(var_i)
    var = float(w @ (cov / np.outer(d, d) * np.outer(sd, sd)) @ w)
    eta = float(edof[a]) if b - a == 1 else _inv_trigamma_half(4.0 * var)
    low = value * math.sqrt(eta / chdtri(eta, alpha / 2.0))
    high = value * math.sqrt(eta / chdtri(eta, 1.0 - alpha / 2.0))
    return {"value": value, "ci95": [low, high], "tau_range_s": [float(tau[a]), float(tau[b - 1])],
            "n_points": b - a, "edof": eta,
            "extrapolated": not tau[a] * (1 - 1e-12) <= tau_read <= tau[b - 1] * (1 + 1e-12)}


def fit_readings(result: Any, units: str | None = None) -> dict[str, dict] | None:
    """:func:`allan_readings` of the Allan variance of a fit's WV (``result.wv``), or None when
    the fit has no classical WV or its AV gives no reading."""
    from gmwm.wv import AllanVariance, WaveletVariance

    wv = getattr(result, "wv", None)
    if not isinstance(wv, WaveletVariance):
        return None
    try:
        return allan_readings(AllanVariance.from_wv(wv), units or None)
    except InputError:
        return None


def allan_readings(av: Any, units: str | None = None, tol: float = 0.15) -> dict[str, dict]:
    """IEEE 952 readings of a maximal-overlap Allan variance ``av`` (``tau`` [s], ``avar``,
    ``ci_low``, ``ci_high``, ``clusters``, ``n``, and ``ci_edof`` if it has them):

    * ``N`` (white noise, ARW/VRW): the slope -1/2 line read at tau = 1 s;
    * ``K`` (random walk, RRW/AccRW): the slope +1/2 line read at tau = 3 s;
    * ``B`` (bias instability): the floor of a flat region / 0.6643. A flat region is a run of at
      least 3 adjacent points whose local log-log slope is within ``tol`` of 0 and which contains
      the AD minimum; B is then the slope-0 line through its points within two levels of the
      minimum. Without one (e.g. white noise meeting
      a random walk, or a deviation still falling at the longest cluster time: the floor is not
      reached) B is the AD minimum / 0.6643 with ``upper_bound: True`` and a ``note`` (``at_end``:
      the minimum is the longest cluster time).

    Slope lines use the heaviest (by summed edof) run of at least 2 adjacent points whose local
    slope is within ``tol`` of the nominal one. The CI (``ci95``, level ``1 - av.alpha``): for N
    the points' chi-square intervals combined with the correlation of the levels (see
    :func:`_line_reading`); for K and a flat-region B a percentile interval over re-read perturbed
    curves (:func:`_resampled_interval`; ``ci_method: "resampled"``), which carries the choice of
    the run and K's read-out far outside it (docs/METHODS.md §9.3). A line
    read outside its run whose near end is within two levels (a factor 4 in tau) of the AD
    minimum carries a ``warning``: near the crossover the other noise still adds to the deviation,
    so the extrapolated reading is too high. Values in the datasheet units of ``units`` (N, K, B
    labels as in :func:`datasheet`); a reading with no region of its slope is
    ``{"value": None, "note": ...}``.
    """
    us = unit_system(units)
    tau = np.asarray(av.tau, float)
    var = np.asarray(av.avar, float)
    lo, hi = np.asarray(av.ci_low, float), np.asarray(av.ci_high, float)
    m = np.asarray(av.clusters, float)
    n = np.asarray(av.n, float)
    levels = np.asarray(getattr(av, "levels", np.log2(2 * m)), float).round().astype(np.int64)
    ci_edof = getattr(av, "ci_edof", None)
    # each point's equivalent degrees of freedom: those of its interval (eta_3 if unknown)
    edof = np.maximum(n / (2.0 * m), 1.0) if ci_edof is None else np.asarray(ci_edof, float)
    keep = (var > 0) & (lo > 0) & np.isfinite(hi) & np.isfinite(edof)
    if keep.sum() < 3:
        raise InputError("the Allan variance needs at least 3 positive values for the readings")
    tau, var, lo, hi, edof, levels = (a[keep] for a in (tau, var, lo, hi, edof, levels))
    T = int(av.n_samples)
    alpha = float(getattr(av, "alpha", 0.05))
    adev, dlo, dhi = np.sqrt(var), np.sqrt(lo), np.sqrt(hi)
    local = np.gradient(np.log10(adev), np.log10(tau))
    i_min = int(np.argmin(adev))
    chosen = _reading_runs(local, edof, i_min, tol)
    out: dict[str, dict] = {}
    for key, slope, tau_read, (label, factor), name in (
            ("N", -0.5, 1.0, us.white, us.white_name), ("K", 0.5, 3.0, us.rw, us.rw_name)):
        run = chosen[key]
        if run is None:
            out[key] = {"value": None, "unit": label, "ci95": None, "name": name,
                        "note": f"no region of slope {slope:+g} in the Allan deviation"}
            continue
        r = _line_reading(tau, adev, edof, levels, T, slope, tau_read, run, alpha)
        if key == "K":  # the line's own interval misses the run choice and the read-out far out
            ci = _resampled_interval("K", tau, adev, edof, levels, T, tol, alpha)
            if ci is not None:
                r.update(ci95=ci, ci_method="resampled")
        r["value"] *= factor
        r["ci95"] = [c * factor for c in r["ci95"]]
        near = run[1] - 1 if slope < 0 else run[0]   # the run's end towards the crossover
        entry = {"name": name, "unit": label, **r, "read_at_tau_s": tau_read}
        if r["extrapolated"] and abs(near - i_min) <= 2:
            entry["warning"] = (f"{key} extrapolated from a slope {slope:+g} region that "
                                f"{'ends' if slope < 0 else 'starts'} within a factor 4 in tau of "
                                f"the Allan-deviation minimum ({tau[i_min]:.4g} s): the other noise "
                                "adds to the deviation there, so the reading is likely too high")
        out[key] = entry
    label, factor = us.level
    at_end = bool(i_min == adev.size - 1)
    entry: dict[str, Any] = {"name": "bias instability", "unit": label, "tau_s": float(tau[i_min]),
                             "at_end": at_end}
    if chosen["B"] is not None:
        # the floor: the slope-0 line through the flat points within two levels of the minimum
        # (their mean lacks the downward selection bias of the minimum of noisy points; farther
        # points, still within tol of slope 0, can sit measurably above the floor)
        run = chosen["B"]
        r = _line_reading(tau, adev, edof, levels, T, 0.0, float(tau[i_min]), run, alpha)
        ci = _resampled_interval("B", tau, adev, edof, levels, T, tol, alpha)
        if ci is not None:  # the run is placed by the noisy minimum: resample that choice
            r.update(ci95=ci, ci_method="resampled")
        entry.update(value=factor * r["value"] / BI_AD_FACTOR, upper_bound=False,
                     ci95=[factor * c / BI_AD_FACTOR for c in r["ci95"]],
                     tau_range_s=r["tau_range_s"], n_points=r["n_points"])
    else:
        why = ("the minimum is at the longest cluster time: the floor is not reached" if at_end
               else f"no flat region (>= 3 points of local slope within {tol:g} of 0) at the "
                    "minimum")
        entry.update(value=factor * adev[i_min] / BI_AD_FACTOR, upper_bound=True,
                     ci95=[factor * dlo[i_min] / BI_AD_FACTOR, factor * dhi[i_min] / BI_AD_FACTOR],
                     note=f"upper bound: {why}")
    out["B"] = entry
    return out
