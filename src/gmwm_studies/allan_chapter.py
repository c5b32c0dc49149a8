"""Reproduction study of the Allan-variance chapter ([AV-chapter], docs/METHODS.md §15).

One pure function per item of the chapter, each returning tables (pandas) and arrays; figures are
drawn from those results by the ``figure_*`` functions. Every random quantity comes from
:func:`gmwm_studies.seeds.replicate_rng` keyed by ``"allan/<item>"``, the sample size and the
replicate, under one base seed.

Conventions (docs/METHODS.md §2.4): the chapter's scale ``tau_j = 2**j`` is a **cluster length** m
in samples; the project's Haar WV level j has filter length 2m, and AV(m) = 2 nu_j. Signals are
per-sample (sampling rate 1 Hz), so cluster times in seconds are cluster lengths in samples.

Items
-----
* Figs 4.1 / 4.2 (:func:`adev_study`): Allan deviation of simulated WN and WN + RW with the
  theoretical lines (slopes -1/2, +1/2; AV = sigma^2/m + gamma^2 m / 3, chapter Sec. 4.4.1), the
  IEEE 952 readings (:func:`gmwm.datasheet.allan_readings`) and the GMWM fit. A least-squares
  slope of log AD is judged against the same fit to the exact AV over the same clusters
  (``truth``; 0.4934 on Fig 4.2's three longest, where the WN still adds), the chapter's +-1/2
  beside it (``nominal``).
* Example 4.2 (:func:`ma1_study`): the chapter's closed-form AV of an MA(1), against Lemma 4.2,
  the project's exact WV of an equivalent QN + WN model (theta < 0) and a simulation.
* Lemma 4.2 (:func:`lemma42_study`): AV from the autocovariance of an ARMA(1,1) against the
  definition (a quadratic form), the spectral integral (discrete-time analogue of Lemma 4.1) and,
  where the ARMA(1,1) is a WN + AR1 sum, the project's exact WV.
* Sec. 4.2.2 (:func:`ambiguity_study`): two spectra with the same AV, (a) the chapter's
  construction Phi(f) = 2 Phi(2 f) in continuous time, (b) a discrete-time pair of MA(4) processes
  whose AVs agree at every dyadic cluster although their spectral difference is a trigonometric
  polynomial (so not of the form Phi(f) = 2 Phi(2f)).
* Remark 4.3 (:func:`interval_study`): Gaussian AV intervals (the project's Gaussian variance
  (docs/METHODS.md eq. 2.3) and a Bartlett long-run variance, the chapter's Sec. 4.3.3) go below 0
  at long clusters; the project's chi-square intervals do not.
* Example 4.1 (:func:`mle_study`): exact Gaussian MLE of WN + AR1 (the chapter's likelihood,
  evaluated by a Kalman filter, and by the chapter's dense T x T matrix for its cost), failure
  counts and run times beside the GMWM on the same signals.
"""

from __future__ import annotations

import inspect
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

import gmwm
from gmwm.datasheet import allan_readings
from gmwm.errors import InputError
from gmwm.wv import AllanVariance, haar_levels, wvar, wvar_many
from gmwm_studies.seeds import replicate_rng, replicate_seed

__all__ = [
    "DYADIC_NULL",
    "FIG41",
    "FIG42",
    "MLE_SETTINGS",
    "AdevResult",
    "AmbiguityResult",
    "MLEFit",
    "additivity_study",
    "adev_replicates",
    "adev_study",
    "allan_counts",
    "ambiguity_study",
    "arma11_acvf",
    "arma11_as_wn_ar1",
    "arma11_spectrum",
    "av_continuous",
    "av_from_acvf",
    "av_lemma41_sampled",
    "av_quadratic_form",
    "av_spectral",
    "avsm_consistency_study",
    "bartlett_lrv",
    "dense_cost",
    "dyadic_pair_acvf",
    "figure_adev",
    "figure_ambiguity",
    "figure_intervals",
    "figure_ma1",
    "fit_wn_ar1_mle",
    "flicker_av",
    "haar_levels",
    "interval_kinds",
    "interval_study",
    "items_numbers",
    "lemma41_study",
    "lemma42_study",
    "ma1_acvf",
    "ma1_as_qn_wn",
    "ma1_av",
    "ma1_study",
    "ma_coefficients",
    "mle_study",
    "moav_asymptotics_study",
    "moav_at",
    "model_av",
    "moment_start",
    "readings_table",
    "wn_ar1_loglike",
    "wn_ar1_loglike_dense",
]

#: Chapter Fig. 4.1: white noise, sigma^2 = 1, T = 1e5.
FIG41: dict[str, float] = {"WN[1].sigma2": 1.0}
#: Chapter Fig. 4.2: WN sigma^2 = 10^2 plus RW gamma^2 = 0.03^2, T = 1e5.
FIG42: dict[str, float] = {"WN[1].sigma2": 100.0, "RW[1].gamma2": 0.03**2}
_FIGS = {"fig41": ("WN", FIG41), "fig42": ("WN+RW", FIG42)}


def _rng(item: str, n: int, r: int, seed: int) -> np.random.Generator:
    return replicate_rng(f"allan/{item}", int(n), int(r), int(seed))


def _clusters(J: int) -> np.ndarray:
    """Cluster lengths m = 2**(j-1), j = 1..J (docs/METHODS.md §2.4)."""
    return 2 ** np.arange(J)


# ==================================================================================================
# Exact Allan variances
# ==================================================================================================


def model_av(model: str | gmwm.Model, params: Mapping[str, float], m: Any) -> np.ndarray:
    """Exact AV at cluster lengths ``m`` of a project model: AV(m) = 2 nu(tau = 2m) (§2.4)."""
    mod = model if isinstance(model, gmwm.Model) else gmwm.Model(model)
    m = np.atleast_1d(np.asarray(m, dtype=float))
    return 2.0 * mod.wv(mod.theta(dict(params)), 2.0 * m)


def av_from_acvf(acvf: np.ndarray, m: int) -> float:
    """[AV-chapter] Lemma 4.2 written with the autocovariance gamma(h) = sigma_X^2 rho(h):
    AV(m) = (m [g(0) - g(m)] + sum_{i<m} i [2 g(m-i) - g(i) - g(2m-i)]) / m^2.

    ``acvf`` holds gamma(0), ..., gamma(2m - 1) at least (docs/METHODS.md §2.4)."""
    m = int(m)
    g = np.asarray(acvf, dtype=float)
    if m < 1 or g.size < 2 * m:
        raise InputError(f"Lemma 4.2 at m = {m} needs gamma(0..{2 * m - 1}), got {g.size} lags")
    i = np.arange(1, m)
    return float((m * (g[0] - g[m]) + np.sum(i * (2.0 * g[m - i] - g[i] - g[2 * m - i]))) / m**2)


def av_quadratic_form(acvf: np.ndarray, m: int) -> float:
    """AV(m) straight from [AV-chapter] Definition 4.2: half the variance of w'X with
    w = (1, ..., 1, -1, ..., -1) / m (2m taps), i.e. (1/2) sum_h gamma(h) c(h), c the
    autocorrelation sequence of w. Independent of Lemma 4.2 (no summation by parts)."""
    m = int(m)
    g = np.asarray(acvf, dtype=float)
    w = np.r_[np.ones(m), -np.ones(m)] / m
    c = np.correlate(w, w, "full")  # lags -(2m-1) .. 2m-1
    lags = np.abs(np.arange(-(2 * m - 1), 2 * m))
    return float(0.5 * np.sum(c * g[lags]))


