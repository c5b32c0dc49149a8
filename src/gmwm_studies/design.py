"""Design against estimator: what the asymptotic theory of each study's GMWM predicts at the
truth its Monte Carlo simulates from, beside what the replicates show.

For every parameter of Simulations 2 and 3, the two STIM-300 sensors and the Navchip axes
(their parametric bootstrap simulates from the fitted values, which are the truth here):

* the asymptotic SE of the estimator at the truth: the sandwich of :func:`gmwm.plan.predict`
  (docs/METHODS.md §5.9, §17.3) with the model's exact WV covariance at the study's length T and
  levels J, and the weights the estimator's Omega converges to (:func:`limit_weights`);
* the design's probability of the events the reports count, under a Gaussian limit:

  - ``p_le0``: an estimate at or below 0, for the scale parameter of each component (the one the
    ``at_boundary`` counts test). Computed on the scale on which the WV is linear in it: the
    parameter itself for a variance (sigma2, gamma2, Q2), its square for a DR slope omega or a
    SIN amplitude alpha (their WV is omega^2 tau^2 / 16, alpha^2 x ...), where the estimate
    y = p^2 is asymptotically N(y0, (2 p0 se)^2) (delta method), so P = Phi(-1 / (k rse)) with
    k = 1 or 2. A truth at 0 gives 1/2 (half of a Gaussian centred at the boundary).
  - ``p_factor2_normal``: off by more than a factor 2 (:func:`gmwm_studies.counts.factor2_off`)
    under N(theta, Sigma) on the parameter scale; ``p_factor2_lognormal``: the same under the
    delta method on the log scale, ln x ~ N(ln x0, rse^2). The two bracket what a Gaussian
    approximation can say (they differ most when rse is not small); neither is exact at finite T.
    For a sinusoid the joint event of the ``SIN<k>.factor2_miss`` counts (alpha or beta off) is
    drawn from the bivariate limit (:data:`N_DRAWS` draws, seeded).

* the observed count from the committed per-replicate table (the named counts of
  :mod:`gmwm_studies.counts`, same rules) and ``binom_p_*``: the two-sided exact binomial test
  of that count against the design probability (it carries the Monte Carlo error only, not the
  approximation's).

A design probability close to the observed share says the miss rate is the design's (any
consistent Gaussian estimator would show it); an observed share far above it is the estimator's
(multimodality, label switches, local optima).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from statistics import NormalDist
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from gmwm.atomic import write_text_atomic
from gmwm.errors import InputError
from gmwm_studies.counts import Count, draw_counts, factor2_off, study_counts, write_counts

__all__ = ["COLUMNS", "HIGHLIGHT", "N_DRAWS", "audit_counts", "design_counts", "limit_weights",
           "navchip_design", "render_markdown", "study_design", "write_design"]

N_DRAWS = 1_000_000
"""Draws from the bivariate Gaussian limit for the joint SIN factor-2 probability (MC SE below
5e-4 at any probability)."""

HIGHLIGHT: dict[str, tuple[tuple[str, str], ...]] = {
    # (fit or "*", component) per study: the components REPRODUCTION.md discusses
    "sim2": (("*", "SIN[2]"),),  # Fig 4: the slow sinusoid's factor-2 misses
    "sim3": (("*", "RW[1]"),),  # Fig 4: the RW at the boundary 0
    "stim300_gyro": (("*", "RW[1]"),),  # K (Figs 1-2, Sec. IV)
    "stim300_accel": (("*", "DR[1]"), ("*", "QN[1]")),  # R and Q at 0 (footnote stim)
    "navchip": (("*", "DR[1]"), ("gyroscope_X", "WN[1]"), ("gyroscope_X", "GM[1]"),
                ("gyroscope_X", "GM[2]"), ("gyroscope_X", "RW[1]")),  # Table 1, Fig 4
}

COLUMNS = ["study", "fit", "T", "J", "estimator", "weights", "parameter", "highlight", "truth",
           "se", "rse", "power", "p_le0", "observed_at_zero", "p_factor2_normal",
           "p_factor2_lognormal", "observed_factor2", "n", "binom_p_at_zero",
           "binom_p_factor2"]
"""Columns of asymptotic.csv. ``fit``: the Navchip axis (empty for the simulations); ``power``:
k of ``p_le0`` (module docstring); ``observed_*``: counts over the ``n`` converged fits;
``binom_p_*``: the two-sided exact binomial test of each observed count against its design
probability (``p_le0`` and ``p_factor2_normal``)."""

_PHI = NormalDist().cdf


def limit_weights(settings: Mapping[str, Any]) -> str | None:
    """The weights an estimator's Omega converges to at the truth, as :func:`gmwm.plan.predict`
    names them; None for an estimator that is not a GMWM (ARMAV, AVSM).

    ``efficient``: the inverse model covariance of the WV; re-weighting with the model WV
    (``reweight`` > 0): ``gaussian`` (eta_j / (2 nu_j^2)) at the model WV; otherwise the CI rule
    named in ``weights``, evaluated at the model WV."""
    from gmwm.settings import FitSettings

    if settings.get("method", "gmwm") != "gmwm":
        return None
    w = str(settings.get("weights", FitSettings().weights))
    if w == "efficient":
        return "efficient"
    if int(settings.get("reweight", 0) or 0) > 0:
        return "gaussian"
    return w


def _power(model: Any, comp: Any, theta: np.ndarray) -> int:
    """Degree k of the component's WV in its scale parameter (1 for a variance, 2 for a DR
    slope or a SIN amplitude), read off the process: nu(2 p) / nu(p) = 2^k."""
    p = np.array(theta[comp.slice], dtype=float)
    i = comp.process.scale_index
    p[i] = 1.0 if p[i] == 0 else p[i]
    tau = np.array([2.0, 4.0])
    nu1 = comp.process.wv(p, tau, model.freq)
    p[i] *= 2
    nu2 = comp.process.wv(p, tau, model.freq)
    return round(math.log2(float(nu2[0] / nu1[0])))


def _p_le0(rse: float, power: int, truth: float) -> float:
    if truth == 0:
        return 0.5
    if not math.isfinite(rse):
        return math.nan
    return _PHI(-1.0 / (power * rse)) if rse > 0 else 0.0


def _p_factor2(rse: float) -> tuple[float, float]:
    """(normal, lognormal) probability of a factor-2 miss for a relative SE ``rse``."""
    if not math.isfinite(rse):
        return math.nan, math.nan
    if rse == 0:
        return 0.0, 0.0
    normal = _PHI(-0.5 / rse) + _PHI(-1.0 / rse)  # x/x0 < 1/2 or > 2
    return normal, 2.0 * _PHI(-math.log(2.0) / rse)


def _joint_factor2(truth: np.ndarray, cov: np.ndarray, seed: int) -> tuple[float, float]:
    """P(any of the parameters off by a factor 2) under N(truth, cov) and under the log-scale
    delta-method limit N(ln truth, cov / (truth truth'))."""
    if not np.all(np.isfinite(cov)) or np.any(truth <= 0):
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    z = rng.multivariate_normal(np.zeros(truth.size), cov, size=N_DRAWS, method="eigh")
    off = np.zeros(N_DRAWS, bool)
    off_log = np.zeros(N_DRAWS, bool)
    for i in range(truth.size):
        off |= factor2_off(truth[i] + z[:, i], truth[i])
        # the same standard normal draw on the log scale: ln x = ln x0 + (z_i / x0)
        off_log |= factor2_off(truth[i] * np.exp(z[:, i] / truth[i]), truth[i])
    return float(off.mean()), float(off_log.mean())


def _binom_p(k: int | None, n: int, p: float) -> float:
    """Two-sided exact binomial test of ``k`` events in ``n`` against probability ``p``."""
    if k is None or not math.isfinite(p) or n <= 0:
        return math.nan
    if p <= 0 or p >= 1:
        return 1.0 if k == (0 if p <= 0 else n) else 0.0
    return float(binomtest(int(k), n, p).pvalue)


def _highlight(study: str, fit: str, comp: str) -> bool:
    return any(f in ("*", fit) and c == comp for f, c in HIGHLIGHT.get(study, ()))


def _rows(study: str, fit: str, T: int, J: int, estimator: str, weights: str, model: Any,
          truth: Mapping[str, float], estimates: pd.DataFrame, at_zero: Mapping[str, int | None],
          sin_observed: Mapping[int, int | None], seed: int) -> list[dict[str, Any]]:
    """Rows of one (study, fit, estimator): a prediction at the truth and the observed counts
    (``at_zero``: parameter -> count; ``sin_observed``: k -> the joint factor-2 count)."""
    from gmwm.plan import predict

    theta = np.array([float(truth[n]) for n in model.param_names])
    with np.errstate(divide="ignore", invalid="ignore"):  # relative SEs of a truth at 0
        pred = predict(model, theta, T, levels=J, weights=weights)
    n = len(estimates)
    out = []
    for comp in model.components:
        power = _power(model, comp, theta)
        for k, name in enumerate(model.param_names[comp.slice]):
            x0, se, rse = theta[comp.start + k], pred.se[name], pred.rse[name]
            is_scale = k == comp.process.scale_index
            pn, pl = _p_factor2(rse) if x0 != 0 else (math.nan, math.nan)
            f2 = int(np.sum(factor2_off(estimates[name], x0))) if x0 != 0 else None
            obs0 = at_zero.get(name) if is_scale else None
            p0 = _p_le0(rse, power, x0) if is_scale else math.nan
            out.append({
                "study": study, "fit": fit, "T": T, "J": J, "estimator": estimator,
                "weights": weights, "parameter": name,
                "highlight": _highlight(study, fit, comp.name), "truth": x0,
                "se": se if x0 != 0 else math.nan, "rse": rse if x0 != 0 else math.nan,
                "power": power if is_scale else None, "p_le0": p0, "observed_at_zero": obs0,
                "p_factor2_normal": pn, "p_factor2_lognormal": pl, "observed_factor2": f2,
                "n": n, "binom_p_at_zero": _binom_p(obs0, n, p0),
                "binom_p_factor2": _binom_p(f2, n, pn)})
        if comp.process.name == "SIN" and comp.name.startswith("SIN["):
            idx = np.arange(comp.start, comp.start + comp.process.n_params)
            kk = int(comp.name[4:-1])
            pn, pl = _joint_factor2(theta[idx], pred.cov[np.ix_(idx, idx)], seed + kk)
            obs = sin_observed.get(kk)
            out.append({
                "study": study, "fit": fit, "T": T, "J": J, "estimator": estimator,
                "weights": weights, "parameter": f"{comp.name} (alpha or beta)",
                "highlight": _highlight(study, fit, comp.name), "truth": math.nan,
                "se": math.nan, "rse": math.nan, "power": None, "p_le0": math.nan,
                "observed_at_zero": None, "p_factor2_normal": pn, "p_factor2_lognormal": pl,
                "observed_factor2": obs, "n": n, "binom_p_at_zero": math.nan,
                "binom_p_factor2": _binom_p(obs, n, pn)})
    return out


def study_design(study: str, df: pd.DataFrame, record: Mapping[str, Any],
                 estimators: Mapping[str, Mapping[str, Any]], *, label_T: bool = False,
                 seed: int = 0) -> list[dict[str, Any]]:
    """Rows of one Monte Carlo study at one T (per-replicate table ``df`` and its record, from
    :func:`gmwm_studies.replicates.read_replicates`) for each of its GMWM estimators
    (``estimators``: name -> settings of the config's ``estimators`` section)."""
    from gmwm.model import Model

    model = Model(str(record["model"]))  # per-sample parameters: the study's own model
    T, J = int(record["T"]), int(record["J"])
    truth = {str(k): float(v) for k, v in record["truth"].items()}
    counts = {c.name: c.value for c in study_counts(study, df, record, "", label_T=label_T)}
    out: list[dict[str, Any]] = []
    for est in dict.fromkeys(df["estimator"].astype(str)):
        weights = limit_weights(estimators.get(est, {"method": "?"}))
        if weights is None:
            continue
        sub = df[(df["estimator"].astype(str) == est) & df["converged"].astype(bool)]
        prefix = ".".join([study, *([f"T{T}"] if label_T else []), est])
        at_zero = {n: counts.get(f"{prefix}.at_boundary.{n.replace('[', '').replace(']', '')}")
                   for n in model.param_names}
        sin = {int(c.name[4:-1]): counts.get(f"{prefix}.SIN{c.name[4:-1]}.factor2_miss")
               for c in model.components if c.process.name == "SIN"}
        out += _rows(study, "", T, J, est, weights, model, truth, sub, at_zero, sin, seed)
    if not out:
        raise InputError(f"study {study}: no GMWM estimator among "
                         f"{sorted(set(df['estimator'].astype(str)))}")
    return out


def navchip_design(estimates: pd.DataFrame, draws: pd.DataFrame, model_spec: str,
                   settings: Mapping[str, Any], n_samples: int, levels: int, freq: float, *,
                   seed: int = 0) -> list[dict[str, Any]]:
    """Rows of the Navchip axes: the bootstrap simulates each axis from its fit (``estimates``,
    one row per fit) at the recording's length and levels and refits with the fit's settings;
    the observed counts are over its converged draws (``draws``, one row per fit and draw)."""
    from gmwm.model import Model

    weights = limit_weights(settings)
    if weights is None:
        raise InputError("navchip: the fit is not a GMWM; no sandwich to predict")
    model = Model(model_spec, freq=float(freq))
    out: list[dict[str, Any]] = []
    for _, row in estimates.iterrows():
        fit = str(row["fit"])
        truth = {n: float(row[n]) for n in model.param_names}
        d = draws[draws["fit"].astype(str) == fit]
        counts = {c.name: c.value for c in draw_counts(f"navchip.{fit}", d, truth, "")}
        at_zero = {n: counts.get(f"navchip.{fit}.{n.replace('[', '').replace(']', '')}"
                                 ".at_boundary") for n in model.param_names}
        ok = d[d["converged"].astype(bool)]
        out += _rows("navchip", fit, int(n_samples), int(levels), "gmwm", weights, model, truth,
                     ok, at_zero, {}, seed)
    return out


# ---------------------------------------------------------------------------------------------
# counts, files
# ---------------------------------------------------------------------------------------------


def _key(row: Mapping[str, Any], label_T: bool) -> str:
    p = str(row["parameter"]).split(" ")[0].replace("[", "").replace("]", "")
    if row["study"] == "navchip":
        return f"navchip.{row['fit']}.{p}"
    t = [f"T{row['T']}"] if label_T else []
    return ".".join([row["study"], *t, row["estimator"], p])


_QUANTITIES = {
    "truth": "truth the Monte Carlo simulates from",
    "se": "asymptotic SE at the truth (gmwm.plan.predict sandwich, the estimator's limit weights)",
    "rse": "asymptotic SE / truth",
    "p_le0": ("design probability of an estimate <= 0 (Gaussian limit on the scale where the WV "
              "is linear in the parameter)"),
    "observed_at_zero": "converged fits with the parameter at the boundary 0 (the counts' rule)",
    "observed_at_zero_share": "observed_at_zero / n",
    "p_factor2_normal": ("design probability of a factor-2 miss under N(theta, Sigma) "
                         "(SIN[k] alone: alpha or beta, by simulation)"),
    "p_factor2_lognormal": ("design probability of a factor-2 miss under the log-scale delta "
                            "method (SIN[k] alone: alpha or beta, by simulation)"),
    "observed_factor2": "converged fits off the truth by more than a factor 2 (counts.factor2_off)",
    "observed_factor2_share": "observed_factor2 / n",
    "n": "converged fits",
    "binom_p_at_zero": "P(count >= observed_at_zero) if p_le0 were exact (binomial)",
    "binom_p_factor2": "P(count >= observed_factor2) if p_factor2_normal were exact (binomial)",
}


def design_counts(rows: Sequence[Mapping[str, Any]], source: str) -> list[Count]:
    """Named numbers of the rows, for the count markers of REPRODUCTION.md. Names:
    ``<study>[.T<T>].<estimator>.<param>.<quantity>`` (``navchip.<sensor>_<axis>.<param>...``;
    ``T<T>`` for studies with several lengths; ``SIN<k>`` alone: the joint alpha-or-beta event)."""
    Ts: dict[str, set[int]] = {}
    for r in rows:
        Ts.setdefault(str(r["study"]), set()).add(int(r["T"]))
    out = []
    for r in rows:
        key = _key(r, len(Ts[str(r["study"])]) > 1)
        what = f"{r['parameter']} ({r['study']}{' ' + r['fit'] if r['fit'] else ''}, " \
               f"T = {r['T']}, {r['estimator']}, weights {r['weights']})"
        vals = dict(r)
        n = int(r["n"])
        for q in ("observed_at_zero", "observed_factor2"):
            v = r[q]
            vals[f"{q}_share"] = None if v is None or n == 0 else v / n
        for q, definition in _QUANTITIES.items():
            v = vals.get(q)
            if v is None or (isinstance(v, float) and not math.isfinite(v)):
                continue
            v = int(v) if q in ("observed_at_zero", "observed_factor2", "n") else float(v)
            out.append(Count(f"{key}.{q}", v, f"{definition}: {what}", source))
    return out


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, bool | np.bool_):
        return "yes" if v else ""
    if isinstance(v, int | np.integer):
        return str(int(v))
    return f"{float(v):.4g}"


def _observed(count: Any, n: int) -> str:
    if count is None or (isinstance(count, float) and not math.isfinite(count)):
        return ""
    return f"{int(count)}/{n} ({int(count) / n:.3g})" if n else str(int(count))


def render_markdown(df: pd.DataFrame) -> str:
    """asymptotic.md: the highlighted rows first, then every row."""
    head = ["study", "fit", "T", "estimator", "weights", "parameter", "truth", "rse",
            "P(<= 0)", "observed at 0", "P(factor 2) normal / lognormal", "observed factor 2"]

    def table(sub: pd.DataFrame) -> list[str]:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in sub.to_dict("records"):
            f2 = ("" if not math.isfinite(r["p_factor2_normal"]) else
                  f"{_fmt(r['p_factor2_normal'])} / {_fmt(r['p_factor2_lognormal'])}")
            cells = [r["study"], r["fit"], str(r["T"]), r["estimator"], r["weights"],
                     r["parameter"], _fmt(r["truth"]), _fmt(r["rse"]), _fmt(r["p_le0"]),
                     _observed(r["observed_at_zero"], r["n"]), f2,
                     _observed(r["observed_factor2"], r["n"])]
            lines.append("| " + " | ".join(cells) + " |")
        return lines

    text = [
        "# Design against estimator: asymptotic precision at the truth beside the replicates",
        "",
        ("Computed by the pipeline (rule `design`, `gmwm_studies.design`) from the committed "
         "per-replicate tables and the Navchip bootstrap draws; numbers quoted in "
         "REPRODUCTION.md link to [counts.md](counts.md). `rse`: the asymptotic SE at the truth "
         "(`gmwm.plan.predict`: sandwich with the model's exact WV covariance at the study's T and "
         "J, and the weights the estimator's Omega converges to: `ci-eta3` for the CI-weighted "
         "GMWM, `gaussian` for the re-weighted STIM-300 GMWM, `efficient` for the two-step one) "
         "over the truth. Navchip: the truth is each axis's fit, which its parametric bootstrap "
         "simulates from."),
        "",
        ("Design probabilities are Gaussian approximations, not exact finite-T probabilities: "
         "`P(<= 0)` is Phi(-1 / (k rse)) on the scale where the WV is linear in the parameter "
         "(k = 2 for a DR slope or a SIN amplitude, 1 for a variance; 1/2 for a truth at 0); "
         "`P(factor 2)` under N(theta, Sigma) (normal) and under the log-scale delta method "
         "(lognormal); for a sinusoid alone (alpha or beta) by simulation from the bivariate "
         f"limit ({N_DRAWS:,} draws). Observed: count / converged fits. An observed share far "
         "above the design's is the estimator's; the `binom_p_*` columns of "
         "[asymptotic.csv](asymptotic.csv) test each count against its design probability "
         "(exact binomial, two-sided: Monte Carlo error only, not the approximation's)."),
        "",
        "## Rows discussed in REPRODUCTION.md",
        "",
        *table(df[df["highlight"].astype(bool)]),
        "",
        "## Every parameter",
        "",
        *table(df),
        "",
    ]
    return "\n".join(text)


AUDIT_REL = 1e-9
"""An audit row describes a committed fit when their objectives agree to this (relative)."""
AUDIT_AT_BEST = 1e-6
"""A fit is at the best objective its audit found when it is above it by at most this
(relative); ``benchmarks/audit_sim2_misses.py`` uses the same threshold."""


def audit_counts(study: str, df: pd.DataFrame, truth: Mapping[str, float], audit: pd.DataFrame,
                 source: str, comp: str = "SIN[2]") -> list[Count]:
    """Counts of a multistart audit of one sinusoid's factor-2 misses (the table written by
    ``benchmarks/audit_sim2_misses.py``: per audited fit its objective, the best objective a
    hard search of the same objective found, and whether that best point has the sinusoid
    within 2x of the truth).

    Per estimator, names ``<study>.<estimator>.<SINk>.audit.<quantity>``: ``misses`` (converged
    fits off by a factor 2 in alpha or beta, the counts' rule), ``audited`` (misses with an audit
    row of the same objective, :data:`AUDIT_REL`), ``not_audited``, ``at_best`` (audited misses
    within :data:`AUDIT_AT_BEST` of the best found: the objective's own minimum as far as the
    search can tell), ``local`` (the others: the search stopped short), ``local_within_2x``
    (local misses whose better optimum has the sinusoid within 2x), ``share_at_best``
    (at_best / audited) and ``local_excess_min`` / ``_max`` (objective / best - 1)."""
    key = comp.replace("[", "").replace("]", "")
    out = []
    for est, e in df[df["converged"].astype(bool)].groupby("estimator", sort=True):
        off = (factor2_off(e[f"{comp}.alpha"], truth[f"{comp}.alpha"])
               | factor2_off(e[f"{comp}.beta"], truth[f"{comp}.beta"]))
        miss = e[off]
        a = audit[audit["estimator"] == est].set_index("replicate")
        rows = a.reindex(miss["replicate"].to_numpy())
        same = (rows["objective"].to_numpy() / miss["objective"].to_numpy() - 1)
        audited = np.abs(same) < AUDIT_REL
        excess = miss["objective"].to_numpy() / rows["best_objective"].to_numpy() - 1
        at_best = audited & (excess <= AUDIT_AT_BEST)
        local = audited & ~at_best
        within = local & (rows["best_sin2_within_2x"].fillna(0).to_numpy().astype(bool))
        n_aud = int(audited.sum())
        name = f"{study}.{est}.{key}.audit"
        what = f"{comp} ({study}, {est})"
        vals = [("misses", int(off.sum()), ("converged fits off the truth by more than a factor 2 "
                 "in alpha or beta")),
                ("audited", n_aud, "misses whose fit the audit searched (same objective)"),
                ("not_audited", int(len(miss) - n_aud), "misses with no audit of their fit"),
                ("at_best", int(at_best.sum()), ("audited misses at the best objective the "
                 "audit's search found (within 1e-6 relative)")),
                ("local", int(local.sum()), ("audited misses above a better optimum the search "
                 "found")),
                ("local_within_2x", int(within.sum()), ("local misses whose better optimum has "
                 "the sinusoid within 2x of the truth")),
                ("share_at_best", at_best.sum() / n_aud if n_aud else None,
                 "at_best / audited")]
        if local.any():
            vals += [("local_excess_min", float(excess[local].min()),
                      "smallest objective / best - 1 of the local misses"),
                     ("local_excess_max", float(excess[local].max()),
                      "largest objective / best - 1 of the local misses")]
        out += [Count(f"{name}.{q}", v, f"{d}: {what}", source) for q, v, d in vals]
    return out


def write_design(rows: Iterable[Mapping[str, Any]], csv_path: str, md_path: str,
                 counts_json: str, counts_md: str,
                 extra: Sequence[Count] = ()) -> pd.DataFrame:
    """Write asymptotic.csv / .md and the counts of the rows (counts.json / .md beside them),
    with ``extra`` counts (the audits') after them."""
    import os

    rows = list(rows)
    df = pd.DataFrame(rows, columns=COLUMNS)
    for c in ("observed_at_zero", "observed_factor2", "power"):
        df[c] = df[c].astype("Int64")
    write_text_atomic(csv_path, df.to_csv(index=False, float_format="%.6g"))
    write_text_atomic(md_path, render_markdown(df))
    src = os.path.relpath(os.path.abspath(csv_path), os.path.dirname(os.path.abspath(counts_md)))
    write_counts([*design_counts(rows, src), *extra], counts_json, counts_md,
                 title="Design numbers quoted in the reports")
    return df
