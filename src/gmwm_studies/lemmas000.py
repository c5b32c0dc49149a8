"""Paper 000's lemmas and remark, checked: Lemma 1 (the sinusoid's WV), Lemma 2 (its
identifiability), Remark A (efficient weights), and the paired bootstrap behind Fig 9's verdict.

* :func:`lemma1_exact`: the library's SIN WV (``Sinusoid.wv``, the sin^4 form) against the paper's
  closed form ``alpha^2 (1 - cos(beta tau / 2))^2 / (tau^2 (1 - cos beta))`` in 60-digit mpmath, and
  against ``alpha^2 / 2 |H_j(beta)|^2`` with the Haar filter's response summed term by term
  (float64, ``tau <= 2^14``). Relative errors; ``tau`` = 2^j samples.
* :func:`lemma1_rate`: the empirical WV of a random-phase sinusoid against its closed form over
  ``T = 2^12 .. 2^20``: per level the mean over replicates of ``|nu_hat - nu|`` times ``T``
  (bounded if the error is O_p(1/T)), and the log-log slope of the mean error on T with a
  bootstrap interval (resampling replicates within each T).
* :func:`lemma2_jacobian`: the model WV's Jacobian in relative units (d log nu_j / d log theta_k)
  at a point: singular values, condition number, and per sinusoid the cosine of the angle between
  its alpha and beta columns (1 = the two are confounded: only alpha * beta acts on the WV).
* :func:`lemma2_ridge`: for fits on a sinusoid's alpha-beta ridge (``gmwm_studies.counts``
  ``RIDGE_FACTOR``), the fit is redone from the replicate's seed (its objective must equal the
  table's) and its own objective is evaluated along the ridge ``alpha * beta = const`` and at the
  truth: relative objective increase ``Q / Q_fit - 1``.
* :func:`efficiency`: two estimators of the same replicates (e.g. CI weights vs efficient
  weights): SD, RMSE and median |error| ratios with paired bootstrap intervals, factor-2 misses.
* :func:`sd_gap_bootstrap`: the SD gap ``1 - SD_b / SD_a`` per parameter and the differences of
  gaps, with paired bootstrap intervals.

Bootstrap intervals are percentile intervals (2.5 %, 97.5 %) from a seeded generator.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import mpmath
import numpy as np
import pandas as pd

from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.processes import Sinusoid
from gmwm.wv import wvar_many
from gmwm_studies.counts import RIDGE_FACTOR, factor2_off
from gmwm_studies.seeds import replicate_rng

__all__ = [
    "RIDGE_COLUMNS",
    "efficiency",
    "lemma1_exact",
    "lemma1_rate",
    "lemma2_jacobian",
    "lemma2_ridge",
    "ridge_rows",
    "ridge_study",
    "sd_gap_bootstrap",
    "write_tables",
]

_SIN = Sinusoid()
_CHUNK = 16


def _resolved(x: float, tol: float = 1e-12) -> float:
    """``x`` or 0 when |x| < tol: a relative objective change below float64 resolution (sums of
    22 squared residuals) is rounding, which would differ between runs in its last bits."""
    return 0.0 if abs(x) < tol else float(x)


def _boot_ci(x: np.ndarray) -> tuple[float, float]:
    return float(np.quantile(x, 0.025)), float(np.quantile(x, 0.975))


def _closed_form_mp(alpha: float, beta: float, tau: int) -> float:
    """The paper's (1 - cos) closed form at 60 digits."""
    with mpmath.workdps(60):
        a, b, t = mpmath.mpf(alpha), mpmath.mpf(beta), mpmath.mpf(tau)
        v = a**2 * (1 - mpmath.cos(b * t / 2)) ** 2 / (t**2 * (1 - mpmath.cos(b)))
        return float(v)


