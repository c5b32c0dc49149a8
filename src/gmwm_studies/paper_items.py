"""Paper items checked by computation over committed tables (issue 42 item 1): rule ``paper_items``.

REPRODUCTION.md quotes these numbers as links into ``reports/paper_items/paper_items.json``
(``[18.18](paper_items/paper_items.json#p004/lemma1/det_printed)``); ``paper_items.md`` beside it
renders the same numbers with their definitions. Nothing here runs a fit: every number is either
exact arithmetic on a paper's printed formula or a count / statistic over the committed STIM-300
and SVO tables, so the rule costs seconds.

* ``p004/lemma1``: [GMWFM] Lemma 1's Jacobian of the first five AV levels with respect to
  (Q^2, sigma^2, B^2, gamma^2, omega^2), rows j = 1..5 of
  c (3/2^(2j), 1/2^j, 2 ln 2 / pi, 2^j / 3, 2^(2j-1)), and its determinant with the (1,1) entry as
  printed (3/2) and as the Lemma's own formula gives it (3/4), for c = 1 (AV) and c = 1/2 (WV).
* ``p004/sample_size``: short (T = 2.5e6) -> long (6.3e6) for each GMWFM estimator (GMWM and both
  ARMAVs; the AVSM is the paper's reference, not a GMWFM estimator), each sensor and parameter:
  does the SD fall, does the RMSE fall, how does |bias| move in its Monte Carlo SE (the table's
  cells, Table I units).
* ``p004/cor1``: weighted ARMAV / GMWM RMSE over the 12 cells (Corollary 1: both asymptotically
  efficient, hence equal RMSEs).
* ``p004/fig1``: cells where the GMWM's and the weighted ARMAV's relative SDs print the same at
  3 significant digits; with the OLS ARMAV as the paper's ARMAV (``ols_reading``), the cells
  where the GMWM has the lowest |bias| / SD of the three and where the ARMAV's RMSE is below
  the AVSM's.
* ``p004/bias``: Sec. III's bias argument (f(x) = x has the smaller bias): |bias| of each ARMAV
  against the GMWM's per cell, the excess in units of the GMWM's SD, and the signed bias
  difference on the same replicates (per-replicate tables, Table I units) over its paired Monte
  Carlo SE (keys ``<gyro|accel>.<Q|N|K|R>.T<T>``).
* ``p003/theorems``: [SVO] Theorems 1-2 (consistency, asymptotic normality of c-hat) as far as one
  sample size shows them: mean - c0 in Monte Carlo SEs over the 1000 coverage replications
  (omega_2) and the 50 training arrays (omega_1, omega_2, RDVG against c_RDVG at the true Q).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm.errors import InputError
from gmwm_studies import sensors as units  # Table I units
from gmwm_studies.replicates import read_replicates

__all__ = ["GMWFM", "jacobian_lemma1", "lemma1", "stim300_items", "svo_theorems", "write_items"]

#: The GMWFM estimators of paper 004's Monte Carlo (the AVSM is its reference, not a GMWFM).
GMWFM = ("gmwm_cf", "armav", "armav_ols")
#: [GMWFM] Sec. IV's short and long signals (Table I).
LONG_SHORT = (2_500_000, 6_300_000)


def jacobian_lemma1(entry11: float = 0.75, c: float = 1.0) -> np.ndarray:
    """[GMWFM] Lemma 1's 5 x 5 Jacobian of v_j, j = 1..5, w.r.t. (Q^2, sigma^2, B^2, gamma^2,
    omega^2) from the Lemma's formula, with the (1,1) entry replaced by ``entry11`` (printed: 3/2;
    the formula: 3/4). ``c`` = 1 for the AV, 1/2 for the Haar WV (the Lemma's Remark A)."""
    a = 2.0 * math.log(2.0) / math.pi
    rows = [[3.0 / 4.0**j, 1.0 / 2.0**j, a, 2.0**j / 3.0, 2.0 ** (2 * j - 1)] for j in range(1, 6)]
    jac = c * np.array(rows, dtype=float)
    jac[0, 0] = c * entry11
    return jac


def lemma1() -> dict[str, Any]:
    """Determinants of Lemma 1's Jacobian under both readings of its (1,1) entry."""
    unit = math.log(2.0) / (1024.0 * math.pi)  # the paper writes det = c^5 * N ln 2 / (1024 pi)
    out: dict[str, Any] = {"entry11_printed": 1.5, "entry11_formula": 0.75}
    for name, e in (("printed", 1.5), ("formula", 0.75)):
        for c, suffix in ((1.0, ""), (0.5, "_wv")):
            d = float(np.linalg.det(jacobian_lemma1(e, c)))
            out[f"det_{name}{suffix}"] = d
        out[f"det_{name}_over_unit"] = out[f"det_{name}"] / unit  # the integer N of the paper's form
    out["paper_numerator"] = 84357
    out["formula_entry_from_j1"] = 3.0 / 2.0**2
    return out


def _table(path: str | os.PathLike) -> pd.DataFrame:
    if not os.path.isfile(path):
        raise InputError(f"STIM-300 table not found: {path}")
    return pd.read_csv(path)


def _cell(df: pd.DataFrame, est: str, T: int, param: str, col: str) -> float:
    sel = df[(df.estimator == est) & (df.n_samples == T) & (df.parameter == param)]
    if len(sel) != 1:
        raise InputError(f"STIM-300 table: {len(sel)} rows for {est}, T={T}, {param}")
    return float(sel[col].iloc[0])


def _paired_bias(replicates: Mapping[tuple[str, int], str | os.PathLike], sensor: str, T: int,
                 param: str, est: str, ref: str = "gmwm_cf") -> dict[str, float]:
    """|error| difference on the same replicates: mean(est - truth) - mean(ref - truth) in Table I
    units and its Monte Carlo SE (paired; converged fits of both only)."""
    df, record = read_replicates(replicates[(sensor, T)])
    freq = float(record["freq"])
    truth = units.to_table_units(param, abs(float(record["truth"][param])), sensor, freq)

    def err(e: str) -> pd.Series:
        sub = df[(df.estimator == e) & (df.converged == 1)].set_index("replicate")[param]
        return pd.Series(units.to_table_units(param, np.abs(sub.to_numpy(float)), sensor, freq),
                         index=sub.index) - truth

    a, b = err(est), err(ref)
    common = a.index.intersection(b.index)
    d = (a[common] - b[common]).to_numpy()
    if len(d) < 2:
        raise InputError(f"{replicates[(sensor, T)]}: fewer than 2 replicates where both {est} "
                         f"and {ref} converged")
    return {"bias_diff": float(d.mean()), "mc_se_diff": float(d.std(ddof=1) / math.sqrt(len(d))),
            "n_paired": len(d)}


def stim300_items(tables: Mapping[str, str | os.PathLike],
                  replicates: Mapping[tuple[str, int], str | os.PathLike] | None = None,
                  lengths: Sequence[int] = LONG_SHORT) -> dict[str, Any]:
    """Sample-size, Corollary 1 and bias items over the STIM-300 tables (``tables``: gyro /
    accel -> ``stim300_<sensor>_bias_sd_rmse.csv``; ``replicates``: (sensor name of the table,
    T) -> per-replicate CSV, for the paired bias differences, omitted: none; ``lengths``: the
    (short, long) sample sizes)."""
    if len(lengths) != 2 or lengths[0] >= lengths[1]:
        raise InputError(f"STIM-300 lengths: need (short, long), got {list(lengths)}")
    cells, cor1, bias, fig1 = [], [], [], []
    for sensor, path in tables.items():
        df = _table(path)
        sname = str(df["sensor"].iloc[0])
        for param in dict.fromkeys(df["parameter"]):
            sym = str(df[df.parameter == param]["symbol"].iloc[0])
            for est in GMWFM:
                sd0, sd1 = (_cell(df, est, T, param, "sd") for T in lengths)
                r0, r1 = (_cell(df, est, T, param, "rmse") for T in lengths)
                b0, b1 = (abs(_cell(df, est, T, param, "bias")) for T in lengths)
                se = math.hypot(*(_cell(df, est, T, param, "mc_se_bias") for T in lengths))
                cells.append({"sensor": sensor, "symbol": sym, "parameter": param,
                              "estimator": est, "sd_short": sd0, "sd_long": sd1,
                              "rmse_short": r0, "rmse_long": r1, "sd_falls": sd1 < sd0,
                              "rmse_falls": r1 < r0, "abs_bias_short": b0, "abs_bias_long": b1,
                              # the change of |bias| in its Monte Carlo SE (independent runs)
                              "abs_bias_change_z": (b1 - b0) / se if se > 0 else math.nan})
            for T in lengths:
                g = _cell(df, "gmwm_cf", T, param, "rmse")
                cor1.append(_cell(df, "armav", T, param, "rmse") / g)
                # Fig. 1: are the two relative SDs the same number at 3 significant digits?
                rg, ra = (_cell(df, e, T, param, "rel_sd") for e in ("gmwm_cf", "armav"))
                # and, with the OLS ARMAV as the paper's ARMAV, who has the lowest |bias| / SD,
                # and does the ARMAV or the AVSM have the lower RMSE ("alternating")
                three = ("gmwm_cf", "armav_ols", "avsm")
                ab = [abs(_cell(df, e, T, param, "bias")) for e in three]
                sd = [_cell(df, e, T, param, "sd") for e in three]
                fig1.append({"equal_3sig": f"{rg:.3g}" == f"{ra:.3g}",
                             "gmwm_lowest_abs_bias": ab[0] < min(ab[1:]),
                             "gmwm_lowest_sd": sd[0] < min(sd[1:]),
                             "armav_ols_rmse_below_avsm": _cell(df, "armav_ols", T, param, "rmse")
                             < _cell(df, "avsm", T, param, "rmse")})
                row: dict[str, Any] = {"sensor": sensor, "symbol": sym, "T": T,
                                       "abs_bias_gmwm": abs(_cell(df, "gmwm_cf", T, param, "bias"))}
                sd_g = _cell(df, "gmwm_cf", T, param, "sd")
                for est in ("armav", "armav_ols"):
                    b = _cell(df, est, T, param, "bias")
                    row[f"abs_bias_{est}"] = abs(b)
                    # the |bias| excess in units of the GMWM's SD: how much it can weigh in RMSE
                    row[f"{est}_excess_over_sd"] = (abs(b) - row["abs_bias_gmwm"]) / sd_g
                    if replicates is not None:
                        # signed bias difference on the same replicates, in its paired MC SE
                        p = _paired_bias(replicates, sname, T, param, est)
                        row[f"{est}_minus_gmwm_bias"] = p["bias_diff"]
                        # identical estimates on every replicate: no difference to weigh
                        row[f"{est}_minus_gmwm_z"] = (p["bias_diff"] / p["mc_se_diff"]
                                                      if p["mc_se_diff"] > 0 else math.nan)
                bias.append(row)
    sample = {"cells": len(cells),
              "sd_falls": sum(c["sd_falls"] for c in cells),
              "rmse_falls": sum(c["rmse_falls"] for c in cells),
              "both_fall": sum(c["sd_falls"] and c["rmse_falls"] for c in cells),
              "abs_bias_falls": sum(c["abs_bias_long"] < c["abs_bias_short"] for c in cells),
              "abs_bias_grows_beyond_2se": sum(c["abs_bias_change_z"] > 2 for c in cells),
              "per_cell": cells}
    out_bias: dict[str, Any] = {"cells": len(bias), "per_cell": bias}
    for est in ("armav", "armav_ols"):
        out_bias[f"{est}_larger"] = sum(b[f"abs_bias_{est}"] > b["abs_bias_gmwm"] for b in bias)
        out_bias[f"{est}_max_excess_over_sd"] = max(b[f"{est}_excess_over_sd"] for b in bias)
        # the weakest paired evidence among the cells where the ARMAV's |bias| is the larger
        zs = [abs(b[f"{est}_minus_gmwm_z"]) for b in bias
              if b[f"abs_bias_{est}"] > b["abs_bias_gmwm"] and f"{est}_minus_gmwm_z" in b]
        out_bias[f"{est}_min_abs_z_where_larger"] = min(zs) if zs else math.nan
    for b in bias:
        out_bias[f"{b['sensor']}.{b['symbol']}.T{b['T']}"] = b
    return {"sample_size": sample,
            "cor1": {"cells": len(cor1), "rmse_ratio_min": min(cor1), "rmse_ratio_max": max(cor1)},
            "fig1": {"cells": len(fig1),
                     "rel_sd_equal_3sig": sum(f["equal_3sig"] for f in fig1),
                     "ols_reading": {k: sum(f[k] for f in fig1) for k in (
                         "gmwm_lowest_abs_bias", "gmwm_lowest_sd", "armav_ols_rmse_below_avsm")}},
            "bias": out_bias}


def svo_theorems(coverage_csv: str | os.PathLike, coefficients_csv: str | os.PathLike,
                 n_arrays: int) -> dict[str, Any]:
    """Mean - c0 in Monte Carlo SEs: over the coverage replications (``coverage.csv``; the
    rows of the scheme with the most replications: a capped scheme, config
    ``svo.coverage.scheme_replicates``, has its statistics over its own fewer replications)
    and over the ``n_arrays`` training arrays (``coefficients.csv``, config ``svo.train``;
    methods with a spread, i.e. not equal weights)."""
    if n_arrays < 2:
        raise InputError(f"SVO training arrays: need at least 2, got {n_arrays}")
    cov = pd.read_csv(coverage_csv)
    cov = cov[cov.mbb == cov.loc[cov["replicates"].idxmax(), "mbb"]]
    n = cov["replicates"].to_numpy(float)
    z = (cov["mean_coef"] - cov["c0"]) / (cov["sd_coef"] / np.sqrt(n))
    out: dict[str, Any] = {
        "replications": {"n": int(n[0]), "max_abs_z": float(np.abs(z).max()),
                         "max_abs_rel_dev": float(np.abs(cov["mean_coef"] / cov["c0"] - 1).max()),
                         "max_sd_over_c0": float((cov["sd_coef"] / cov["c0"].abs()).max()),
                         "z": {str(g): float(v) for g, v in zip(cov["gyro"], z)}}}
    coefs = pd.read_csv(coefficients_csv)
    arrays: dict[str, Any] = {}
    for method, sub in coefs.groupby("method", sort=True):
        if (sub["sd"] < 1e-12).all():  # equal weights: 1/6, no spread
            continue
        zz = (sub["mean"] - sub["true"]) / (sub["sd"] / math.sqrt(n_arrays))
        arrays[str(method)] = {"max_abs_z": float(np.abs(zz).max()),
                               "z": {str(g): float(v) for g, v in zip(sub["gyro"], zz)}}
    out["arrays"] = {"n": n_arrays, **arrays}
    return out


def render_markdown(items: Mapping[str, Any]) -> str:
    """The numbers of ``items`` as a short page (what REPRODUCTION.md links next to the JSON)."""
    lem = items["p004"]["lemma1"]
    ss = items["p004"]["sample_size"]
    bias = items["p004"]["bias"]
    lines = [
        "# Paper items computed from committed tables (rule `paper_items`)",
        "",
        "Written by `gmwm_studies.paper_items`; REPRODUCTION.md links the JSON beside this page.",
        "",
        "## Paper 004, Lemma 1: determinant of the Jacobian of the first five AV levels",
        "",
        "| (1,1) entry | det, c = 1 (AV) | det / (ln 2 / (1024 pi)) | det, c = 1/2 (WV) |",
        "|---|---|---|---|",
        (f"| 3/2 (printed) | {lem['det_printed']:.6g} | {lem['det_printed_over_unit']:.6g} | "
        f"{lem['det_printed_wv']:.6g} |"),
        (f"| 3/4 (the Lemma's formula, 3/2^(2j) at j = 1) | {lem['det_formula']:.6g} | "
        f"{lem['det_formula_over_unit']:.6g} | {lem['det_formula_wv']:.6g} |"),
        "",
        "## Paper 004, Sec. IV sample size: short -> long, GMWFM estimators (GMWM, both ARMAVs)",
        "",
        (f"SD falls in {ss['sd_falls']} of {ss['cells']} cells, RMSE in {ss['rmse_falls']}, "
        f"both in {ss['both_fall']}; |bias| falls in {ss['abs_bias_falls']}, grows by more than "
        f"2 Monte Carlo SEs in {ss['abs_bias_grows_beyond_2se']}."),
        "",
        ("| sensor | symbol | estimator | SD short | SD long | RMSE short | RMSE long | \\|bias\\| "
        "short | \\|bias\\| long | change / MC SE |"),
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in ss["per_cell"]:
        lines.append(f"| {c['sensor']} | {c['symbol']} | {c['estimator']} | {c['sd_short']:.4g} | "
                     f"{c['sd_long']:.4g} | {c['rmse_short']:.4g} | {c['rmse_long']:.4g} | "
                     f"{c['abs_bias_short']:.4g} | {c['abs_bias_long']:.4g} | "
                     f"{c['abs_bias_change_z']:+.2f} |")
    cor = items["p004"]["cor1"]
    lines += ["", "## Paper 004, Corollary 1: weighted ARMAV / GMWM RMSE",
              "", (f"{cor['rmse_ratio_min']:.4g} to {cor['rmse_ratio_max']:.4g} over "
              f"{cor['cells']} cells."), "",
              "## Paper 004, Fig. 1: GMWM and weighted ARMAV relative SDs", "",
              (f"equal at 3 significant digits in {items['p004']['fig1']['rel_sd_equal_3sig']} of "
               f"{items['p004']['fig1']['cells']} cells. With the OLS ARMAV (GMWM, ARMAV, AVSM), "
               "cells where " + ", ".join(
                   f"{k}: {v}" for k, v in items["p004"]["fig1"]["ols_reading"].items()) + "."),
              "",
              "## Paper 004, Sec. III bias argument: |bias|, ARMAV against GMWM",
              "", (f"weighted ARMAV's |bias| larger in {bias['armav_larger']} of {bias['cells']} "
              f"cells, OLS ARMAV's in {bias['armav_ols_larger']}. z: the bias difference ARMAV - GMWM "
               "on the same replicates over its paired Monte Carlo SE; excess: (|bias ARMAV| - "
               "|bias GMWM|) / SD GMWM, the weight the excess can have in the RMSE."), "",
              "| sensor | symbol | T | GMWM | weighted ARMAV | z | excess | OLS ARMAV | z | excess |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for b in bias["per_cell"]:
        lines.append(f"| {b['sensor']} | {b['symbol']} | {b['T']} | {b['abs_bias_gmwm']:.4g} | "
                     f"{b['abs_bias_armav']:.4g} | {b.get('armav_minus_gmwm_z', float('nan')):.3g} "
                     f"| {b['armav_excess_over_sd']:.3g} | {b['abs_bias_armav_ols']:.4g} | "
                     f"{b.get('armav_ols_minus_gmwm_z', float('nan')):.3g} | "
                     f"{b['armav_ols_excess_over_sd']:.3g} |")
    th = items["p003"]["theorems"]
    rep = th["replications"]
    lines += ["", "## Paper 003, Theorems 1-2: c-hat against c0 at T = 2^20 (Case 1)", "",
              (f"Over {rep['n']} coverage replications (SVO omega_2): max |mean - c0| / "
              f"(SD / sqrt(n)) = {rep['max_abs_z']:.3g}, max |mean / c0 - 1| = "
              f"{rep['max_abs_rel_dev']:.3g}, max SD / c0 = {rep['max_sd_over_c0']:.3g}."), "",
              f"Over the {th['arrays']['n']} training arrays, max |mean - true| / (SD / sqrt(n)):",
              ""]
    for m, v in th["arrays"].items():
        if m != "n":
            lines.append(f"* {m}: {v['max_abs_z']:.3g}")
    return "\n".join(lines) + "\n"


def compute_items(stim_tables: Mapping[str, str | os.PathLike],
                  stim_replicates: Mapping[tuple[str, int], str | os.PathLike] | None,
                  svo_coverage: str | os.PathLike, svo_coefficients: str | os.PathLike,
                  svo_arrays: int, lengths: Sequence[int] = LONG_SHORT) -> dict[str, Any]:
    """Every item, keyed as the JSON: ``p004/{lemma1,sample_size,cor1,bias}``, ``p003/theorems``."""
    p004 = {"lemma1": lemma1(), **stim300_items(stim_tables, stim_replicates, lengths)}
    return {"p004": p004, "p003": {"theorems": svo_theorems(svo_coverage, svo_coefficients,
                                                            svo_arrays)}}


def write_items(items: Mapping[str, Any], json_path: str | os.PathLike,
                md_path: str | os.PathLike) -> None:
    """Write the JSON and its page atomically."""
    write_json_atomic(json_path, items)
    write_text_atomic(md_path, render_markdown(items))


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gmwm_studies.paper_items [REPORTS]``: recompute from REPORTS (default
    ``reports``) into REPORTS/paper_items/, with the training-array count of
    ``config/config.yaml`` (what the rule runs)."""
    import sys

    import yaml
    args = list(sys.argv[1:] if argv is None else argv)
    base = Path(args[0] if args else "reports")
    cfg = yaml.safe_load(Path("config/config.yaml").read_text(encoding="utf-8"))
    try:
        items = compute_items(
            {s: base / "stim300" / f"stim300_{s}_bias_sd_rmse.csv" for s in ("gyro", "accel")},
            {(sensor, T): base / f"stim300_{s}" / "replicates" / f"estimates_T{T}.csv"
             for s, sensor in (("gyro", "gyroscope"), ("accel", "accelerometer"))
             for T in LONG_SHORT},
            base / "svo" / "case1" / "coverage.csv", base / "svo" / "case1" / "coefficients.csv",
            int(cfg["svo"]["train"]))
    except InputError as exc:
        print(f"paper_items: {exc}", file=sys.stderr)
        return 2
    write_items(items, base / "paper_items" / "paper_items.json",
                base / "paper_items" / "paper_items.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