def _gauss_panels(edges: np.ndarray, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre abscissae and weights on every panel [edges[k], edges[k+1]]."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    a, b = edges[:-1, None], edges[1:, None]
    return (a + b) / 2 + (b - a) / 2 * x, (b - a) / 2 * w


def av_spectral(spectrum: Callable[[np.ndarray], np.ndarray], m: int, nodes: int = 32) -> float:
    """AV(m) of a discrete-time stationary series from its two-sided spectral density S(f) on
    [-1/2, 1/2] (cycles/sample): AV(m) = 4 int_0^{1/2} S(f) sin^4(pi f m) / (m sin(pi f))^2 df.

    This is the discrete-time form of [AV-chapter] Lemma 4.1 (whose kernel (pi f tau)^2 is the
    continuous-time one): the AV filter w of :func:`av_quadratic_form` has squared gain
    4 sin^4(pi f m) / (m sin(pi f))^2. The kernel has m humps on (0, 1/2]; each hump is one
    Gauss-Legendre panel, the first one refined geometrically towards f = 0 for peaked spectra."""
    m = int(m)
    edges = np.arange(m + 1) / (2.0 * m)
    edges = np.unique(np.r_[0.0, edges[1] * np.geomspace(1e-9, 1.0, 40), edges[1:]])
    f, w = _gauss_panels(edges, nodes)
    kern = np.sin(np.pi * f * m) ** 4 / (m * np.sin(np.pi * f)) ** 2
    return float(4.0 * np.sum(w * spectrum(f) * kern))


def av_continuous(spectrum_x: Callable[[np.ndarray], np.ndarray], tau: float, *,
                  K: float = 2000.0, tail_mean: Callable[[float], float] | None = None,
                  nodes: int = 24, u_min: float = -45.0) -> float:
    """[AV-chapter] Lemma 4.1 in continuous time, AV(tau) = 4 int_0^inf S(f) sin^4(pi f tau) /
    (pi f tau)^2 df, written in x = f tau: 4/tau int_0^inf S(x/tau) sin^4(pi x)/(pi x)^2 dx.

    ``spectrum_x(x)`` must return S(x / tau) / tau (the caller folds tau in). Quadrature: x in
    (0, 1] on panels of width 1/4 in log2 x (from 2**u_min), x in [1, K] on panels of width 1/2
    (the period of sin^4), and the tail x > K, where sin^4 averages 3/8, from ``tail_mean(K)``
    = int_K^inf spectrum_x(x) / (pi x)^2 dx (its oscillating remainder is O(K^-4))."""
    u, wu = _gauss_panels(np.arange(u_min, 1e-12, 0.25), nodes)
    x1 = 2.0**u
    i1 = np.sum(wu * math.log(2.0) * x1 * spectrum_x(x1) * np.sin(np.pi * x1) ** 4
                / (np.pi * x1) ** 2)
    x2, w2 = _gauss_panels(np.arange(1.0, K + 1e-9, 0.5), nodes)
    i2 = np.sum(w2 * spectrum_x(x2) * np.sin(np.pi * x2) ** 4 / (np.pi * x2) ** 2)
    tail = 0.375 * tail_mean(K) if tail_mean is not None else 0.0
    return float(4.0 * (i1 + i2 + tail))


# --- MA(1) (Example 4.2) and ARMA(1,1) (Lemma 4.2) ------------------------------------------------


def ma1_acvf(theta: float, sigma2: float, hmax: int) -> np.ndarray:
    """gamma(0..hmax) of X_t = Z_t + theta Z_{t-1}, Var Z = sigma2."""
    g = np.zeros(int(hmax) + 1)
    g[0] = sigma2 * (1.0 + theta**2)
    if hmax >= 1:
        g[1] = sigma2 * theta
    return g


def ma1_av(theta: float, sigma2: float, m: Any) -> np.ndarray:
    """[AV-chapter] Example 4.2: AV(m) = sigma2 [(1 + theta^2) m + (2m - 3) theta] / m^2, valid
    for every cluster m >= 1. Derived independently from Definition 4.2: the difference of the
    two m-means is (Z_k + (1+theta) sum_{i=1}^{m-1} Z_{k-i} + (theta-1) Z_{k-m}
    - (1+theta) sum_{i=m+1}^{2m-1} Z_{k-i} - theta Z_{k-2m}) / m, whose variance is
    sigma2 [2 + 2 theta^2 - 2 theta + 2 (m-1) (1+theta)^2] / m^2; half of it is the formula."""
    m = np.asarray(m, dtype=float)
    return sigma2 * ((1.0 + theta**2) * m + (2.0 * m - 3.0) * theta) / m**2


def ma1_as_qn_wn(theta: float, sigma2: float) -> dict[str, float] | None:
    """For theta < 0 an MA(1) has the second moments of QN + WN (docs/METHODS.md §3.2-3.3):
    QN autocovariance (2 Q^2, -Q^2) gives Q^2 = -theta sigma2, WN = sigma2 (1 + theta)^2.
    None for theta >= 0 (a positive lag-1 covariance is not a QN)."""
    if theta >= 0:
        return None
    return {"QN[1].Q2": -theta * sigma2, "WN[1].sigma2": sigma2 * (1.0 + theta) ** 2}


def arma11_acvf(phi: float, theta: float, sigma2: float, hmax: int) -> np.ndarray:
    """gamma(0..hmax) of X_t = phi X_{t-1} + Z_t + theta Z_{t-1} (|phi| < 1), Var Z = sigma2:
    gamma(0) = sigma2 (1 + 2 phi theta + theta^2) / (1 - phi^2),
    gamma(1) = sigma2 (1 + phi theta)(phi + theta) / (1 - phi^2), gamma(h) = phi^(h-1) gamma(1)."""
    h = np.arange(int(hmax) + 1)
    g = np.empty(h.size)
    g[0] = sigma2 * (1.0 + 2.0 * phi * theta + theta**2) / (1.0 - phi**2)
    g1 = sigma2 * (1.0 + phi * theta) * (phi + theta) / (1.0 - phi**2)
    g[1:] = g1 * float(phi) ** (h[1:] - 1)
    return g


def arma11_spectrum(phi: float, theta: float, sigma2: float) -> Callable[[np.ndarray], np.ndarray]:
    """Two-sided spectral density S(f) = sigma2 |1 + theta e^{-2 pi i f}|^2 /
    |1 - phi e^{-2 pi i f}|^2 on [-1/2, 1/2] (cycles/sample)."""
    def spec(f: np.ndarray) -> np.ndarray:
        c = np.cos(2.0 * np.pi * f)
        return sigma2 * (1.0 + 2.0 * theta * c + theta**2) / (1.0 - 2.0 * phi * c + phi**2)
    return spec


def arma11_as_wn_ar1(phi: float, theta: float, sigma2: float) -> dict[str, float] | None:
    """The WN + AR1 model with the second moments of an ARMA(1,1), when one exists: matching
    sigma2 |1 + theta z|^2 = nu2 + s2 |1 - phi z|^2 on the unit circle gives the WN variance
    s2 = -sigma2 theta / phi and the AR1 innovation variance
    nu2 = sigma2 (phi + theta)(1 + phi theta) / phi; both positive iff theta / phi < 0 and
    (phi + theta)(1 + phi theta) / phi > 0. (So [AV-chapter] Example 4.1's WN + AR1 is an ARMA(1,1).)"""
    if phi == 0 or theta == 0:
        return None
    s2 = -sigma2 * theta / phi
    nu2 = sigma2 * (phi + theta) * (1.0 + phi * theta) / phi
    if s2 <= 0 or nu2 <= 0:
        return None
    return {"WN[1].sigma2": s2, "AR1[1].phi": phi, "AR1[1].sigma2": nu2}


def ma_coefficients(acvf: Sequence[float]) -> np.ndarray:
    """MA(q) coefficients b_0..b_q with sum_j b_j b_{j+k} = acvf[k] (spectral factorisation,
    Fejer-Riesz), for an autocovariance whose spectrum is strictly positive: the roots of
    z^q sum_k acvf[|k|] z^k inside the unit circle are kept."""
    c = np.asarray(acvf, dtype=float)
    q = c.size - 1
    if q == 0:
        return np.sqrt(c[:1])
    roots = np.roots(np.r_[c[::-1], c[1:]])
    inside = roots[np.abs(roots) < 1.0]
    if inside.size != q:
        raise InputError("spectral factorisation needs a strictly positive spectrum")
    b = np.real(np.poly(inside))[::-1]  # b(z) = prod (1 - r z) up to scale, ascending powers
    b *= math.sqrt(c[0] / float(b @ b))
    return b


def _simulate_ma(b: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    z = rng.standard_normal(n + b.size - 1)
    return np.convolve(z, b, mode="valid")


# ==================================================================================================
# Item: Figs 4.1 and 4.2 (Allan deviation of WN and WN + RW)
# ==================================================================================================


def _av_true(which: str, m: np.ndarray) -> dict[str, np.ndarray]:
    """Theoretical AV lines: the chapter's (Sec. 4.4.1) and the exact one (§9.1, §14)."""
    _, p = _FIGS[which]
    wn = p["WN[1].sigma2"] / m
    if which == "fig41":
        return {"chapter": wn, "exact": wn}
    g2 = p["RW[1].gamma2"]
    return {"chapter": wn + g2 * m / 3.0, "exact": wn + g2 * (m / 3.0 + 1.0 / (6.0 * m)),
            "WN": wn, "RW": g2 * m / 3.0}


def _slope(m: np.ndarray, av: np.ndarray, sel: np.ndarray) -> float:
    """Least-squares slope of log AD on log m over the selected clusters."""
    return float(np.polyfit(np.log(m[sel]), 0.5 * np.log(av[sel]), 1)[0])


def _slope_sets(which: str, m: np.ndarray) -> dict[str, np.ndarray]:
    """Clusters each log-AD slope is read on: all of them for WN alone; for WN + RW, m <= 32 for
    the WN (below the crossover m* = sqrt(3 sigma^2 / gamma^2) ~ 577; at m = 32 the RW adds 1 %)
    and the three longest for the RW."""
    if which == "fig41":
        return {"slope_all": np.ones(m.size, bool)}
    return {"slope_wn": m <= 32, "slope_rw": np.arange(m.size) >= m.size - 3}


@dataclass
class AdevResult:
    """Outcome of :func:`adev_study` for one figure: replicate 0 (drawn) and the replicate table."""

    which: str
    av: Any  # gmwm.wv.AllanVariance of replicate 0
    readings: dict[str, dict]
    fit: Any  # GMWMResult of replicate 0
    replicates: pd.DataFrame  # one row per replicate
    summary: pd.DataFrame  # one row per quantity: truth, replicate 0, MC mean / SD
    # per replicate: the readings' 95 % intervals (N_ci_low, N_ci_high, K_ci_low, K_ci_high)
    reading_cis: pd.DataFrame | None = None


def adev_study(which: str, n_samples: int = 100_000, replicates: int = 100, seed: int = 0
               ) -> AdevResult:
    """[AV-chapter] Fig. 4.1 (``which="fig41"``) or Fig. 4.2 (``"fig42"``): per replicate the
    maximal-overlap AV, the IEEE 952 readings N (slope -1/2 at 1 s) and K (slope +1/2 at 3 s),
    least-squares slopes of log AD where one term dominates, and the GMWM fit of the true model."""
    if which not in _FIGS:
        raise InputError(f"which must be one of {sorted(_FIGS)}, got {which!r}")
    model_str, truth = _FIGS[which]
    model = gmwm.Model(model_str)
    theta = model.theta(truth)
    rows, cis, first = [], [], None
    for r in range(int(replicates)):
        x = model.simulate(theta, n_samples, rng=_rng(which, n_samples, r, seed))
        wv = wvar(x)
        av = AllanVariance.from_wv(wv)
        m = av.clusters.astype(float)
        rd = allan_readings(av)
        fit = gmwm.fit(wv, model, seed=replicate_seed(f"allan/{which}", n_samples, r, seed))
        row = {"replicate": r, "N": rd["N"].get("value"), "K": rd["K"].get("value")}
        cis.append({"replicate": r, **{f"{k}_ci_{end}": (rd[k].get("ci95") or [np.nan] * 2)[i]
                                      for k in ("N", "K") for i, end in enumerate(("low", "high"))}})
        row |= {q: _slope(m, av.avar, s) for q, s in _slope_sets(which, m).items()}
        row |= {f"gmwm_{k}": v for k, v in fit.as_dict().items()}
        rows.append(row)
        if r == 0:
            first = (av, rd, fit)
    table = pd.DataFrame(rows)
    # a slope's estimand is the least-squares slope of the exact log AD over the clusters it is
    # read on (e.g. 0.493, not 1/2, on Fig 4.2's three longest, where the WN still adds); the
    # chapter's +-1/2 is kept as ``nominal``
    exact = _av_true(which, m)["exact"]
    nominal = {"slope_all": -0.5, "slope_wn": -0.5, "slope_rw": 0.5}
    truth_of = {"N": math.sqrt(truth["WN[1].sigma2"]), "K": math.sqrt(truth.get("RW[1].gamma2",
                                                                                 np.nan))}
    truth_of |= {q: _slope(m, exact, s) for q, s in _slope_sets(which, m).items()}
    truth_of |= {f"gmwm_{k}": v for k, v in truth.items()}
    summary = pd.DataFrame([
        {"figure": which, "quantity": q, "truth": truth_of.get(q, np.nan),
         "nominal": nominal.get(q, np.nan),
         "replicate0": float(table[q].iloc[0]) if table[q].notna().iloc[0] else np.nan,
         "mc_mean": float(table[q].mean()), "mc_sd": float(table[q].std(ddof=1)),
         "n_read": int(table[q].notna().sum()), "replicates": len(table)}
        for q in table.columns if q != "replicate"
        if not (which == "fig41" and q == "K")])
    av0, rd0, fit0 = first
    return AdevResult(which, av0, rd0, fit0, table, summary, pd.DataFrame(cis, dtype=float))


def adev_replicates(results: Sequence[AdevResult]) -> pd.DataFrame:
    """Per-replicate table of Figs 4.1-4.2 (``reports/allan/replicates/readings.csv``): figure,
    replicate, the IEEE 952 readings N and K (empty where not read) with their 95 % intervals,
    the slopes and the GMWM estimates (columns of :attr:`AdevResult.replicates`)."""
    out = []
    for res in results:
        t = res.replicates.copy()
        if res.reading_cis is not None:
            cis = res.reading_cis.drop(columns="replicate")
            for c in cis.columns:
                t.insert(t.columns.get_loc(c.split("_")[0]) + 1 + c.endswith("high"), c,
                         cis[c].to_numpy())
        t.insert(0, "figure", res.which)
        out.append(t)
    return pd.concat(out, ignore_index=True)


def readings_table(res: AdevResult) -> pd.DataFrame:
    """The IEEE 952 readings of replicate 0 (:func:`gmwm.datasheet.allan_readings`) next to the
    truth: N = sigma (slope -1/2 line at 1 s), K = gamma (slope +1/2 line at 3 s), B (AD minimum
    / 0.6643; the models have no bias instability, so B is the floor the record reaches)."""
    _, truth = _FIGS[res.which]
    ref = {"N": math.sqrt(truth["WN[1].sigma2"]),
           "K": math.sqrt(truth["RW[1].gamma2"]) if "RW[1].gamma2" in truth else np.nan,
           "B": np.nan}
    rows = []
    for key in ("N", "K", "B"):
        r = res.readings[key]
        ci = r.get("ci95") or [np.nan, np.nan]
        span = r.get("tau_range_s") or [np.nan, np.nan]
        rows.append({"figure": res.which, "reading": key, "truth": ref[key],
                     "value": np.nan if r.get("value") is None else float(r["value"]),
                     "ci_low": float(ci[0]), "ci_high": float(ci[1]),
                     "tau_from": float(span[0]), "tau_to": float(span[1]),
                     "extrapolated": bool(r.get("extrapolated", False)),
                     "at_end": bool(r.get("at_end", False)),
                     "note": r.get("note", "")})
    return pd.DataFrame(rows)


# ==================================================================================================
# Item: Example 4.2 (AV of an MA(1))
# ==================================================================================================


def ma1_study(thetas: Sequence[float] = (-0.5, 0.5), sigma2: float = 1.0,
              n_samples: int = 65536, replicates: int = 200, seed: int = 0, levels: int = 12
              ) -> pd.DataFrame:
    """Example 4.2 at clusters m = 1, 2, ..., 2**(levels-1): the chapter's closed form, Lemma 4.2
    on the MA(1) autocovariance, the project's exact QN + WN model (theta < 0 only) and the mean
    maximal-overlap AV of ``replicates`` simulated series with its Monte Carlo SE."""
    rows = []
    m = _clusters(levels)
    for theta in thetas:
        b = np.array([1.0, theta]) * math.sqrt(sigma2)
        sims = np.stack([2.0 * wvar_many(
            _simulate_ma(b, n_samples, _rng(f"ma1/{theta:g}", n_samples, r, seed))[None, :],
            levels)[0] for r in range(int(replicates))])
        mean, se = sims.mean(axis=0), sims.std(axis=0, ddof=1) / math.sqrt(sims.shape[0])
        qn = ma1_as_qn_wn(theta, sigma2)
        proj = model_av("QN+WN", qn, m) if qn else np.full(m.size, np.nan)
        closed = ma1_av(theta, sigma2, m)
        for k, mk in enumerate(m):
            lemma = av_from_acvf(ma1_acvf(theta, sigma2, 2 * mk), mk)
            rows.append({"theta": theta, "m": int(mk), "chapter": closed[k], "lemma42": lemma,
                         "project_model": proj[k], "simulated": mean[k], "mc_se": se[k],
                         "z": (mean[k] - closed[k]) / se[k],
                         "rel_lemma": abs(lemma / closed[k] - 1.0),
                         "rel_model": abs(proj[k] / closed[k] - 1.0)})
    return pd.DataFrame(rows)


# ==================================================================================================
# Item: Lemma 4.2 against the exact AV of an ARMA(1,1)
# ==================================================================================================


def lemma42_study(pairs: Sequence[Sequence[float]] = ((0.9, -0.5), (0.9, 0.5), (-0.6, 0.3),
                                                      (0.99, 0.0)),
                  sigma2: float = 1.0, levels: int = 15, quadform_max: int = 1024
                  ) -> pd.DataFrame:
    """For each ARMA(1,1) (phi, theta) and cluster m = 1..2**(levels-1): Lemma 4.2 on the closed-form
    autocovariance, the spectral integral :func:`av_spectral`, the quadratic form of
    Definition 4.2 (m <= ``quadform_max``) and the project's exact WN + AR1 (or AR1) model where
    the ARMA(1,1) is one (:func:`arma11_as_wn_ar1`); relative differences to the lemma."""
    rows = []
    for phi, theta in pairs:
        spec = arma11_spectrum(phi, theta, sigma2)
        if theta == 0:
            equiv, mstr = {"AR1[1].phi": phi, "AR1[1].sigma2": sigma2}, "AR1"
        else:
            equiv, mstr = arma11_as_wn_ar1(phi, theta, sigma2), "WN+AR1"
        for mk in _clusters(levels):
            g = arma11_acvf(phi, theta, sigma2, 2 * mk)
            lemma = av_from_acvf(g, mk)
            quad = av_spectral(spec, mk)
            qf = av_quadratic_form(g, mk) if mk <= quadform_max else np.nan
            proj = float(model_av(mstr, equiv, mk)[0]) if equiv else np.nan
            rows.append({"phi": phi, "theta": theta, "m": int(mk), "lemma42": lemma,
                         "spectral": quad, "quadratic_form": qf, "project_model": proj,
                         "rel_spectral": abs(quad / lemma - 1.0),
                         "rel_quadratic_form": abs(qf / lemma - 1.0),
                         "rel_project_model": abs(proj / lemma - 1.0)})
    return pd.DataFrame(rows)


# ==================================================================================================
# Item: Sec. 4.2.2 (spectral ambiguity)
# ==================================================================================================


def _flicker_pair(h: float, eps: float, base: float = 2.0
                  ) -> Callable[[float, float], Callable[[np.ndarray], np.ndarray]]:
    """Continuous-time spectra S(f) = h (1 + s eps cos(2 pi log_base f)) / f, s = +-1. With
    base = 2 the difference Phi = 2 h eps cos(2 pi log2 f) / f satisfies Phi(f) = 2 Phi(2f)
    ([AV-chapter] Sec. 4.2.2) and has zero mean over each octave."""
    def at(tau: float, sign: float) -> Callable[[np.ndarray], np.ndarray]:
        c = math.log(tau, base)
        # S(x / tau) / tau = h (1 + s eps cos(2 pi (log_b x - log_b tau))) / x
        return lambda x: h * (1.0 + sign * eps * np.cos(2.0 * np.pi * (np.log(x) / math.log(base)
                                                                       - c))) / x
    return at


def _flicker_tail(h: float, eps: float, sign: float, tau: float, base: float
                  ) -> Callable[[float], float]:
    """int_K^inf h (1 + s eps cos(a ln x - b)) / x / (pi x)^2 dx in closed form,
    a = 2 pi / ln base, b = 2 pi log_base tau."""
    a, b = 2.0 * np.pi / math.log(base), 2.0 * np.pi * math.log(tau, base)

    def tail(K: float) -> float:
        osc = np.real(np.exp(1j * (a * math.log(K) - b)) / (K**2 * (2.0 - 1j * a)))
        return h / np.pi**2 * (1.0 / (2.0 * K**2) + sign * eps * float(osc))
    return tail


def flicker_av(tau: float, h: float, eps: float, sign: float, base: float = 2.0) -> float:
    """AV(tau) of the continuous-time spectrum h (1 + sign eps cos(2 pi log_base f)) / f by
    :func:`av_continuous`. For eps = 0 it is the flicker-noise AV 4 h ln 2."""
    spec = _flicker_pair(h, eps, base)(tau, sign)
    return av_continuous(spec, tau, tail_mean=_flicker_tail(h, eps, sign, tau, base))


#: Discrete-time autocovariance difference (lags 0..4) with zero AV at every dyadic cluster (and,
#: by the m >= 5 formula, at every cluster but m = 3):
#: the null space of Lemma 4.2 at m = 1, 2, 4 and of m M0 - 3 M1 (all m >= 5; M0 = sum_h d(h),
#: M1 = sum_{k>0} k d(k)) contains d = (0, 0, 1, -2, 1), spectrum -8 cos(6 pi f) sin^2(pi f).
DYADIC_NULL = np.array([0.0, 0.0, 1.0, -2.0, 1.0])


def dyadic_pair_acvf(sigma2: float, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Autocovariances (lags 0..4) of the two MA(4) processes sigma2 +- eps d(h) of
    :data:`DYADIC_NULL` (both spectra sigma2 -+ 8 eps cos(6 pi f) sin^2(pi f) > 0 for
    |eps| < sigma2 / 8)."""
    if not 0 < 8.0 * abs(eps) < sigma2:
        raise InputError(f"need 0 < 8 |eps| < sigma2 for two positive spectra, got eps = {eps}")
    base = np.zeros(5)
    base[0] = sigma2
    return base + eps * DYADIC_NULL, base - eps * DYADIC_NULL


@dataclass
class AmbiguityResult:
    """Outcome of :func:`ambiguity_study` (tables and the curves the figure draws)."""

    table: pd.DataFrame  # one row per (construction, tau or m)
    summary: dict[str, float]
    curves: dict[str, Any]


def ambiguity_study(h: float = 1.0, eps: float = 0.5, dyadic_sigma2: float = 1.0,
                    dyadic_eps: float = 0.1, levels: int = 12, n_samples: int = 16384,
                    replicates: int = 100, seed: int = 0) -> AmbiguityResult:
    """[AV-chapter] Sec. 4.2.2. (a) Continuous time: S_+- = h (1 +- eps cos(2 pi log2 f)) / f
    (difference Phi(f) = 2 Phi(2f)), AV by quadrature at dyadic tau = 2**-8 .. 2**(levels+4) and
    at non-dyadic tau; a control pair with period log3 instead (Phi(f) = 3 Phi(3f)) shows the
    AV difference the condition removes. (b) Discrete time: two MA(4) processes with
    autocovariances sigma2 +- eps d, d = :data:`DYADIC_NULL`, AV by Lemma 4.2 at every cluster
    m = 1..2**(levels-1) (equal exactly at every dyadic m and, the support being 4 lags, at every
    m >= 5: they differ at m = 3 only), plus the mean
    simulated AV of ``replicates`` series of each."""
    rows = []
    pair = {"chapter_2phi2f": 2.0, "control_3phi3f": 3.0}
    dy_taus = 2.0 ** np.arange(-8, levels + 5)
    other_taus = np.r_[3.0 * 2.0 ** np.arange(-4, levels), 1.37, 10.0, 1000.0]
    for name, base in pair.items():
        for tau in np.r_[dy_taus, other_taus]:
            p, q = (flicker_av(float(tau), h, eps, s, base) for s in (1.0, -1.0))
            rows.append({"construction": name, "scale": float(tau),
                         "dyadic": bool(np.log2(tau) == np.round(np.log2(tau))),
                         "av_x": p, "av_y": q, "rel_diff": abs(p / q - 1.0)})
    acv_x, acv_y = dyadic_pair_acvf(dyadic_sigma2, dyadic_eps)
    mmax = 2 ** (levels - 1)
    ms = np.arange(1, mmax + 1)
    pad = np.zeros(2 * mmax)
    av_x = np.array([av_from_acvf(np.r_[acv_x, pad][:2 * k], k) for k in ms])
    av_y = np.array([av_from_acvf(np.r_[acv_y, pad][:2 * k], k) for k in ms])
    for k, (p, q) in enumerate(zip(av_x, av_y, strict=True)):
        m = int(ms[k])
        rows.append({"construction": "discrete_ma4", "scale": float(m),
                     "dyadic": bool(m & (m - 1) == 0), "av_x": p, "av_y": q,
                     "rel_diff": abs(p / q - 1.0)})
    table = pd.DataFrame(rows)
    # simulation of the discrete pair: mean maximal-overlap AV over replicates (both)
    sims = {}
    sim_levels = min(int(levels), int(math.log2(n_samples)) - 1)
    for tag, acv in (("x", acv_x), ("y", acv_y)):
        b = ma_coefficients(acv)
        sims[tag] = np.stack([2.0 * wvar_many(_simulate_ma(
            b, n_samples, _rng(f"ambiguity/{tag}", n_samples, r, seed))[None, :], sim_levels)[0]
            for r in range(int(replicates))])
    dy = _clusters(levels)
    diff = sims["x"] - sims["y"]
    z = diff.mean(axis=0) / (diff.std(axis=0, ddof=1) / math.sqrt(diff.shape[0]))
    f = np.linspace(1e-4, 0.5, 2000)
    phi_d = -8.0 * np.cos(6 * np.pi * f) * np.sin(np.pi * f) ** 2
    summary = {}
    for name in pair:
        t = table[table.construction == name]
        summary[f"{name}_max_rel_diff_dyadic"] = float(t[t.dyadic].rel_diff.max())
        summary[f"{name}_max_rel_diff_nondyadic"] = float(t[~t.dyadic].rel_diff.max())
    t = table[table.construction == "discrete_ma4"]
    summary |= {
        "flicker_av_expected": 4.0 * h * math.log(2.0),
        "chapter_max_rel_err_vs_4hln2": float(np.max(np.abs(
            table[table.construction == "chapter_2phi2f"][["av_x", "av_y"]].to_numpy()
            / (4.0 * h * math.log(2.0)) - 1.0))),
        "chapter_max_rel_spectrum_diff": 2.0 * eps / (1.0 - eps),
        "discrete_max_rel_diff_dyadic": float(t[t.dyadic].rel_diff.max()),
        "discrete_max_rel_diff_nondyadic": float(t[~t.dyadic].rel_diff.max()),
        "discrete_max_abs_spectrum_diff": float(2.0 * dyadic_eps * np.max(np.abs(phi_d))),
        "discrete_spectrum_diff_bound": 16.0 * dyadic_eps,
        "discrete_sim_max_abs_z_dyadic": float(np.max(np.abs(z))),
        "discrete_sim_replicates": int(replicates),
        "discrete_sim_n_samples": int(n_samples),
    }
    curves = {
        "f_cont": np.geomspace(2.0**-10, 2.0**6, 800),
        "h": h, "eps": eps,
        "f_disc": f, "spec_disc_x": dyadic_sigma2 + dyadic_eps * phi_d,
        "spec_disc_y": dyadic_sigma2 - dyadic_eps * phi_d,
        "m_all": ms, "av_disc_x": av_x, "av_disc_y": av_y,
        "m_dyadic": dy, "sim_x": sims["x"].mean(axis=0), "sim_y": sims["y"].mean(axis=0),
    }
    return AmbiguityResult(table, summary, curves)


# ==================================================================================================
# Item: Remark 4.3 (Gaussian AV intervals below 0)
# ==================================================================================================


def interval_kinds() -> tuple[str, ...]:
    """The WV interval kinds of this checkout's ``gmwm.wvar``: the eta_3 chi-square interval
    (docs/METHODS.md §2.5) and any calibrated kind (§2.6) the library offers (``gmwm.wvci``)."""
    try:
        from gmwm.wvci import CI_KINDS  # calibrated WV intervals, when this checkout has them
    except ImportError:
        return ("eta3",)
    return tuple(CI_KINDS)


def _wv_kind(x: np.ndarray, kind: str, levels: int | None = None) -> Any:
    if "ci" in inspect.signature(wvar).parameters:
        return wvar(x, levels, ci=kind)
    if kind != "eta3":
        raise InputError(f"interval kind {kind!r} is not offered by this gmwm.wvar")
    return wvar(x, levels)


def bartlett_lrv(y: np.ndarray, b: int) -> float:
    """Long-run variance of ``y`` with the Bartlett kernel of bandwidth ``b``, estimated as the
    overlapping-batch-means variance: Var(sum of b consecutive y) / b = sum_{|k|<b} (1 - |k|/b)
    gamma_y(k) (Newey-West weights), O(n) by cumulative sums."""
    n = y.size
    b = int(min(max(b, 1), n))
    yc = y - y.mean()
    s = np.r_[0.0, np.cumsum(yc)]
    blocks = s[b:] - s[:-b]
    return float(np.mean(blocks**2) / b)


def interval_study(n_samples: int = 100_000, replicates: int = 200, seed: int = 0,
                   alpha: float = 0.05, lrv_bandwidth: int = 1
                   ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Remark 4.3 on the Fig. 4.2 model (WN + RW): per cluster, over ``replicates`` series,
    the share of intervals whose lower bound is <= 0 and the coverage of the exact AV, for
    * ``gaussian_exact``: AV_hat -+ z SD, SD the exact standard deviation of AV_hat under the true
      model (docs/METHODS.md §4, :func:`gmwm.wvcov.wv_covariance`): the chapter's Sec. 4.3.3
      interval with the long-run variance known, so its failures are the normal shape's own;
    * ``gaussian_eta3``: AV_hat (1 -+ z sqrt(2 / eta_j)), the Gaussian interval with the
      project's Gaussian variance (docs/METHODS.md eq. 2.3);
    * ``gaussian_lrv``: AV_hat -+ z sqrt(LRV / M_j), the chapter's Sec. 4.3.3 interval with a
      Bartlett long-run variance of the squared differences, bandwidth ``lrv_bandwidth`` times
      the filter length 2m (for WN + RW the squared differences are independent beyond 2m - 1
      lags, so Bartlett weights >= 1 - 1/lrv_bandwidth cover their whole dependence);
    * each chi-square kind of :func:`interval_kinds` (twice the WV interval).
    Returns the table and replicate 0's intervals (for the figure), whose key ``replicates``
    holds every replicate's intervals (replicate, m, true_av, ``<kind>_low``, ``<kind>_high``;
    ``reports/allan/replicates/intervals.csv``)."""
    if not 0 < alpha < 1:
        raise InputError(f"alpha must be in (0, 1), got {alpha}")
    from scipy.special import ndtri

    z = float(ndtri(1.0 - alpha / 2.0))
    model = gmwm.Model("WN+RW")
    theta = model.theta(FIG42)
    kinds = interval_kinds()
    types = ["gaussian_exact", "gaussian_eta3", "gaussian_lrv", *kinds]
    sd_exact = None
    lows, highs, first = {t: [] for t in types}, {t: [] for t in types}, None
    for r in range(int(replicates)):
        x = model.simulate(theta, n_samples, rng=_rng("intervals", n_samples, r, seed))
        wv = _wv_kind(x, kinds[0])
        J = wv.n_levels
        av = 2.0 * wv.variance
        eta = np.maximum(wv.n / wv.scales, 1.0)
        if sd_exact is None:  # exact SD of AV_hat = 2 nu_hat under the true model (§4)
            from gmwm.wvcov import wv_covariance

            sd_exact = 2.0 * np.sqrt(np.diag(wv_covariance(model, theta, wv.scales, n_samples)))
        lows["gaussian_exact"].append(av - z * sd_exact)
        highs["gaussian_exact"].append(av + z * sd_exact)
        se = av * np.sqrt(2.0 / eta)
        lows["gaussian_eta3"].append(av - z * se)
        highs["gaussian_eta3"].append(av + z * se)
        lrv_se = np.empty(J)
        for j, w in haar_levels(x, J):
            y = 2.0 * w**2  # mean(y) = AV_hat at m = 2**(j-1)
            lrv_se[j - 1] = math.sqrt(bartlett_lrv(y, lrv_bandwidth * 2**j) / y.size)
        lows["gaussian_lrv"].append(av - z * lrv_se)
        highs["gaussian_lrv"].append(av + z * lrv_se)
        for k, kind in enumerate(kinds):
            w = wv if k == 0 else _wv_kind(x, kind)
            lows[kind].append(2.0 * w.ci_low)
            highs[kind].append(2.0 * w.ci_high)
        if r == 0:
            first = {"m": wv.scales / 2.0, "av": av,
                     "low": {t: lows[t][0] for t in types}, "high": {t: highs[t][0] for t in types},
                     "eta": eta}
    m = first["m"]
    true = model_av(model, FIG42, m)
    n_rep = len(lows[types[0]])
    per = {"replicate": np.repeat(np.arange(n_rep), m.size), "m": np.tile(m.astype(int), n_rep),
           "true_av": np.tile(true, n_rep)}
    for t in types:
        per[f"{t}_low"] = np.concatenate(lows[t])
        per[f"{t}_high"] = np.concatenate(highs[t])
    first["replicates"] = pd.DataFrame(per)
    rows = []
    for t in types:
        lo, hi = np.array(lows[t]), np.array(highs[t])
        for j, mj in enumerate(m):
            rows.append({"interval": t, "m": int(mj), "eta": float(first["eta"][j]),
                         "true_av": float(true[j]),
                         "share_low_le_0": float(np.mean(lo[:, j] <= 0.0)),
                         "coverage": float(np.mean((lo[:, j] <= true[j]) & (true[j] <= hi[:, j]))),
                         "replicates": int(lo.shape[0])})
    first["true"] = true
    return pd.DataFrame(rows), first


# ==================================================================================================
# Item: Example 4.1 (MLE of WN + AR1)
# ==================================================================================================


@njit(cache=True)
def _wn_ar1_filter(x: np.ndarray, phi: float, ratio: float) -> tuple[float, float]:
    """Kalman filter of x_t = c_t + e_t, c_t = phi c_{t-1} + w_t (stationary start), with
    Var e = 1 and Var w = ratio: returns (sum v_t^2 / F_t, sum log F_t). Once the Riccati
    recursion has converged the gain is frozen (same numbers to rounding)."""
    n = x.size
    p = ratio / (1.0 - phi * phi)
    a = 0.0
    ssum = 0.0
    lsum = 0.0
    t = 0
    while t < n:
        f = p + 1.0
        v = x[t] - a
        ssum += v * v / f
        lsum += math.log(f)
        k = p / f
        a = phi * (a + k * v)
        p_new = phi * phi * p * (1.0 - k) + ratio
        t += 1
        if abs(p_new - p) <= 1e-15 * p:
            p = p_new
            break
        p = p_new
    f = p + 1.0
    k = p / f
    logf = math.log(f)
    while t < n:
        v = x[t] - a
        ssum += v * v / f
        lsum += logf
        a = phi * (a + k * v)
        t += 1
    return ssum, lsum


def wn_ar1_loglike(x: np.ndarray, phi: float, nu2: float, sigma2: float) -> float:
    """Exact Gaussian log-likelihood of [AV-chapter] Example 4.1 (WN sigma2 + AR1 (phi, nu2),
    stationary start), by the Kalman filter: -(1/2) (T log 2 pi + log det Sigma + x' Sigma^-1 x)."""
    x = np.ascontiguousarray(x, dtype=float)
    s, lf = _wn_ar1_filter(x, float(phi), float(nu2 / sigma2))
    n = x.size
    return float(-0.5 * (n * math.log(2 * math.pi) + n * math.log(sigma2) + lf + s / sigma2))


def wn_ar1_loglike_dense(x: np.ndarray, phi: float, nu2: float, sigma2: float) -> float:
    """The same log-likelihood from the chapter's T x T covariance
    Sigma = nu2 / (1 - phi^2) [phi^|i-j|] + sigma2 I by a Cholesky factorisation (O(T^3) time,
    8 T^2 bytes)."""
    from scipy.linalg import cho_factor, cho_solve, toeplitz

    x = np.asarray(x, dtype=float)
    n = x.size
    sig = toeplitz(nu2 / (1.0 - phi**2) * phi ** np.arange(n))
    sig[np.diag_indices(n)] += sigma2
    c = cho_factor(sig, lower=True, overwrite_a=True, check_finite=False)
    quad = float(x @ cho_solve(c, x, check_finite=False))
    logdet = 2.0 * float(np.sum(np.log(np.diag(c[0]))))
    return -0.5 * (n * math.log(2 * math.pi) + logdet + quad)


_PHI_BOUND = 0.9999  # |phi| at or beyond: boundary solution
_VAR_REL_BOUND = 1e-6  # a variance below this times Var(x): boundary solution
_ETA_BOX = (math.atanh(0.999999), 30.0)  # search box of (atanh phi, log(nu2 / sigma2))


@dataclass
class MLEFit:
    """Outcome of :func:`fit_wn_ar1_mle`: estimates, exact log-likelihood, status, CPU seconds."""

    params: dict[str, float]
    loglike: float
    converged: bool
    boundary: bool
    message: str
    seconds: float
    nfev: int


def _profile(x: np.ndarray, eta: np.ndarray) -> tuple[float, float]:
    """Profile log-likelihood (sigma2 concentrated out) and sigma2_hat at eta = (atanh phi,
    log ratio)."""
    n = x.size
    s, lf = _wn_ar1_filter(x, math.tanh(eta[0]), math.exp(eta[1]))
    s2 = s / n
    return -0.5 * (n * math.log(2 * math.pi) + n + n * math.log(s2) + lf), s2


def moment_start(x: np.ndarray) -> dict[str, float]:
    """Start from the sample autocovariances: for WN + AR1, gamma(h) = A phi^h (h >= 1), so
    phi = gamma(2) / gamma(1), A = gamma(1) / phi, sigma2 = gamma(0) - A (clipped into the
    parameter space)."""
    xc = x - x.mean()
    n = xc.size
    g = [float(xc[: n - h] @ xc[h:]) / n for h in range(3)]
    phi = float(np.clip(g[2] / g[1], 0.05, 0.999)) if g[1] > 0 else 0.5
    a = float(np.clip(g[1] / phi, 0.05 * g[0], 0.95 * g[0])) if g[1] > 0 else 0.5 * g[0]
    return {"WN[1].sigma2": g[0] - a, "AR1[1].phi": phi, "AR1[1].sigma2": a * (1 - phi**2)}


def _derivatives(x: np.ndarray, eta: np.ndarray, h: float = 1e-4
                 ) -> tuple[float, np.ndarray, np.ndarray]:
    """Profile log-likelihood, gradient and Hessian in eta by central differences (step h)."""
    f0 = _profile(x, eta)[0]
    e = np.eye(2) * h
    fp = [_profile(x, eta + e[i])[0] for i in range(2)]
    fm = [_profile(x, eta - e[i])[0] for i in range(2)]
    grad = np.array([(fp[i] - fm[i]) / (2 * h) for i in range(2)])
    hess = np.empty((2, 2))
    for i in range(2):
        hess[i, i] = (fp[i] - 2 * f0 + fm[i]) / h**2
    hess[0, 1] = hess[1, 0] = (_profile(x, eta + e[0] + e[1])[0] - _profile(x, eta + e[0] - e[1])[0]
                               - _profile(x, eta - e[0] + e[1])[0]
                               + _profile(x, eta - e[0] - e[1])[0]) / (4 * h**2)
    return f0, grad, hess


def _decrement(grad: np.ndarray, hess: np.ndarray) -> tuple[float, np.ndarray]:
    """Newton decrement g' (-H)^-1 g / 2 and the Newton step; inf when -H is not positive
    definite (no maximum there)."""
    try:
        if np.any(np.linalg.eigvalsh(-hess) <= 0):
            return np.inf, np.zeros(2)
        step = np.linalg.solve(-hess, grad)
    except np.linalg.LinAlgError:
        return np.inf, np.zeros(2)
    return float(grad @ step) / 2.0, step


def fit_wn_ar1_mle(x: np.ndarray, start: Mapping[str, float], maxiter: int = 200,
                   polish: int = 5) -> MLEFit:
    """Exact MLE of WN + AR1 from one start: L-BFGS-B on the profile log-likelihood per sample in
    (atanh phi, log nu2/sigma2) inside a wide box, then up to ``polish`` damped Newton steps on the
    total log-likelihood. *Converged* when its Hessian is negative definite and the Newton
    decrement g' (-H)^-1 g / 2 (central finite differences) is below 1e-3, i.e. at most 1e-3 of
    log-likelihood is left to gain;
    *boundary* when |phi| >= 0.9999 or a variance is below 1e-6 Var(x)."""
    from scipy.optimize import minimize

    t0 = time.process_time()
    x = np.ascontiguousarray(x, dtype=float)
    n = x.size
    vx = float(np.var(x))
    eta0 = np.array([math.atanh(float(np.clip(start["AR1[1].phi"], -0.9999, 0.9999))),
                     math.log(start["AR1[1].sigma2"] / start["WN[1].sigma2"])])
    eta0 = np.clip(eta0, [-_ETA_BOX[0], -_ETA_BOX[1]], [_ETA_BOX[0], _ETA_BOX[1]])
    nfev = [0]

    def f(eta: np.ndarray) -> float:
        nfev[0] += 1
        ll = _profile(x, eta)[0]
        return -ll / n if np.isfinite(ll) else 1e300

    res = minimize(f, eta0, method="L-BFGS-B",
                   bounds=[(-_ETA_BOX[0], _ETA_BOX[0]), (-_ETA_BOX[1], _ETA_BOX[1])],
                   options={"maxiter": int(maxiter), "ftol": 1e-13, "gtol": 1e-9})
    lo, hi = np.array([-_ETA_BOX[0], -_ETA_BOX[1]]), np.array([_ETA_BOX[0], _ETA_BOX[1]])
    eta = res.x
    # Newton polish on the total log-likelihood (central differences): L-BFGS-B with
    # finite-difference gradients of -ll/T can stall a little short of the optimum at large T
    for _ in range(polish):
        ll, grad, hess = _derivatives(x, eta)
        nfev[0] += 9
        dec, step = _decrement(grad, hess)
        if not np.isfinite(dec) or dec < 1e-3:
            break
        t = 1.0
        while t > 1e-3:
            trial = np.clip(eta + t * step, lo, hi)
            nfev[0] += 1
            if _profile(x, trial)[0] > ll:
                eta = trial
                break
            t /= 2.0
        else:
            break
    ll, grad, hess = _derivatives(x, eta)
    nfev[0] += 9
    dec, _ = _decrement(grad, hess)
    s2 = _profile(x, eta)[1]
    phi, ratio = math.tanh(eta[0]), math.exp(eta[1])
    params = {"WN[1].sigma2": s2, "AR1[1].phi": phi, "AR1[1].sigma2": ratio * s2}
    boundary = (abs(phi) >= _PHI_BOUND or s2 < _VAR_REL_BOUND * vx
                or ratio * s2 < _VAR_REL_BOUND * vx)
    # the optimiser's own flag is not used: with finite-difference gradients its line search
    # often stops "abnormally" at the optimum; the decrement is the test that matters
    ok = bool(np.isfinite(ll)) and 0 <= dec < 1e-3
    if boundary:
        msg = "boundary: " + ("|phi| >= 0.9999" if abs(phi) >= _PHI_BOUND else "variance -> 0")
    elif not ok:
        msg = f"not converged (optimiser: {res.message}; Newton decrement {dec:.3g})"
    else:
        msg = "converged"
    return MLEFit(params, float(ll), ok and not boundary, boundary, msg,
                  time.process_time() - t0, nfev[0])


def _time_min(fn: Callable[[], Any], repeat: int) -> float:
    """Minimum wall-clock seconds of ``repeat`` calls (wall, not CPU: a multi-threaded BLAS counts
    every thread's CPU; run single-threaded for a per-core figure)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def dense_cost(truth: Mapping[str, float], sizes: Sequence[int], seed: int = 0, repeat: int = 2
               ) -> pd.DataFrame:
    """Seconds per log-likelihood evaluation (minimum wall clock of ``repeat``) by the chapter's
    dense T x T route and by the Kalman filter, the memory of the dense matrix, and the
    difference of the two values."""
    model = gmwm.Model("WN+AR1")
    theta = model.theta(dict(truth))
    p = (truth["AR1[1].phi"], truth["AR1[1].sigma2"], truth["WN[1].sigma2"])
    rows = []
    for n in sizes:
        x = model.simulate(theta, int(n), rng=_rng("dense", n, 0, seed))
        ld = wn_ar1_loglike_dense(x, *p)
        lk = wn_ar1_loglike(x, *p)
        rows.append({"n_samples": int(n),
                     "dense_seconds": _time_min(lambda x=x: wn_ar1_loglike_dense(x, *p), repeat),
                     "kalman_seconds": _time_min(lambda x=x: wn_ar1_loglike(x, *p), max(repeat, 5)),
                     "dense_memory_mb": 8.0 * n * n / 1e6,
                     "loglike_dense": ld, "loglike_kalman": lk, "abs_diff": abs(ld - lk)})
    return pd.DataFrame(rows)


#: Example 4.1 settings (the chapter gives no values): WN sigma2 = 1 plus an AR1 with a correlation
#: time of 100 samples (``fast_ar1``) or 1000 samples (``slow_ar1``), both with an AR1 long-run
#: level nu2 / (1 - phi)^2 = 100 sigma2.
MLE_SETTINGS: dict[str, dict[str, float]] = {
    "fast_ar1": {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 1e-2},
    "slow_ar1": {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.999, "AR1[1].sigma2": 1e-4},
}


def mle_study(n_samples: Sequence[int] = (1000, 10_000, 100_000), replicates: int = 100,
              settings: Mapping[str, Mapping[str, float]] | None = None, seed: int = 0,
              maxiter: int = 200, wrong_optimum_ll: float = 1.0
              ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """[AV-chapter] Example 4.1 on ``replicates`` WN + AR1 signals per setting and T: the GMWM
    (the project's default fit; CPU time includes its WV) and the exact MLE (:func:`fit_wn_ar1_mle`)
    from its own moment start (``mle``, the headline: no outside information) and from the GMWM
    estimate (``mle_gmwm``). A third MLE run, started at the truth, only supplies a reference
    optimum: a fit is a *wrong optimum* when its log-likelihood is more than ``wrong_optimum_ll``
    below the best of the three MLE runs and of the likelihood at the GMWM estimate.

    Returns (per replicate table, summary per setting, T and method: failure counts, CPU seconds,
    RMSE over the replicates where the headline MLE converged to the best optimum)."""
    settings = {k: dict(v) for k, v in (settings or MLE_SETTINGS).items()}
    model = gmwm.Model("WN+AR1")
    names = model.param_names
    rows = []
    for label, truth in settings.items():
        theta = model.theta(truth)
        for n in n_samples:
            for r in range(int(replicates)):
                key = f"mle/{label}"
                x = model.simulate(theta, int(n), rng=_rng(key, n, r, seed))
                t0 = time.process_time()
                g = gmwm.fit(x, model, seed=replicate_seed(f"allan/{key}", n, r, seed))
                tg = time.process_time() - t0
                gp = g.as_dict()
                inside = gp["WN[1].sigma2"] > 0 and gp["AR1[1].sigma2"] > 0
                fits = {"mle": fit_wn_ar1_mle(x, moment_start(x), maxiter),
                        "mle_gmwm": fit_wn_ar1_mle(x, gp if inside else truth, maxiter),
                        "oracle": fit_wn_ar1_mle(x, truth, maxiter)}
                ll_gmwm = (wn_ar1_loglike(x, gp["AR1[1].phi"], gp["AR1[1].sigma2"],
                                          gp["WN[1].sigma2"]) if inside else -np.inf)
                best = max(ll_gmwm, *(ft.loglike for ft in fits.values()))
                common = {"setting": label, "n_samples": int(n), "replicate": r,
                          "best_loglike": best}
                rows.append({**common, "method": "gmwm", "seconds": tg,
                             "converged": bool(g.converged), "boundary": not inside,
                             "wrong_optimum": False, "loglike": ll_gmwm,
                             **{k: gp[k] for k in names}})
                for meth in ("mle", "mle_gmwm"):
                    ft = fits[meth]
                    rows.append({**common, "method": meth, "seconds": ft.seconds,
                                 "converged": ft.converged, "boundary": ft.boundary,
                                 "wrong_optimum": bool(ft.loglike < best - wrong_optimum_ll),
                                 "loglike": ft.loglike, **{k: ft.params[k] for k in names}})
    per = pd.DataFrame(rows)
    idx = ["setting", "n_samples", "replicate"]
    head = per[per.method == "mle"].set_index(idx)
    good = head[head.converged & ~head.wrong_optimum].index
    out = []
    for (label, n, meth), d in per.groupby(["setting", "n_samples", "method"], sort=False):
        kept = d.set_index(idx)
        kept = kept.loc[kept.index.intersection(good)]
        failed = ~d.converged | d.boundary | d.wrong_optimum
        row = {"setting": label, "n_samples": int(n), "method": meth, "replicates": len(d),
               "not_converged": int((~d.converged & ~d.boundary).sum()),
               "boundary": int(d.boundary.sum()), "wrong_optimum": int(d.wrong_optimum.sum()),
               "any_failure": int(failed.sum()),
               "seconds_mean": float(d.seconds.mean()),
               "seconds_median": float(d.seconds.median()), "n_compared": len(kept)}
        for k in names:
            row[f"rmse_{k}"] = float(np.sqrt(np.mean((kept[k] - settings[label][k]) ** 2)))
        out.append(row)
    return per, pd.DataFrame(out)


# ==================================================================================================
# Figures
# ==================================================================================================


def figure_adev(res: AdevResult) -> Any:
    """Fig. 4.1 / 4.2 analogue: AD of replicate 0 with its 95 % CI, the theoretical lines, the
    IEEE 952 reading lines and the GMWM model AD."""
    from gmwm.plots import PALETTE, plot_av, style, subplots

    fig, ax = subplots(figsize=(5.6, 3.8))
    plot_av(res.av, ax=ax, deviation=True, readings=res.readings,
            label="Allan deviation (replicate 0)")
    m = res.av.clusters.astype(float)
    mm = np.geomspace(m.min(), m.max(), 200)
    lines = _av_true(res.which, mm)
    with style():
        if res.which == "fig42":
            ax.plot(mm, np.sqrt(lines["WN"]), color=PALETTE[5], lw=0.9, ls="-.",
                    label=r"WN: $\sigma/\sqrt{\tau}$ (slope $-1/2$)")
            ax.plot(mm, np.sqrt(lines["RW"]), color=PALETTE[6], lw=0.9, ls="-.",
                    label=r"RW: $\gamma\sqrt{\tau/3}$ (slope $+1/2$)")
            ax.plot(mm, np.sqrt(lines["chapter"]), color=PALETTE[0], lw=1.0,
                    label=r"theory $\sqrt{\sigma^2/\tau + \gamma^2\tau/3}$")
        else:
            ax.plot(mm, np.sqrt(lines["chapter"]), color=PALETTE[0], lw=1.0,
                    label=r"theory $\sigma/\sqrt{\tau}$ (slope $-1/2$)")
        for key in ("N", "K") if res.which == "fig42" else ("N",):
            if res.readings[key].get("value") is None:  # say so rather than draw nothing
                ax.plot([], [], " ", label=f"{key}: no IEEE reading ({res.readings[key]['note']})")
        fit = res.fit
        ax.plot(m, np.sqrt(2.0 * fit.model.wv(fit.params, 2.0 * m)), color=PALETTE[0], lw=0,
                marker="s", ms=5, mfc="none", mew=0.8, label="GMWM model", zorder=6)
        ax.set_ylabel("Allan deviation [signal unit]")
        ax.set_xlabel("Cluster time τ [samples]")
        ax.legend(loc="best", fontsize=7)
    return fig


def figure_ma1(table: pd.DataFrame) -> Any:
    """Example 4.2: the chapter's MA(1) AV against the simulated mean with 95 % MC bands."""
    from gmwm.plots import PALETTE, style, subplots

    fig, ax = subplots(figsize=(5.2, 3.4))
    with style():
        for i, (theta, d) in enumerate(table.groupby("theta")):
            c = PALETTE[1 + i]
            ax.plot(d.m, d.chapter, color=c, lw=1.0, label=f"Example 4.2, θ = {theta:g}")
            ax.fill_between(d.m, d.simulated - 1.96 * d.mc_se, d.simulated + 1.96 * d.mc_se,
                            color=c, alpha=0.25, lw=0)
            ax.plot(d.m, d.simulated, "o", color=c, ms=3, label=f"simulated mean, θ = {theta:g}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Cluster length m [samples]")
        ax.set_ylabel("Allan variance [σ² units]")
        ax.legend(loc="best", fontsize=7)
    return fig


def figure_ambiguity(res: AmbiguityResult) -> Any:
    """Sec. 4.2.2: spectra (left) and Allan variances (right) of the two constructions."""
    from gmwm.plots import PALETTE, style, subplots

    c = res.curves
    fig, axes = subplots(2, 2, figsize=(7.6, 5.6))
    with style():
        ax = axes[0, 0]
        f = c["f_cont"]
        for s, col, lab in ((1.0, PALETTE[1], "X"), (-1.0, PALETTE[2], "Y")):
            ax.plot(f, c["h"] * (1 + s * c["eps"] * np.cos(2 * np.pi * np.log2(f))) / f,
                    color=col, label=f"$S_{lab}(f) = h(1 {'+' if s > 0 else '-'} "
                    r"\epsilon\cos(2\pi\log_2 f))/f$")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Frequency f [1/time unit]")
        ax.set_ylabel("PSD [unit²·time]")
        ax.set_title(r"(a) chapter: $\Phi(f) = 2\Phi(2f)$")
        ax.legend(fontsize=6.5)
        ax = axes[0, 1]
        t = res.table
        floor = 1e-17  # exact zeros drawn here
        for name, dy, mk, col, lab in (
                ("chapter_2phi2f", True, "o", PALETTE[1], r"$\Phi(f)=2\Phi(2f)$, dyadic τ"),
                ("chapter_2phi2f", False, "s", PALETTE[3], r"$\Phi(f)=2\Phi(2f)$, other τ"),
                ("control_3phi3f", None, "x", PALETTE[2], r"control $\Phi(f)=3\Phi(3f)$")):
            d = t[t.construction == name]
            if dy is not None:
                d = d[d.dyadic == dy]
            ax.plot(d.scale, np.maximum(d.rel_diff, floor), mk, color=col, ms=4,
                    mfc="none" if mk == "s" else col, label=lab)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(floor / 3, 1.0)
        ax.set_xlabel("Cluster time τ [time unit]")
        ax.set_ylabel(r"$|\mathrm{AV}_X/\mathrm{AV}_Y - 1|$ (0 drawn at 1e-17)")
        ax.set_title(r"(b) AVs equal at every τ ($4h\ln 2$), quadrature")
        ax.legend(fontsize=6.5)
        ax = axes[1, 0]
        ax.plot(c["f_disc"], c["spec_disc_x"], color=PALETTE[1], label="X (MA(4))")
        ax.plot(c["f_disc"], c["spec_disc_y"], color=PALETTE[2], label="Y (MA(4))")
        ax.set_xlabel("Frequency f [cycles/sample]")
        ax.set_ylabel("PSD [unit²·sample]")
        ax.set_title(r"(c) discrete time: $\Phi = -16\epsilon\cos(6\pi f)\sin^2(\pi f)$")
        ax.legend(fontsize=7)
        ax = axes[1, 1]
        ax.plot(c["m_all"], c["av_disc_x"], color=PALETTE[1], lw=0.8, label="X, every m")
        ax.plot(c["m_all"], c["av_disc_y"], color=PALETTE[2], lw=0.8, label="Y, every m")
        dy = c["m_dyadic"]
        ax.plot(dy, c["av_disc_x"][dy - 1], "o", color=PALETTE[0], ms=4,
                label="dyadic m (equal)")
        ds = dy[: c["sim_x"].size]
        ax.plot(ds, c["sim_x"], "+", color=PALETTE[1], ms=7, label="simulated mean X")
        ax.plot(ds, c["sim_y"], "x", color=PALETTE[2], ms=5, label="simulated mean Y")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Cluster length m [samples]")
        ax.set_ylabel("Allan variance [unit²]")
        ax.set_title("(d) equal at every m but 3 (Lemma 4.2)")
        ax.legend(fontsize=6.5)
    return fig


def figure_intervals(table: pd.DataFrame, first: Mapping[str, Any]) -> Any:
    """Remark 4.3: replicate 0's AV with each interval (a lower bound <= 0 drawn as a downward
    arrow at the axis floor), share of lower bounds <= 0 and coverage per cluster."""
    from gmwm.plots import PALETTE, style, subplots

    fig, axes = subplots(1, 3, figsize=(10.5, 3.4))
    m, av = np.asarray(first["m"]), np.asarray(first["av"])
    types = list(first["low"])
    cols = {t: PALETTE[1 + i] for i, t in enumerate(types)}
    with style():
        ax = axes[0]
        ax.plot(m, first["true"], color=PALETTE[0], lw=1.0, label="exact AV")
        ax.plot(m, av, "o", color=PALETTE[0], ms=3, label="AV estimate (replicate 0)")
        floor = float(np.min(av)) / 20.0
        for i, t in enumerate(types):
            lo, hi = np.asarray(first["low"][t]), np.asarray(first["high"][t])
            off = 1.0 + 0.06 * (i - (len(types) - 1) / 2)
            xm = m * off
            ax.vlines(xm, np.where(lo > 0, lo, floor), hi, color=cols[t], lw=1.2, label=t)
            neg = lo <= 0
            ax.plot(xm[neg], np.full(neg.sum(), floor), "v", color=cols[t], ms=5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Cluster time τ [samples]")
        ax.set_ylabel("Allan variance [unit²]")
        ax.set_title("95 % intervals (▼: lower bound ≤ 0)")
        ax.legend(fontsize=6.5)
        for ax, col, title in ((axes[1], "share_low_le_0", "share of lower bounds ≤ 0"),
                               (axes[2], "coverage", "coverage of the exact AV")):
            for t in types:
                d = table[table.interval == t]
                ax.plot(d.m, d[col], "o-", color=cols[t], ms=3, lw=0.8, label=t)
            if col == "coverage":
                ax.axhline(0.95, color=PALETTE[0], lw=0.8, ls=":", label="nominal 0.95")
            ax.set_xscale("log")
            ax.set_xlabel("Cluster time τ [samples]")
            ax.set_ylabel(title)
            ax.set_ylim(-0.03, 1.03)
            ax.legend(fontsize=6.5)
    return fig


# ==================================================================================================
# Key numbers (the JSON the reproduction table quotes) and the index's summary table
# ==================================================================================================


def _f(v: Any) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None


def adev_numbers(res: AdevResult) -> dict[str, Any]:
    """Replicate-0 and Monte Carlo numbers of one AD figure, by quantity."""
    return {row.quantity: {"truth": _f(row.truth), "replicate0": _f(row.replicate0),
                           "mc_mean": _f(row.mc_mean), "mc_sd": _f(row.mc_sd),
                           "n_read": int(row.n_read), "replicates": int(row.replicates)}
            for row in res.summary.itertuples()}


def ma1_numbers(table: pd.DataFrame) -> dict[str, Any]:
    return {"max_abs_z": float(table.z.abs().max()),
            "max_rel_lemma42": float(table.rel_lemma.max()),
            "max_rel_project_model": float(table.rel_model.max()),
            "thetas": sorted(float(t) for t in table.theta.unique()),
            "max_m": int(table.m.max())}


def lemma42_numbers(table: pd.DataFrame) -> dict[str, Any]:
    return {"max_rel_spectral": float(table.rel_spectral.max()),
            "max_rel_quadratic_form": float(table.rel_quadratic_form.max()),
            "max_rel_project_model": float(table.rel_project_model.max()),
            "max_m": int(table.m.max()),
            "max_m_quadratic_form": int(table.m[table.quadratic_form.notna()].max()),
            "pairs": [[float(a), float(b)] for a, b in
                      table[["phi", "theta"]].drop_duplicates().to_numpy()]}


def interval_numbers(table: pd.DataFrame) -> dict[str, Any]:
    """Per interval type: the share of lower bounds <= 0 and the coverage at the two longest
    clusters, and the shortest cluster where any lower bound was <= 0."""
    out: dict[str, Any] = {}
    for t, d in table.groupby("interval", sort=False):
        d = d.sort_values("m")
        neg = d[d.share_low_le_0 > 0]
        out[t] = {"share_low_le_0_last": float(d.share_low_le_0.iloc[-1]),
                  "share_low_le_0_second_last": float(d.share_low_le_0.iloc[-2]),
                  "coverage_last": float(d.coverage.iloc[-1]),
                  "coverage_second_last": float(d.coverage.iloc[-2]),
                  "coverage_min": float(d.coverage.min()),
                  "first_m_low_le_0": int(neg.m.iloc[0]) if len(neg) else None,
                  "eta_last": float(d.eta.iloc[-1]), "m_last": int(d.m.iloc[-1]),
                  "replicates": int(d.replicates.iloc[0])}
    return out


def mle_numbers(summary: pd.DataFrame, dense: pd.DataFrame, t_target: int = 100_000
                ) -> dict[str, Any]:
    """Failure counts and CPU seconds per setting, T and method; the dense route's largest
    measured size, its time, and the O(T^3) projection to ``t_target`` (time and memory)."""
    out: dict[str, Any] = {"fits": {}}
    for row in summary.itertuples():
        out["fits"].setdefault(row.setting, {}).setdefault(str(row.n_samples), {})[row.method] = {
            "replicates": int(row.replicates), "not_converged": int(row.not_converged),
            "boundary": int(row.boundary), "wrong_optimum": int(row.wrong_optimum),
            "any_failure": int(row.any_failure), "seconds_mean": float(row.seconds_mean),
            "seconds_median": float(row.seconds_median)}
    d = dense.sort_values("n_samples")
    big = d.iloc[-1]
    ratio = (float(big.dense_seconds / d.iloc[-2].dense_seconds) if len(d) > 1 else None)
    out["dense"] = {"n_samples": int(big.n_samples), "seconds": float(big.dense_seconds),
                    "doubling_ratio": ratio,
                    "projected_seconds_at_target": float(big.dense_seconds
                                                         * (t_target / big.n_samples) ** 3),
                    "memory_gb_at_target": 8.0 * t_target**2 / 1e9, "target": int(t_target),
                    "max_abs_loglike_diff": float(d.abs_diff.max()),
                    "kalman_seconds_at_largest": float(big.kalman_seconds)}
    return out


def summary_table(numbers: Mapping[str, Any]) -> pd.DataFrame:
    """One row per checked quantity: ``item`` (the chapter's), ``quantity``, ``value`` (this
    run) and ``reference`` (the chapter's or the exact value; NaN when there is none)."""
    rows: list[tuple[str, str, float | None, float | None]] = []
    for fig, item in (("fig41", "Fig 4.1"), ("fig42", "Fig 4.2")):
        for q, v in numbers[fig].items():
            rows.append((item, f"{q} (MC mean of {v['replicates']})", v["mc_mean"], v["truth"]))
    m = numbers["ma1"]
    rows += [("Example 4.2", "max abs z, simulated mean vs formula", m["max_abs_z"], None),
             ("Example 4.2", "max rel. diff. Lemma 4.2 vs formula", m["max_rel_lemma42"], 0.0),
             ("Example 4.2", "max rel. diff. QN+WN model vs formula", m["max_rel_project_model"],
              0.0)]
    lm = numbers["lemma42"]
    rows += [("Lemma 4.2", f"max rel. diff. vs {k}", lm[f"max_rel_{k}"], 0.0)
             for k in ("spectral", "quadratic_form", "project_model")]
    a = numbers["ambiguity"]
    rows += [("Sec 4.2.2", "Phi(f)=2Phi(2f): max rel. AV diff., dyadic tau",
              a["chapter_2phi2f_max_rel_diff_dyadic"], 0.0),
             ("Sec 4.2.2", "Phi(f)=2Phi(2f): max rel. AV diff., other tau",
              a["chapter_2phi2f_max_rel_diff_nondyadic"], 0.0),
             ("Sec 4.2.2", "control Phi(f)=3Phi(3f): max rel. AV diff.",
              a["control_3phi3f_max_rel_diff_dyadic"], None),
             ("Sec 4.2.2", "discrete MA(4) pair: max rel. AV diff., dyadic m",
              a["discrete_max_rel_diff_dyadic"], 0.0),
             ("Sec 4.2.2", "discrete MA(4) pair: max rel. AV diff., other m",
              a["discrete_max_rel_diff_nondyadic"], None)]
    for t, v in numbers["intervals"].items():
        rows += [("Remark 4.3", f"{t}: share of lower bounds <= 0 at m = {v['m_last']}",
                  v["share_low_le_0_last"], None),
                 ("Remark 4.3", f"{t}: coverage at m = {v['m_last']}", v["coverage_last"], 0.95)]
    for name, v in numbers.get("lemma41", {}).items():
        rows += [("Lemma 4.1", f"{name}: continuous-kernel AV / exact AV - 1 at m = 1",
                  v["rel_continuous_m1"], 0.0),
                 ("Lemma 4.1", f"{name}: same at m = {v['m_max']}", v["rel_continuous_mmax"], 0.0)]
    if "cor41" in numbers:
        c = numbers["cor41"]
        rows += [("Cor 4.1", "max rel. diff. exact AV of the sum vs sum of AVs", c["max_rel_exact"],
                  0.0),
                 ("Cor 4.1", f"max abs z of the mean cross term ({c['replicates']} replicates)",
                  c["max_abs_z_cross"], None)]
    for tkey, by_m in numbers.get("moav", {}).items():
        for mkey, v in by_m.items():
            rows += [("Lemma 4.3", f"{tkey} {mkey}: RMSE / AV", v["rel_rmse"], None),
                     ("Lemma 4.4", f"{tkey} {mkey}: skewness of AV_hat", v["skewness"], 0.0),
                     ("Sec 4.3.3", f"{tkey} {mkey}: coverage, Bartlett LRV interval",
                      v["coverage_lrv"], 0.95),
                     ("Sec 4.3.3", f"{tkey} {mkey}: coverage, printed width sigma_T / T",
                      v["coverage_printed"], 0.95)]
    for tkey, by_meth in numbers.get("consistency", {}).items():
        for meth, by_p in by_meth.items():
            for par, v in by_p.items():
                if v["mean_ratio"] is not None:
                    rows.append(("Sec 4.1", f"{tkey} {meth} {par}: mean / truth", v["mean_ratio"],
                                 1.0))
                if meth == "avsm":
                    rows.append(("Sec 4.1", f"{tkey} avsm {par}: noise-free value / truth",
                                 v["noise_free_ratio"], 1.0))
    if "mle" in numbers:
        for setting, by_t in numbers["mle"]["fits"].items():
            for n, by_m in by_t.items():
                for meth in ("mle", "gmwm"):
                    v = by_m[meth]
                    what = f"{setting} T={n} {meth}: failures of {v['replicates']}"
                    rows.append(("Example 4.1", what, v["any_failure"], None))
                    rows.append(("Example 4.1", f"{setting} T={n} {meth}: mean CPU s",
                                 v["seconds_mean"], None))
        dn = numbers["mle"]["dense"]
        rows.append(("Example 4.1", f"dense likelihood: s per evaluation at T={dn['n_samples']}",
                     dn["seconds"], None))
        rows.append(("Example 4.1", f"dense likelihood: projected s at T={dn['target']}",
                     dn["projected_seconds_at_target"], None))
    return pd.DataFrame(rows, columns=["item", "quantity", "value", "reference"])


# ==================================================================================================
# Items added for the chapter's remaining claims: Lemma 4.1, Corollary 4.1, Lemmas 4.3-4.4 with the
# Sec. 4.3.3 interval, and Sec. 4.1's "AV-based methods are inconsistent"
# ==================================================================================================

#: Sampled processes of the Lemma 4.1 check: (name, ARMA(1,1) phi, theta), innovation variance 1.
LEMMA41_PROCESSES: tuple[tuple[str, float, float], ...] = (
    ("WN", 0.0, 0.0), ("MA1(0.5)", 0.0, 0.5), ("AR1(0.9)", 0.9, 0.0), ("AR1(0.99)", 0.99, 0.0))


def av_lemma41_sampled(spectrum: Callable[[np.ndarray], np.ndarray], m: int, nodes: int = 32
                       ) -> float:
    """[AV-chapter] Lemma 4.1 as printed (continuous-time kernel sin^4(pi f tau) / (pi f tau)^2)
    applied to a sampled series: its two-sided spectral density S(f) on [-1/2, 1/2] (zero beyond
    the Nyquist frequency), tau = m samples: 4 int_0^{1/2} S(f) sin^4(pi f m) / (pi f m)^2 df.
    Same quadrature panels as :func:`av_spectral`, whose discrete kernel differs by the factor
    (pi f / sin(pi f))^2."""
    m = int(m)
    edges = np.arange(m + 1) / (2.0 * m)
    edges = np.unique(np.r_[0.0, edges[1] * np.geomspace(1e-9, 1.0, 40), edges[1:]])
    f, w = _gauss_panels(edges, nodes)
    kern = np.sin(np.pi * f * m) ** 4 / (np.pi * f * m) ** 2
    return float(4.0 * np.sum(w * spectrum(f) * kern))


def lemma41_study(levels: int = 15) -> pd.DataFrame:
    """Lemma 4.1 on sampled series, per process of :data:`LEMMA41_PROCESSES` and cluster
    m = 1..2**(levels-1): the exact AV (Lemma 4.2 on the closed-form autocovariance), the printed
    continuous-time formula (:func:`av_lemma41_sampled`) and the discrete-kernel integral
    (:func:`av_spectral`); ``rel_continuous`` = continuous / exact - 1 (signed),
    ``rel_discrete`` = |discrete / exact - 1|."""
    rows = []
    for name, phi, theta in LEMMA41_PROCESSES:
        spec = arma11_spectrum(phi, theta, 1.0)
        for mk in _clusters(levels):
            exact = av_from_acvf(arma11_acvf(phi, theta, 1.0, 2 * mk), mk)
            cont = av_lemma41_sampled(spec, mk)
            disc = av_spectral(spec, mk)
            rows.append({"process": name, "m": int(mk), "exact": exact, "continuous": cont,
                         "discrete_kernel": disc, "rel_continuous": cont / exact - 1.0,
                         "rel_discrete": abs(disc / exact - 1.0)})
    return pd.DataFrame(rows)


#: Corollary 4.1's sum: independent WN, AR1 and RW (per-sample parameters).
COR41_PARTS: dict[str, dict[str, float]] = {
    "WN": {"WN[1].sigma2": 1.0}, "AR1": {"AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1},
    "RW": {"RW[1].gamma2": 1e-4}}


def additivity_study(n_samples: int = 16384, replicates: int = 200, seed: int = 0,
                     levels: int = 12) -> pd.DataFrame:
    """Corollary 4.1 on Z = WN + AR1 + RW (:data:`COR41_PARTS`, independent), per cluster
    m = 1..2**(levels-1): the exact AV of the sum model against the sum of the parts' exact AVs
    (``rel_exact``), and over ``replicates`` simulated triples the mean of
    AV_hat(Z) - sum AV_hat(parts) (the cross terms; mean 0 under independence) with its z, and
    the mean AV_hat(Z) against the sum of exact AVs (z)."""
    m = _clusters(levels)
    parts = {k: (gmwm.Model(k), p) for k, p in COR41_PARTS.items()}
    every = {k: v for p in COR41_PARTS.values() for k, v in p.items()}
    exact_sum = sum(model_av(mod, p, m) for mod, p in parts.values())
    exact_model = model_av("WN+AR1+RW", every, m)
    cross, total = [], []
    for r in range(int(replicates)):
        rng = _rng("cor41", n_samples, r, seed)
        xs = [mod.simulate(mod.theta(p), n_samples, rng=rng) for mod, p in parts.values()]
        avs = 2.0 * wvar_many(np.stack([*xs, np.sum(xs, axis=0)]), levels)
        cross.append(avs[-1] - avs[:-1].sum(axis=0))
        total.append(avs[-1])
    cross, total = np.array(cross), np.array(total)
    n = cross.shape[0]
    c_se = cross.std(axis=0, ddof=1) / math.sqrt(n)
    t_se = total.std(axis=0, ddof=1) / math.sqrt(n)
    return pd.DataFrame({
        "m": m.astype(int), "exact_sum_of_parts": exact_sum, "exact_sum_model": exact_model,
        "rel_exact": np.abs(exact_model / exact_sum - 1.0),
        "mean_cross": cross.mean(axis=0), "se_cross": c_se, "z_cross": cross.mean(axis=0) / c_se,
        "mean_av_sum": total.mean(axis=0), "z_av_sum": (total.mean(axis=0) - exact_sum) / t_se,
        "replicates": n})


def moav_at(x: np.ndarray, m: int) -> np.ndarray:
    """Half the squared differences of the overlapping m-means, Y_k = (Xbar_k - Xbar_{k-m})^2 / 2, k = 2m..T ([AV-chapter] Definition 4.3; their
    mean is the MOAV at cluster m)."""
    s = np.r_[0.0, np.cumsum(np.asarray(x, dtype=float))]
    means = (s[m:] - s[:-m]) / m  # Xbar over x[k-m+1..k], k = m..T
    d = means[m:] - means[:-m]
    return 0.5 * d * d


def moav_asymptotics_study(n_samples: Sequence[int] = (1000, 10_000, 100_000),
                           clusters: Sequence[int] = (1, 16, 256), replicates: int = 200,
                           seed: int = 0, alpha: float = 0.05) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Lemmas 4.3 (consistency) and 4.4 (asymptotic normality) of the MOAV and the Sec. 4.3.3
    interval, on the Fig. 4.2 model (WN + RW: its differences are stationary, strongly mixing,
    with all moments), per T and cluster m over ``replicates`` series:

    * ``rel_rmse``: RMSE / AV; ``sqrtT_rel_rmse`` = sqrt(T) x that (Lemma 4.4: tends to a
      constant); ``skewness`` of AV_hat (0 for a normal law);
    * coverage of the 1 - alpha intervals AV_hat -+ z se with se = the exact SD of AV_hat
      (``exact``), sqrt(LRV_hat / M), LRV_hat the Bartlett long-run variance of the Y_k of
      :func:`moav_at` with bandwidth 2m (``lrv``, the interval read with the Lemma 4.4 scaling),
      and the printed width sigma_T / T with sigma_T^2 the long-run variance of the squared
      differences 2 Y_k (``printed``).

    Returns the summary and the per-replicate table (replicate, T, m, AV_hat, the three
    half-widths)."""
    from scipy.special import ndtri
    from scipy.stats import skew

    from gmwm.wvcov import wv_covariance

    z = float(ndtri(1.0 - alpha / 2.0))
    model = gmwm.Model("WN+RW")
    theta = model.theta(FIG42)
    rows, reps = [], []
    for n in n_samples:
        n = int(n)
        ms = [int(c) for c in clusters if 2 * int(c) < n]
        sd = 2.0 * np.sqrt(np.diag(wv_covariance(model, theta, 2.0 * np.array(ms, float), n)))
        for r in range(int(replicates)):
            x = model.simulate(theta, n, rng=_rng("moav", n, r, seed))
            for k, mk in enumerate(ms):
                y = moav_at(x, mk)
                lrv = bartlett_lrv(y, 2 * mk)
                reps.append({"replicate": r, "n_samples": n, "m": mk, "av_hat": float(y.mean()),
                             "half_exact": z * sd[k], "half_lrv": z * math.sqrt(lrv / y.size),
                             "half_printed": z * math.sqrt(4.0 * lrv) / n})
    per = pd.DataFrame(reps)
    for (n, mk), d in per.groupby(["n_samples", "m"], sort=True):
        tv = float(model_av(model, FIG42, mk)[0])
        est = d.av_hat.to_numpy()
        row = {"n_samples": int(n), "m": int(mk), "true_av": tv,
               "rel_bias": float(est.mean() / tv - 1.0),
               "rel_rmse": float(np.sqrt(np.mean((est - tv) ** 2)) / tv)}
        row["sqrtT_rel_rmse"] = row["rel_rmse"] * math.sqrt(n)
        row["skewness"] = float(skew(est))
        for kind in ("exact", "lrv", "printed"):
            h = d[f"half_{kind}"].to_numpy()
            row[f"coverage_{kind}"] = float(np.mean(np.abs(est - tv) <= h))
        row["replicates"] = len(d)
        rows.append(row)
    return pd.DataFrame(rows), per


class _ExactWV:
    """A noise-free WV (the probability limit of the WV estimator) in the shape :func:`gmwm.avsm
    .fit_avsm` reads: scales 2**j, variance, M_j = T - 2**j + 1, freq 1."""

    def __init__(self, model: gmwm.Model, params: Mapping[str, float], n_samples: int,
                 levels: int):
        self.levels = np.arange(1, levels + 1)
        self.scales = 2.0 ** self.levels
        self.variance = model.wv(model.theta(dict(params)), self.scales)
        self.n = n_samples - self.scales + 1
        self.freq = 1.0


#: Sec. 4.1's consistency check: WN + RW with the crossover at m* = sqrt(3 sigma2 / gamma2) = 173.
CONSISTENCY_MODEL: tuple[str, dict[str, float]] = (
    "WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4})


def avsm_consistency_study(n_samples: Sequence[int] = (10_000, 100_000, 1_000_000),
                           replicates: int = 100, seed: int = 0,
                           limit_n_samples: Sequence[int] = (10_000_000,)
                           ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """[AV-chapter] Sec. 4.1: AV-based (log-log line fit) estimators are inconsistent. The AV
    slope method (:func:`gmwm.avsm.fit_avsm`, fixed-slope line fits) and the GMWM on the same
    WN + RW series (:data:`CONSISTENCY_MODEL`) at growing T, and the AVSM applied to the exact WV
    at the same T (its probability limit for that T; also at ``limit_n_samples``, no simulation).
    Returns the summary (per T, method, parameter: mean / truth, SD / truth, RMSE / truth, and the
    AVSM's noise-free value / truth; the mean is carried by rare wild AVSM readings, the median
    is not) and the per-replicate estimates."""
    from gmwm.avsm import fit_avsm

    model_str, truth = CONSISTENCY_MODEL
    model = gmwm.Model(model_str)
    theta = model.theta(truth)
    names = list(model.param_names)
    reps = []
    for n in n_samples:
        n = int(n)
        for r in range(int(replicates)):
            x = model.simulate(theta, n, rng=_rng("avsm_consistency", n, r, seed))
            wv = wvar(x)
            a = fit_avsm(wv, model)
            g = gmwm.fit(wv, model, seed=replicate_seed("allan/avsm_consistency", n, r, seed))
            for meth, vals in (("avsm", dict(zip(a.param_names, a.params, strict=True))),
                               ("gmwm", g.as_dict())):
                reps.append({"replicate": r, "n_samples": n, "method": meth,
                             **{k: float(vals[k]) for k in names}})
    per = pd.DataFrame(reps)
    rows = []
    for n in [*map(int, n_samples), *map(int, limit_n_samples)]:
        J = math.floor(math.log2(n)) - 1  # gmwm.wvar's default number of levels
        lim = fit_avsm(_ExactWV(model, truth, n, J), model)
        limit = dict(zip(lim.param_names, lim.params, strict=True))
        d_n = per[per.n_samples == n]
        for meth in ("avsm", "gmwm"):
            d = d_n[d_n.method == meth]
            for k in names:
                tv = truth[k]
                est = d[k].to_numpy(float) / tv
                rows.append({
                    "n_samples": n, "method": meth, "parameter": k, "truth": tv,
                    "mean_ratio": float(est.mean()) if est.size else np.nan,
                    "median_ratio": float(np.median(est)) if est.size else np.nan,
                    "sd_ratio": float(est.std(ddof=1)) if est.size > 1 else np.nan,
                    "rmse_ratio": (float(np.sqrt(np.mean((est - 1.0) ** 2))) if est.size
                                   else np.nan),
                    "mc_se_mean_ratio": (float(est.std(ddof=1) / math.sqrt(est.size))
                                         if est.size > 1 else np.nan),
                    "noise_free_ratio": (float(limit[k] / tv) if meth == "avsm" else 1.0),
                    "replicates": int(est.size)})
    return pd.DataFrame(rows), per


def items_numbers(lemma41: pd.DataFrame, cor41: pd.DataFrame, moav: pd.DataFrame,
                  consistency: pd.DataFrame) -> dict[str, Any]:
    """Key numbers of the four added items (the JSON REPRODUCTION.md quotes)."""
    out: dict[str, Any] = {"lemma41": {}}
    for name, d in lemma41.groupby("process", sort=False):
        out["lemma41"][name] = {
            "max_abs_rel_continuous": float(d.rel_continuous.abs().max()),
            "rel_continuous_m1": float(d.rel_continuous.iloc[0]),
            "rel_continuous_mmax": float(d.rel_continuous.iloc[-1]),
            "max_rel_discrete": float(d.rel_discrete.max()), "m_max": int(d.m.max())}
    out["cor41"] = {"max_rel_exact": float(cor41.rel_exact.max()),
                    "max_abs_z_cross": float(cor41.z_cross.abs().max()),
                    "max_abs_z_av_sum": float(cor41.z_av_sum.abs().max()),
                    "replicates": int(cor41.replicates.iloc[0]), "levels": len(cor41)}
    out["moav"] = {f"T{int(r.n_samples)}": {} for r in moav.itertuples()}
    for r in moav.itertuples():
        out["moav"][f"T{int(r.n_samples)}"][f"m{int(r.m)}"] = {
            k: (float(getattr(r, k)) if k != "replicates" else int(r.replicates))
            for k in ("rel_bias", "rel_rmse", "sqrtT_rel_rmse", "skewness", "coverage_exact",
                      "coverage_lrv", "coverage_printed", "replicates")}
    out["consistency"] = {}
    for r in consistency.itertuples():
        out["consistency"].setdefault(f"T{int(r.n_samples)}", {}).setdefault(r.method, {})[
            r.parameter] = {"mean_ratio": _f(r.mean_ratio), "median_ratio": _f(r.median_ratio),
                            "sd_ratio": _f(r.sd_ratio),
                            "rmse_ratio": _f(r.rmse_ratio), "noise_free_ratio": _f(r.noise_free_ratio),
                            "replicates": int(r.replicates)}
    return out


def allan_counts(readings: pd.DataFrame, intervals: pd.DataFrame, moav: pd.DataFrame,
                 sources: Mapping[str, str], consistency: pd.DataFrame | None = None) -> list:
    """The named counts the Allan rows quote (:class:`gmwm_studies.counts.Count`), recomputed from
    the per-replicate files (``sources``: file of each table, relative to ``reports/allan``):

    * ``allan.<fig>.n``; per reading R in N, K: ``allan.<fig>.<R>.n_read`` (replicates where the
      IEEE 952 reading exists), ``.missing`` and ``.ci_covers`` (read and its 95 % interval holds
      the truth sqrt(sigma2) or sqrt(gamma2));
    * ``allan.intervals.n`` and per interval kind and cluster m ``allan.intervals.<kind>.m<m>
      .low_le_0`` (lower bound <= 0) and ``.covered`` (low <= exact AV <= high);
    * ``allan.moav.T<T>.m<m>.<kind>.covered`` (Sec. 4.3.3 intervals of
      :func:`moav_asymptotics_study`: |AV_hat - AV| <= half-width);
    * with ``consistency`` (:func:`avsm_consistency_study`'s replicates):
      ``allan.consistency.T<T>.<method>.<param>.n``, ``.within1pct`` (|estimate / truth - 1|
      <= 0.01) and ``.off10pct`` (> 0.1)."""
    from gmwm_studies.counts import Count

    out = []
    src = sources["readings"]
    for fig, d in readings.groupby("figure", sort=True):
        truth = _FIGS[str(fig)][1]
        out.append(Count(f"allan.{fig}.n", len(d), "replicates", src))
        for key, par in (("N", "WN[1].sigma2"), ("K", "RW[1].gamma2")):
            if par not in truth or key not in d.columns:
                continue
            v = d[key].to_numpy(float)
            read = np.isfinite(v)
            tv = math.sqrt(truth[par])
            lo, hi = d[f"{key}_ci_low"].to_numpy(float), d[f"{key}_ci_high"].to_numpy(float)
            out += [Count(f"allan.{fig}.{key}.n_read", int(read.sum()),
                          f"replicates where the IEEE 952 {key} reading exists", src),
                    Count(f"allan.{fig}.{key}.missing", int((~read).sum()),
                          f"replicates without a {key} reading (no run of the local slope "
                          "within its tolerance)", src),
                    Count(f"allan.{fig}.{key}.ci_covers", int(np.sum(read & (lo <= tv)
                                                                     & (tv <= hi))),
                          f"replicates whose {key} reading's 95 % interval holds the truth "
                          f"{tv:g}", src)]
    src = sources["intervals"]
    kinds = [c[:-4] for c in intervals.columns if c.endswith("_low")]
    out.append(Count("allan.intervals.n", int(intervals.replicate.nunique()),
                     "replicates of the Remark 4.3 interval study", src))
    for kind in kinds:
        for mk, d in intervals.groupby("m", sort=True):
            lo, hi = d[f"{kind}_low"].to_numpy(float), d[f"{kind}_high"].to_numpy(float)
            tv = d.true_av.to_numpy(float)
            p = f"allan.intervals.{kind}.m{int(mk)}"
            out += [Count(f"{p}.low_le_0", int(np.sum(lo <= 0.0)),
                          f"replicates whose {kind} interval at m = {int(mk)} has a lower bound "
                          "<= 0", src),
                    Count(f"{p}.covered", int(np.sum((lo <= tv) & (tv <= hi))),
                          f"replicates whose {kind} interval at m = {int(mk)} holds the exact AV",
                          src)]
    src = sources["moav"]
    for (n, mk), d in moav.groupby(["n_samples", "m"], sort=True):
        tv = float(model_av("WN+RW", FIG42, int(mk))[0])
        err = np.abs(d.av_hat.to_numpy(float) - tv)
        for kind in ("exact", "lrv", "printed"):
            out.append(Count(f"allan.moav.T{int(n)}.m{int(mk)}.{kind}.covered",
                             int(np.sum(err <= d[f"half_{kind}"].to_numpy(float))),
                             f"replicates (of {len(d)}) whose Sec. 4.3.3 interval ({kind} "
                             f"half-width) at T = {int(n)}, m = {int(mk)} holds the exact AV",
                             src))
    if consistency is not None:
        src = sources["consistency"]
        truth = CONSISTENCY_MODEL[1]
        for (n, meth), d in consistency.groupby(["n_samples", "method"], sort=True):
            for par, tv in truth.items():
                dev = np.abs(d[par].to_numpy(float) / tv - 1.0)
                p = f"allan.consistency.T{int(n)}.{meth}.{_pname(par)}"
                out += [Count(f"{p}.n", len(d), "replicates", src),
                        Count(f"{p}.within1pct", int(np.sum(dev <= 0.01)),
                              f"replicates whose {meth} {par} is within 1 % of the truth", src),
                        Count(f"{p}.off10pct", int(np.sum(dev > 0.1)),
                              f"replicates whose {meth} {par} is more than 10 % off the truth",
                              src)]
    return out


def _pname(name: str) -> str:
    return name.replace("[", "").replace("]", "")