def _filter_wv(alpha: float, beta: float, tau: int) -> float:
    """alpha^2 / 2 |H(beta)|^2, H the Haar filter (+1/tau on tau/2 taps, -1/tau on the next)."""
    k = np.arange(tau)
    h = np.where(k < tau // 2, 1.0, -1.0) / tau
    resp = np.sum(h * np.exp(-1j * beta * k))
    return float(alpha**2 / 2 * abs(resp) ** 2)


def lemma1_exact(cases: Mapping[str, Sequence[float]], levels: int, filter_levels: int = 14
                 ) -> pd.DataFrame:
    """One row per case (name -> (alpha, beta)) and level j = 1..levels."""
    rows = []
    for name, (alpha, beta) in cases.items():
        tau = 2.0 ** np.arange(1, levels + 1)
        lib = _SIN.wv(np.array([alpha, beta]), tau)
        for j in range(1, levels + 1):
            t = 2**j
            cf = _closed_form_mp(alpha, beta, t)
            fl = _filter_wv(alpha, beta, t) if j <= filter_levels else math.nan
            v = float(lib[j - 1])
            rows.append({"case": name, "alpha": alpha, "beta": beta, "level": j, "tau": t,
                         "library": v, "closed_form": cf,
                         "rel_err_closed_form": abs(v - cf) / cf if cf > 0 else abs(v - cf),
                         "filter": fl,
                         "rel_err_filter": abs(v - fl) / fl if fl > 0 else abs(v - fl)})
    return pd.DataFrame(rows)


def lemma1_rate(cases: Mapping[str, Sequence[float]], log2_T: Sequence[int], levels: int,
                replicates: int, seed: int, n_boot: int = 1000
                ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(detail, slopes) of the empirical WV's error for random-phase sinusoids.

    With W_{j,t} = alpha |H_j| sin(beta t + phase), nu_hat_j - nu_j = -nu_j / M_j
    sum_t cos(2 beta t + phase'), so |nu_hat_j - nu_j| <= nu_j / (M_j |sin beta|) for every phase
    (the bound ``bound``: T x error stays below nu_j T / (M_j |sin beta|) ~ nu_j / |sin beta|) and
    E|nu_hat_j - nu_j| = (2 / pi) nu_j |sin(M_j beta)| / (M_j |sin beta|) (``exact_mean``); M_j =
    T - 2^j + 1. detail: per case, T and level, the Monte Carlo mean |error| with its SE, z against
    the exact mean, T x mean |error|, the largest |error| / bound over replicates. slopes: per
    case and level, the log-log slope on T of the mean |error| (``slope``: oscillates with
    |sin(M_j beta)|) and of the mean |error| / |sin(M_j beta)| (``slope_normalized``: the 1/T rate
    itself), each with a bootstrap interval (replicates resampled within each T)."""
    if min(log2_T) - 1 < levels:
        raise InputError(f"levels {levels} needs T >= 2^{levels + 1}; got 2^{min(log2_T)}")
    detail, slopes = [], []
    for ci, (name, (alpha, beta)) in enumerate(cases.items()):
        p = np.array([alpha, beta], dtype=float)
        tau = 2 ** np.arange(1, levels + 1)
        nu = _SIN.wv(p, tau.astype(float))
        Ts = np.array([2**lt for lt in log2_T])
        E = np.empty((len(Ts), replicates, levels))  # |error|
        for i, T in enumerate(Ts):
            t = np.arange(1, T + 1, dtype=float)
            for r0 in range(0, replicates, _CHUNK):  # _CHUNK signals in memory at a time
                rs = range(r0, min(r0 + _CHUNK, replicates))
                X = np.empty((len(rs), T))
                for i_r, r in enumerate(rs):
                    rng = replicate_rng(f"lemmas000/lemma1/{name}", int(T), r, seed)
                    X[i_r] = alpha * np.sin(beta * t + rng.uniform(0, 2 * np.pi))
                E[i, r0:r0 + len(rs)] = np.abs(wvar_many(X, levels=levels) - nu)
        M = Ts[:, None] - tau[None, :] + 1  # (nT, levels)
        osc = np.abs(np.sin(M * beta))
        bound = nu[None, :] / (M * abs(math.sin(beta)))
        exact = 2 / np.pi * bound * osc
        mean = E.mean(axis=1)
        se = E.std(axis=1, ddof=1) / math.sqrt(replicates)
        worst = (E / bound[:, None, :]).max(axis=1)
        for i, T in enumerate(Ts):
            for j in range(levels):
                detail.append({
                    "case": name, "T": int(T), "level": j + 1, "nu": float(nu[j]),
                    "mean_abs_err": float(mean[i, j]), "mc_se": float(se[i, j]),
                    "exact_mean_abs_err": float(exact[i, j]),
                    "z": float((mean[i, j] - exact[i, j]) / se[i, j]) if se[i, j] > 0 else 0.0,
                    "T_x_mean_abs_err": float(T * mean[i, j]),
                    "T_x_bound": float(T * bound[i, j]),
                    "max_err_over_bound": float(worst[i, j])})
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(ci,)))
        idx = rng.integers(0, replicates, size=(len(Ts), n_boot, replicates))
        bmean = np.stack([E[i][idx[i]].mean(axis=1) for i in range(len(Ts))])  # (nT, B, levels)
        lt = np.log(Ts.astype(float))
        for j in range(levels):
            row: dict[str, Any] = {"case": name, "alpha": alpha, "beta": beta, "level": j + 1}
            for key, y, yb in (("slope", mean[:, j], bmean[:, :, j]),
                               ("slope_normalized", mean[:, j] / osc[:, j],
                                bmean[:, :, j] / osc[:, j, None])):
                row[key] = float(np.polyfit(lt, np.log(y), 1)[0])
                bs = np.polyfit(lt, np.log(yb), 1)[0]
                row[f"{key}_ci_low"], row[f"{key}_ci_high"] = _boot_ci(bs)
            txe = Ts * mean[:, j]
            row["T_x_err_min"], row["T_x_err_max"] = float(txe.min()), float(txe.max())
            row["T_x_bound_max"] = float((Ts * bound[:, j]).max())
            row["max_err_over_bound"] = float(worst[:, j].max())
            row["max_abs_z"] = float(np.max(np.abs((mean[:, j] - exact[:, j]) / se[:, j])))
            slopes.append(row)
    return pd.DataFrame(detail), pd.DataFrame(slopes)


def lemma2_jacobian(model_spec: str, points: Mapping[str, Mapping[str, float]], levels: int
                    ) -> pd.DataFrame:
    """Relative Jacobian d log nu / d log theta at each named point (parameter name -> value):
    rank (singular values above 1e-10 of the largest), condition number, smallest singular value,
    and per SIN the |cosine| between its alpha and beta columns."""
    m = Model(model_spec)
    tau = 2.0 ** np.arange(1, levels + 1)
    rows = []
    for point, values in points.items():
        theta = m.theta(dict(values))
        nu = m.wv(theta, tau)
        Jrel = m.jacobian(theta, tau) * theta[None, :] / nu[:, None]
        s = np.linalg.svd(Jrel, compute_uv=False)
        rank = int(np.sum(s > 1e-10 * s[0]))
        base = {"model": model_spec, "point": point, "levels": levels}
        rows.append({**base, "quantity": "rank", "value": rank})
        rows.append({**base, "quantity": "n_params", "value": theta.size})
        # below the rank tolerance the smallest singular value is rounding noise (it moves with
        # the last bits of a ridge fit's WV): reported as 0, the condition number as inf
        sv_min = float(s[-1]) if rank == s.size else 0.0
        rows.append({**base, "quantity": "sv_min", "value": sv_min})
        rows.append({**base, "quantity": "condition",
                     "value": float(s[0] / sv_min) if sv_min > 0 else math.inf})
        names = m.param_names if hasattr(m, "param_names") else list(m.as_dict(theta))
        for k in range(1, m.count("SIN") + 1):
            ia, ib = names.index(f"SIN[{k}].alpha"), names.index(f"SIN[{k}].beta")
            a, b = Jrel[:, ia], Jrel[:, ib]
            cos = abs(float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b))))
            rows.append({**base, "quantity": f"SIN[{k}].cos_alpha_beta", "value": cos})
            rows.append({**base, "quantity": f"SIN[{k}].beta_tau_J",
                         "value": float(values[f"SIN[{k}].beta"] * tau[-1])})
    return pd.DataFrame(rows)


def ridge_rows(table: pd.DataFrame, J: int, estimators: Sequence[str]) -> pd.DataFrame:
    """Converged fits with a SIN on the alpha-beta ridge (period 2 pi / beta > RIDGE_FACTOR 2^J),
    with columns ``sin`` (its index k), ordered by estimator, k and decreasing alpha."""
    out = []
    conv = table[(table["converged"] == 1) & table["estimator"].isin(list(estimators))]
    k = 1
    while f"SIN[{k}].beta" in table.columns:
        b = conv[f"SIN[{k}].beta"].to_numpy(float)
        with np.errstate(divide="ignore"):
            period = np.where(b > 0, 2 * np.pi / np.where(b > 0, b, 1.0), np.inf)
        sel = conv[np.isfinite(b) & (period > RIDGE_FACTOR * 2.0**J)].copy()
        sel["sin"] = k
        out.append(sel.sort_values(["estimator", f"SIN[{k}].alpha"], ascending=[True, False]))
        k += 1
    return pd.concat(out) if out else table.iloc[:0]


def lemma2_ridge(problem: Any, theta_fit: np.ndarray, sin: int, truth: Mapping[str, float],
                 betas: np.ndarray) -> pd.DataFrame:
    """Objective of ``problem`` (a ``gmwm.inference.Problem``) along the ridge alpha * beta =
    alpha_fit * beta_fit of SIN[sin], the other parameters at the fit's: one row per beta, plus
    the point where only SIN[sin] is moved to the truth (``point = truth_sin``) and the whole
    truth (``point = truth``). ``rel_increase`` = Q / Q_fit - 1."""
    m = problem.model
    names = list(m.as_dict(theta_fit))
    ia, ib = names.index(f"SIN[{sin}].alpha"), names.index(f"SIN[{sin}].beta")
    q0 = float(problem.objective(theta_fit))
    c = float(theta_fit[ia] * theta_fit[ib])
    rows = []
    for b in betas:
        th = theta_fit.copy()
        th[ia], th[ib] = c / b, b
        q = float(problem.objective(th))
        rows.append({"point": "ridge", "alpha": c / b, "beta": float(b), "objective": q,
                     "rel_increase": _resolved(q / q0 - 1)})
    th = theta_fit.copy()
    th[ia], th[ib] = truth[f"SIN[{sin}].alpha"], truth[f"SIN[{sin}].beta"]
    tt = m.theta(dict(truth))
    for point, t in (("fit", theta_fit), ("truth_sin", th), ("truth", tt)):
        q = float(problem.objective(t))
        rows.append({"point": point, "alpha": float(t[ia]), "beta": float(t[ib]), "objective": q,
                     "rel_increase": _resolved(q / q0 - 1)})
    return pd.DataFrame(rows)


def efficiency(table: pd.DataFrame, truth: Mapping[str, float], base: str, other: str,
               seed: int, n_boot: int = 2000) -> pd.DataFrame:
    """Per parameter: SD, RMSE and median |error| (``mad``) of ``base`` and ``other`` on the
    replicates where both converged, their ratios other / base with paired bootstrap intervals,
    the SD ratio on the ``n_no_miss`` replicates where neither fit has a sinusoid off the truth
    by a factor 2 (``sd_no_miss_ratio``), and the factor-2 misses of each (the ``factor2_miss``
    rule of :mod:`gmwm_studies.counts`, over the same replicates)."""
    a = table[table["estimator"] == base].set_index("replicate")
    b = table[table["estimator"] == other].set_index("replicate")
    common = a.index.intersection(b.index)
    both = common[(a.loc[common, "converged"] == 1).to_numpy()
                  & (b.loc[common, "converged"] == 1).to_numpy()]
    if len(both) < 3:
        raise InputError(f"{base} and {other}: only {len(both)} replicates converged in both")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))
    idx = rng.integers(0, len(both), size=(n_boot, len(both)))
    # replicates where neither fit has a SIN off by a factor 2 (the identified bulk)
    sins = [p[:-len(".alpha")] for p in truth if p.startswith("SIN[") and p.endswith(".alpha")]
    hit = np.ones(len(both), bool)
    for d in (a, b):
        for k in sins:
            for q in (f"{k}.alpha", f"{k}.beta"):
                hit &= ~factor2_off(d.loc[both, q].to_numpy(float), truth[q])
    clean = np.flatnonzero(hit)
    cidx = rng.integers(0, len(clean), size=(n_boot, len(clean))) if len(clean) else None
    stats = {
        "sd": lambda e: e.std(ddof=1, axis=-1),
        "rmse": lambda e: np.sqrt(np.mean(e**2, axis=-1)),
        "mad": lambda e: np.median(np.abs(e), axis=-1),
    }
    rows = []
    for p, tv in truth.items():
        ea = a.loc[both, p].to_numpy(float) - tv
        eb = b.loc[both, p].to_numpy(float) - tv
        row: dict[str, Any] = {"parameter": p, "truth": tv, "n": len(both)}
        for s, f in stats.items():
            va, vb = float(f(ea)), float(f(eb))
            row[f"{s}_{base}"], row[f"{s}_{other}"] = va, vb
            row[f"{s}_ratio"] = vb / va if va > 0 else math.nan
            with np.errstate(divide="ignore", invalid="ignore"):
                lo, hi = _boot_ci(f(eb[idx]) / f(ea[idx]))
            row[f"{s}_ratio_ci_low"], row[f"{s}_ratio_ci_high"] = lo, hi
        row["n_no_miss"] = len(clean)
        if len(clean) > 2:
            ca, cb = ea[clean], eb[clean]
            with np.errstate(divide="ignore", invalid="ignore"):
                row["sd_no_miss_ratio"] = float(stats["sd"](cb) / stats["sd"](ca))
                lo, hi = _boot_ci(stats["sd"](cb[cidx]) / stats["sd"](ca[cidx]))
            row["sd_no_miss_ratio_ci_low"], row["sd_no_miss_ratio_ci_high"] = lo, hi
        row[f"factor2_{base}"] = int(np.sum(factor2_off(ea + tv, tv)))
        row[f"factor2_{other}"] = int(np.sum(factor2_off(eb + tv, tv)))
        rows.append(row)
    for k in sorted({int(p.split("[")[1].split("]")[0]) for p in truth if p.startswith("SIN[")}):
        pa, pb = f"SIN[{k}].alpha", f"SIN[{k}].beta"
        row = {"parameter": f"SIN[{k}] (alpha or beta)", "n": len(both)}
        for est, d in ((base, a), (other, b)):
            off = factor2_off(d.loc[both, pa], truth[pa]) | factor2_off(d.loc[both, pb], truth[pb])
            row[f"factor2_{est}"] = int(np.sum(off))
        rows.append(row)
    return pd.DataFrame(rows)


def sd_gap_bootstrap(table: pd.DataFrame, parameters: Sequence[str], base: str, other: str,
                     reference: str, seed: int, n_boot: int = 2000) -> pd.DataFrame:
    """SD gap ``1 - SD_other / SD_base`` [%] per parameter on the replicates where both
    converged, and ``gap(p) - gap(reference)`` [percentage points], with paired bootstrap
    intervals (the same resampled replicates for both estimators and every parameter)."""
    a = table[table["estimator"] == base].set_index("replicate")
    b = table[table["estimator"] == other].set_index("replicate")
    common = a.index.intersection(b.index)
    both = common[(a.loc[common, "converged"] == 1).to_numpy()
                  & (b.loc[common, "converged"] == 1).to_numpy()]
    A = a.loc[both, list(parameters)].to_numpy(float)
    B = b.loc[both, list(parameters)].to_numpy(float)
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(2,)))
    idx = rng.integers(0, len(both), size=(n_boot, len(both)))
    gap = 100 * (1 - B.std(ddof=1, axis=0) / A.std(ddof=1, axis=0))
    bgap = 100 * (1 - B[idx].std(ddof=1, axis=1) / A[idx].std(ddof=1, axis=1))
    iref = list(parameters).index(reference)
    rows = []
    for i, p in enumerate(parameters):
        lo, hi = _boot_ci(bgap[:, i])
        d = bgap[:, i] - bgap[:, iref]
        dlo, dhi = _boot_ci(d)
        rows.append({"parameter": p, "n": len(both), f"sd_{base}": float(A[:, i].std(ddof=1)),
                     f"sd_{other}": float(B[:, i].std(ddof=1)), "gap_pct": float(gap[i]),
                     "gap_ci_low": lo, "gap_ci_high": hi,
                     "diff_vs_reference_pp": float(gap[i] - gap[iref]),
                     "diff_ci_low": dlo, "diff_ci_high": dhi,
                     "share_gap_above_reference": float(np.mean(d > 0))})
    return pd.DataFrame(rows)


def ridge_study(table: pd.DataFrame, record: Mapping[str, Any], estimators: Mapping[str, Any],
                study: str, base_seed: int, simulator: str, betas: np.ndarray,
                max_fits: int, levels: int | None = None, log: Any = None
                ) -> tuple[pd.DataFrame, dict[str, dict[str, float]]]:
    """Ridge profiles (:func:`lemma2_ridge`) of up to ``max_fits`` ridge fits of a study's
    per-replicate table (``record``: its truth JSON), each redone as the pipeline did it (the
    replicate's WV from :func:`gmwm_studies.montecarlo.simulate_wv_chunk` with ``simulator`` and
    ``levels``, the fit's starts from stream 1 of its seed, its estimator's settings).

    Columns ``table_objective``, ``refit_objective`` and ``matches_table`` (relative 1e-6) say
    whether the refit is the table's fit; a mismatch (a table made by other code or another
    simulator) is logged as a warning and the profile is then the refit's. Returns the profile
    rows and the refits' estimates (for :func:`lemma2_jacobian`), keyed ``rep<id>_<estimator>``."""
    from gmwm.estimator import fit
    from gmwm.inference import Problem
    from gmwm.wv import WaveletVariance
    from gmwm_studies.montecarlo import STUDY_WV_CI, estimator_settings, simulate_wv_chunk
    from gmwm_studies.seeds import replicate_seed

    truth = dict(record["truth"])
    J, T, spec = int(record["J"]), int(record["T"]), str(record["model"])
    rows, points = [], {}
    for _, r in ridge_rows(table, J, list(estimators)).head(max_fits).iterrows():
        est, rep, k = str(r["estimator"]), int(r["replicate"]), int(r["sin"])
        chunk = simulate_wv_chunk(spec, truth, T, [rep], study, base_seed, levels=levels,
                                  simulator=simulator)
        wv = WaveletVariance.from_table(chunk.scales, chunk.variances[0], n_samples=T, freq=1.0,
                                        ci=STUDY_WV_CI)
        res = fit(wv, Model(spec), settings=estimator_settings(estimators[est]),
                  seed=replicate_seed(study, T, rep, base_seed, stream=1))
        prob = Problem.of(res)
        theta = prob.model.canonical(np.asarray(res.params, dtype=float))  # the table's order
        q, q_table = float(prob.objective(theta)), float(r["objective"])
        match = math.isclose(q, q_table, rel_tol=1e-6)
        if not match and log:
            log.warning("%s replicate %d (%s): refit objective %.10g is not the table's %.10g "
                        "(table from other code or simulator than %r): profiling the refit",
                        study, rep, est, q, q_table, simulator)
        prof = lemma2_ridge(prob, theta, k, truth, betas)
        for col, val in (("matches_table", match), ("refit_objective", q),
                         ("table_objective", q_table), ("sin", k), ("estimator", est),
                         ("replicate", rep)):
            prof.insert(0, col, val)
        rows.append(prof)
        points[f"rep{rep}_{est}"] = prob.model.as_dict(theta)
        if log:
            log.info("%s rep %d (%s) SIN[%d]: objective %.6g (table %.6g)", study, rep, est, k,
                     q, q_table)
    return (pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=RIDGE_COLUMNS)
            ), points


RIDGE_COLUMNS = ["replicate", "estimator", "sin", "table_objective", "refit_objective",
                 "matches_table", "point", "alpha", "beta", "objective", "rel_increase"]
"""Columns of the ridge profile table (:func:`ridge_study`)."""


def write_tables(tables: Mapping[str, pd.DataFrame], outdir: str, titles: Mapping[str, str]
                 ) -> list[str]:
    """Each table as ``<outdir>/<name>.csv`` (full precision) and ``.md`` (4 digits, with its
    title), atomically; returns the paths written."""
    import os

    from gmwm_studies.montecarlo import write_table

    out = []
    for name, df in tables.items():
        csv, md = os.path.join(outdir, f"{name}.csv"), os.path.join(outdir, f"{name}.md")
        write_table(df, csv, md, title=titles.get(name))
        out += [csv, md]
    return out
