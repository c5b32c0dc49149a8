"""Named counts over the per-replicate tables, and the checker of the numbers quoted from them.

Prose that quotes a per-replicate count ("the slow sinusoid is off by more than a factor 2 in 37
of 500 replicates") cites it by a stable name; :func:`study_counts` computes every such count from
the committed per-replicate tables (:mod:`gmwm_studies.replicates`), :func:`write_counts` writes
``counts.json`` and ``counts.md`` (name, value, definition, source file), and
:func:`check_markers` compares each quoted number of a Markdown page with ``counts.json``.

Count names: ``<study>[.T<T>][.<fitted model>].<estimator>.<quantity>`` (``T<T>`` only for studies
with several sample sizes), parameter names without brackets (``RW[1].gamma2`` -> ``RW1.gamma2``).
Every count is over the converged fits (a non-converged fit is counted in ``not_converged`` only).

Marker syntax in Markdown: a link whose text is the quoted number and whose target is a
``counts.md`` with the count's name as fragment, e.g.
``[37](counts.md#sim2.gmwm.SIN2.factor2_miss)`` (rendered: the number, linking to its row). The
``counts.json`` beside the linked ``counts.md`` holds the value. A quoted number matches when the
value rounded to the quoted number's significant digits equals it (``0.112`` matches 0.11234;
``37`` matches 37 only).

The same link form marks a number quoted from any committed table (:func:`check_quotes`): the
target is the CSV or JSON file and the fragment selects the cell,

* CSV: ``[0.9376](svo/case2/wv.csv#method=rdvg&level=15&col=ratio_to_equal)``: the rows whose
  ``<key>`` columns equal the values (as text, or as numbers when both parse), the ``col``
  column; exactly one row unless ``agg=min``, ``agg=max``, ``agg=mean`` or ``agg=sum`` (over
  the selected rows, e.g. for a quoted range's ends or a count over several rows;
  ``<key><<number>`` and ``<key>>=<number>`` etc. select rows by a numeric key's range; a row
  whose cell is empty fails unless such a range on that column leaves it out);
  ``over.<key>=<value>`` divides the cell by the cell of the row with that key replaced (a ratio
  of two cells, one row each: ``...&estimator=avsm&col=rmse&over.estimator=gmwm_cf`` is AVSM's
  RMSE over the GMWM's); ``less.<key>=<value>`` likewise subtracts that cell (a difference);
  ``plus=<column>`` / ``minus=<column>`` add / subtract another column of the same row (before
  ``agg``, ``over``, ``less``);
  ``argmax=<column>`` / ``argmin=<column>`` keep, of the selected rows, the one where that
  column is largest / smallest (e.g. the time of a series' peak: ``time_s>=210&col=time_s&
  argmax=ratio``);
  ``mul=100`` multiplies (a percentage), ``abs=1`` takes |x| before that;
  a space or ``&`` in a value is written ``%20`` / ``%26`` (URL encoding);
* JSON: ``[1.00004](allan/summary.json#fig41/N/mc_mean)``: keys (a list's index) separated by
  ``/``, with the same ``&mul=`` and ``&abs=`` options.

A number that no committed file holds (a time from an uncommitted run, a count over replicates
whose per-replicate file is not committed) is marked ``[145](#untraced "why")``: the link goes to
the page's own list of such numbers, and the checker counts them. Rendered, every marker is the
number as a link to its source (or to that list).

After a new run, :func:`refresh_quotes` (``python -m gmwm_studies.counts refresh PAGE.md``)
rewrites every count and cell marker whose quote no longer matches to the file's current value
at the quote's significant digits (:func:`format_like`), atomically, and prints each change;
``--check`` writes nothing and exits 1 on a stale quote. A marker whose file, count or cell is
gone is an error naming its line and link, and then nothing is written. :func:`plain_numbers`
lists the numbers a page still writes as plain text outside the classes that stay plain (the
papers' own numbers, names, design values, computed ones marked "="): the count to bring down.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np
import pandas as pd

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm.errors import InputError

__all__ = [
    "CELL_MARKER",
    "MARKER",
    "RIDGE_FACTOR",
    "UNTRACED_MARKER",
    "WILD_ROBUST_SD",
    "Change",
    "Count",
    "Mismatch",
    "PlainNumber",
    "Quote",
    "cell_value",
    "check_markers",
    "check_quotes",
    "draw_counts",
    "factor2_off",
    "find_markers",
    "find_quotes",
    "format_like",
    "main",
    "navigation_counts",
    "plain_numbers",
    "plan_refresh",
    "quoted_matches",
    "read_counts",
    "refresh_quotes",
    "render_counts_markdown",
    "study_counts",
    "svo_counts",
    "write_counts",
]

RIDGE_FACTOR = 100.0
"""A sinusoid is on the alpha-beta ridge when its period 2 pi / beta exceeds this many times the
longest WV scale 2^J: its WV is then a drift's and only alpha * beta is identified."""
WILD_ROBUST_SD = 100.0
"""An estimate is wild when it lies more than this many robust SDs (1.4826 MAD) from the median."""

MARKER = re.compile(r"\[(?P<quote>[^\]\[]+)\]"
                    r"\((?P<file>(?:[^()\s#]*/)?counts\.md)#(?P<name>[A-Za-z0-9_.\-]+)\)")
"""A count marker: ``[<quoted number>](<path>/counts.md#<count name>)``."""

CELL_MARKER = re.compile(r"\[(?P<quote>[^\]\[]+)\]"
                         r"\((?P<file>[^()\s#]+\.(?:csv|json))#(?P<selector>[^()\s]+)\)")
"""A table-cell marker: ``[<quoted number>](<path>.csv|.json#<selector>)`` (module docstring)."""

UNTRACED_MARKER = re.compile(r"\[(?P<quote>[+\-\u2212]?\.?\d[^\]\[]*)\]"
                             r"\(#untraced(?:\s+\"(?P<why>[^\"]*)\")?\)")
"""A quoted number no committed file holds: ``[<number>](#untraced "<why>")`` (a link with a
text that is not a number, such as one to the list itself, is no marker)."""


@dataclasses.dataclass(frozen=True)
class Count:
    """One named count: value (int, float or None when undefined), definition in words, source
    file (relative to the reports directory)."""

    name: str
    value: float | None
    definition: str
    source: str


def factor2_off(x: Any, truth: float) -> np.ndarray:
    """True where an estimate is off the truth by more than a factor 2 (x / truth > 2 or < 1/2;
    an estimate at 0 is off; NaN is not). The rule of the ``factor2_miss`` counts."""
    r = np.asarray(x, dtype=float) / truth
    return (r > 2) | (r < 0.5)


def _pname(name: str) -> str:
    return name.replace("[", "").replace("]", "")


def _num(x: Any) -> float | int | None:
    if x is None:
        return None
    if isinstance(x, bool | np.bool_):
        return int(x)
    if isinstance(x, int | np.integer):
        return int(x)
    x = float(x)
    return None if not math.isfinite(x) else x


def _sets(df: pd.DataFrame, column: str) -> list[set[str]]:
    return [set(s.split(";")) if s else set() for s in df[column].fillna("").astype(str)]


def _sin_counts(sub: pd.DataFrame, prefix: str, truth: Mapping[str, float], J: int | None,
                src: str) -> list[Count]:
    out: list[Count] = []
    ks = sorted({int(m.group(1)) for c in sub.columns
                 if (m := re.match(r"SIN\[(\d+)\]\.alpha$", c))})
    for k in ks:
        a_name, b_name = f"SIN[{k}].alpha", f"SIN[{k}].beta"
        if a_name not in truth or b_name not in truth:
            continue
        ta, tb = truth[a_name], truth[b_name]
        a = sub[a_name].to_numpy(float)
        b = sub[b_name].to_numpy(float)
        fitted = np.isfinite(a) & np.isfinite(b)
        if not fitted.any():  # the fitted model has no such sinusoid (e.g. a misspecified one)
            continue
        rb = b / tb
        off = factor2_off(a, ta) | factor2_off(b, tb)
        p = f"{prefix}.SIN{k}"
        out.append(Count(f"{p}.factor2_miss", int(np.sum(off & np.isfinite(a))),
                         f"converged fits with SIN[{k}] alpha or beta off the truth by more than "
                         f"a factor 2 (ratio > 2 or < 1/2)", src))
        med = float(np.median(np.abs(rb[fitted] - 1.0)))
        out.append(Count(f"{p}.beta_median_abs_rel_err", med,
                         f"median over converged fits of |SIN[{k}].beta / truth - 1|", src))
        if J:
            with np.errstate(divide="ignore"):  # beta at 0: an infinite period
                period = np.where(b > 0, 2 * np.pi / np.where(b > 0, b, 1.0), np.inf)
            ridge = np.flatnonzero(fitted & (period > RIDGE_FACTOR * 2.0 ** J))
            out.append(Count(f"{p}.ridge", len(ridge),
                             f"converged fits on the SIN[{k}] alpha-beta ridge: period 2 pi / beta "
                             f"(samples) > {RIDGE_FACTOR:g} x the longest scale 2^J (J = {J})",
                             src))
            for i, row in enumerate(sorted(ridge, key=lambda r: -a[r]), start=1):
                q = f"{p}.ridge{i}"
                what = f"ridge fit {i} of SIN[{k}] (by decreasing alpha)"
                out += [
                    Count(f"{q}.replicate", int(sub["replicate"].iloc[row]),
                          f"replicate id of the {what}", src),
                    Count(f"{q}.alpha", _num(a[row]), f"SIN[{k}].alpha of the {what}", src),
                    Count(f"{q}.beta", _num(b[row]), f"SIN[{k}].beta of the {what}", src),
                    Count(f"{q}.alpha_beta", _num(a[row] * b[row]), f"alpha * beta of the {what}",
                          src),
                    Count(f"{q}.period", _num(period[row]),
                          f"period 2 pi / beta (samples) of the {what}", src),
                    Count(f"{q}.period_over_longest_scale", _num(period[row] / 2.0 ** J),
                          f"period / 2^J of the {what}", src),
                ]
    return out


def _wild_counts(sub: pd.DataFrame, prefix: str, params: Sequence[str], record: Mapping[str, Any],
                 src: str) -> list[Count]:
    """STIM-300: estimates far from the median in Table I units (the units of its report)."""
    from gmwm_studies import sensors as units

    out = []
    for name in params:
        x = units.to_table_units(name, np.abs(sub[name].to_numpy(float)), record["sensor"],
                                 float(record["freq"]))
        x = x[np.isfinite(x)]
        if len(x) < 3:
            continue
        med = float(np.median(x))
        rsd = 1.4826 * float(np.median(np.abs(x - med)))
        z = np.abs(x - med) / rsd if rsd > 0 else np.zeros_like(x)
        wild = z > WILD_ROBUST_SD
        p = f"{prefix}.wild.{_pname(name)}"
        d = (f"converged fits with {name} (Table I units) more than {WILD_ROBUST_SD:g} robust SDs "
             f"(1.4826 MAD) from the median")
        out.append(Count(p, int(wild.sum()), d, src))
        if wild.any():  # their distances, only when there are some
            out.append(Count(f"{p}.min_z", _num(z[wild].min()),
                             "smallest |x - median| / robust SD among those", src))
            out.append(Count(f"{p}.max_z", _num(z[wild].max()),
                             "largest |x - median| / robust SD among those", src))
    return out


def study_counts(study: str, df: pd.DataFrame, record: Mapping[str, Any], source: str, *,
                 label_T: bool = False) -> list[Count]:
    """Every named count of one per-replicate table (one study at one T).

    Per estimator (and fitted model): ``n``, ``not_converged``, ``at_boundary.<param>`` for each
    parameter, ``label_switched`` (and ``label_switched.<type>``) when the table has it, per sinusoid ``SIN<k>.factor2_miss``,
    ``SIN<k>.beta_median_abs_rel_err`` and the ridge fits (``SIN<k>.ridge``, ``SIN<k>.ridge<i>.*``,
    see :data:`RIDGE_FACTOR`), and for STIM-300 ``wild.<param>`` (:data:`WILD_ROBUST_SD`).
    ``label_T``: put ``T<T>`` in the names (a study with several sample sizes).
    """
    truth = {str(k): float(v) for k, v in record["truth"].items()}
    J = record.get("J")
    T = int(record["T"])
    keys = ["fit_model", "estimator"] if "fit_model" in df.columns else ["estimator"]
    out: list[Count] = []
    for key, sub in df.groupby(keys, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        prefix = ".".join([study, *([f"T{T}"] if label_T else []), *map(str, key)])
        conv = sub["converged"].astype(bool).to_numpy()
        params = [c for c in sub.columns if "." in c and "[" in c and sub[c].notna().any()]
        out.append(Count(f"{prefix}.n", len(sub), "fits (replicates) in the table", source))
        out.append(Count(f"{prefix}.not_converged", int((~conv).sum()),
                         "fits that did not converge", source))
        ok = sub[conv]
        sets = _sets(ok, "at_boundary")
        for name in params:
            out.append(Count(f"{prefix}.at_boundary.{_pname(name)}", sum(name in s for s in sets),
                             f"converged fits with {name} at the boundary (at_boundary column: "
                             "a scale parameter below 1e-8 x its truth, AR1 |phi| at 1, SIN beta "
                             "at pi)", source))
        if "label_switched" in ok.columns:
            switched = _sets(ok, "label_switched")
            out.append(Count(f"{prefix}.label_switched", sum(bool(s) for s in switched),
                             "converged fits with a true component in another component's column "
                             "(label_switched column not empty)", source))
            types = dict.fromkeys(n.split("[", 1)[0] for n in params)
            for kind in (t for t in types
                         if len({n.split(".")[0] for n in params if n.startswith(f"{t}[")}) > 1):
                out.append(Count(f"{prefix}.label_switched.{kind}",
                                 sum(kind in s for s in switched),
                                 f"converged fits with a {kind} component in another {kind}'s "
                                 "column (the tables' n_switched of its parameters)", source))
        out += _sin_counts(ok, prefix, truth, J, source)
        if record.get("kind") == "mle_comparison":
            out += _sim1_fit_counts(sub, prefix, source)
        if "sensor" in record:
            out += _wild_counts(ok, prefix, params, record, source)
    return out


def _mean(x: Any) -> float | None:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return _num(x.mean()) if x.size else None


def _sim1_fit_counts(sub: pd.DataFrame, prefix: str, source: str) -> list[Count]:
    """Simulation 1, one method at one T (rows where it ran; replicates.SIM1_COLUMNS): wrong
    optima and the mean clocks over all attempts and over the converged fits (converged and not
    at a wrong optimum: the set the study's statistics and ``*_conv`` time columns use)."""
    conv = sub["converged"].astype(bool).to_numpy()
    wrong = sub["wrong_optimum"].fillna(0).astype(bool).to_numpy()
    ok = conv & ~wrong
    out = [Count(f"{prefix}.wrong_optimum", int(wrong.sum()),
                 "converged fits whose log-likelihood is more than wrong_optimum_ll below the "
                 "best any MLE reached on the same signal (wrong_optimum column)", source),
           Count(f"{prefix}.n_ok", int(ok.sum()),
                 "fits converged to the best optimum (converged and not wrong_optimum)", source)]
    if sub["iterations"].notna().any():
        it = sub["iterations"].to_numpy(float)
        out.append(Count(f"{prefix}.iterations_max", int(np.nanmax(it)),
                         "largest number of optimiser iterations (iterations column; the "
                         "maxiter cap when a fit was stopped by it)", source))
    for col, what in (("seconds", "wall time"), ("cpu_seconds", "CPU time")):
        x = sub[col].to_numpy(float)
        out.append(Count(f"{prefix}.mean_{col}", _mean(x),
                         f"mean {what} of the point estimate [s] over every attempted fit "
                         "(failed and capped ones included)", source))
        out.append(Count(f"{prefix}.mean_{col}_conv", _mean(x[ok]),
                         f"mean {what} of the point estimate [s] over the fits converged to the "
                         "best optimum", source))
    return out


def svo_counts(case: str, fits: pd.DataFrame, coverage: pd.DataFrame | None,
               sources: Mapping[str, str]) -> list[Count]:
    """Counts of one SVO case's per-replicate files (svo_study.virtual_fit_table and
    coverage_replicate_table). ``svo.<case>.n_signals``; per method and parameter ``lowest`` (the
    virtual signals on which the method's estimate is the lowest of the methods: the
    ``share_lowest`` of gmwm_estimates.csv) and ``lowest_pct``; per MBB scheme
    ``coverage.<scheme>.n`` (replications), per gyro ``gyro<i>.covered`` and ``gyro<i>.coverage``,
    and ``coverage.<scheme>.min`` / ``.max`` over the gyros. ``sources``: ``fits`` and
    ``coverage`` file names (relative to the counts file)."""
    out: list[Count] = []
    p = f"svo.{case}"
    wide = {prm: fits.pivot_table(index=["replicate", "test"], columns="method", values=prm,
                                  sort=False) for prm in ("sigma2", "gamma2")}
    n = len(wide["gamma2"])
    out.append(Count(f"{p}.n_signals", n, "out-of-sample virtual signals (training array x test "
                     "array) with a GMWM fit per method", sources["fits"]))
    for prm, w in wide.items():
        lowest = w.idxmin(axis=1).to_numpy()
        for m in w.columns:
            k = int(np.sum(lowest == m))
            out.append(Count(f"{p}.{m}.{prm}.lowest", k, f"virtual signals on which {m}'s GMWM "
                             f"{prm} is the lowest of the {w.shape[1]} methods", sources["fits"]))
            out.append(Count(f"{p}.{m}.{prm}.lowest_pct", _num(100.0 * k / n) if n else None,
                             f"the same in percent of the {n} signals", sources["fits"]))
    if coverage is not None:
        for scheme, g in coverage.groupby("mbb", sort=False):
            q = f"{p}.coverage.{scheme}"
            cov = g.groupby("gyro")["covered"].agg(["sum", "count"])
            out.append(Count(f"{q}.n", int(g["replicate"].nunique()),
                             f"coverage replications ({scheme} MBB)", sources["coverage"]))
            shares = []
            for gyro, r in cov.iterrows():
                shares.append(r["sum"] / r["count"])
                out.append(Count(f"{q}.gyro{gyro}.covered", int(r["sum"]),
                                 f"replications whose {scheme}-MBB interval for coefficient "
                                 f"{gyro} covers c0 (covered column)", sources["coverage"]))
                out.append(Count(f"{q}.gyro{gyro}.coverage", _num(shares[-1]),
                                 f"their share (coverage of coefficient {gyro})",
                                 sources["coverage"]))
            out.append(Count(f"{q}.min", _num(min(shares)), "smallest coverage over the gyros",
                             sources["coverage"]))
            out.append(Count(f"{q}.max", _num(max(shares)), "largest coverage over the gyros",
                             sources["coverage"]))
    return out


def navigation_counts(df: pd.DataFrame, source: str, models: Sequence[str] | None = None
                      ) -> list[Count]:
    """Counts of the navigation emulation's per-iteration table
    (navigation.iteration_table): ``navigation.n_iterations``, ``n_dropped``, ``n_used`` and
    ``ratio_at_peak``, the ratio of the first model's mean ``err_at_peak_m`` to the second's over
    the used iterations (= ratio_max.csv's whole-flight ``max_ratio``)."""
    its = df.groupby("iteration")["dropped"].max()
    out = [Count("navigation.n_iterations", int(its.size), "configured iterations", source),
           Count("navigation.n_dropped", int(its.sum()),
                 "iterations dropped (a fit did not converge or its AR1 phi is outside (0, 1))",
                 source),
           Count("navigation.n_used", int((its == 0).sum()), "iterations emulated", source)]
    models = list(models or dict.fromkeys(df["model"]))
    used = df[df["dropped"] == 0]
    if len(models) == 2 and len(used):
        e = [used.loc[used["model"] == m, "err_at_peak_m"].to_numpy(float) for m in models]
        out.append(Count("navigation.ratio_at_peak", _num(e[0].mean() / e[1].mean()),
                         f"mean position error of {models[0]} over {models[1]} at the epoch of "
                         "the ratio's whole-flight maximum (err_at_peak_m)", source))
    return out


def draw_counts(fit: str, df: pd.DataFrame, estimate: Mapping[str, float], source: str,
                quantiles: Sequence[float] = (0.1, 0.5, 0.9)) -> list[Count]:
    """Counts of one fit's bootstrap draws (table of :func:`replicates.bootstrap_draw_table`).

    ``<fit>.n_failed``; per parameter ``q<pct>`` (numpy's default linear quantile of the converged,
    label-aligned refits), ``min``, ``max`` and ``at_boundary`` (refits exactly 0, or below 1e-8 x
    a non-zero estimate)."""
    conv = df["converged"].astype(bool).to_numpy()
    ok = df[conv]
    out = [Count(f"{fit}.n", len(df), "bootstrap draws", source),
           Count(f"{fit}.n_failed", int((~conv).sum()), "refits that failed or did not converge",
                 source)]
    for name, est in estimate.items():
        x = ok[name].to_numpy(float)
        p = f"{fit}.{_pname(name)}"
        for q in quantiles:
            out.append(Count(f"{p}.q{round(100 * q):d}",
                             _num(np.quantile(x, q)) if len(x) else None,
                             f"{100 * q:g} % quantile (numpy linear) of the converged refits of "
                             f"{name}", source))
        out.append(Count(f"{p}.min", _num(x.min()) if len(x) else None,
                         f"smallest refit of {name}", source))
        out.append(Count(f"{p}.max", _num(x.max()) if len(x) else None,
                         f"largest refit of {name}", source))
        tol = 1e-8 * abs(est)
        out.append(Count(f"{p}.at_boundary", int(np.sum(np.abs(x) <= tol)),
                         f"refits of {name} at 0 (|x| <= 1e-8 x |estimate|)", source))
    return out


# ---------------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------------


TITLE = "Counts quoted in the reports"


def render_counts_markdown(counts: Sequence[Count], title: str = TITLE) -> str:
    """Markdown table: one row per count with an anchor (``#<name>``) for the markers' links."""
    lines = [f"# {title}", "",
             ("Computed by the pipeline (gmwm_studies.counts) from the per-replicate tables "
              "named in the source column. A number quoted in REPRODUCTION.md as "
              "`[value](counts.md#name)` links to its row; tests/test_counts.py checks it against "
              "counts.json. Counts are over the converged fits."), "",
             "| name | value | definition | source |", "|---|---|---|---|"]
    for c in counts:
        v = "undefined" if c.value is None else (str(c.value) if isinstance(c.value, int)
                                                 else f"{c.value:.6g}")
        text = c.definition.replace("|", "\\|")  # a literal | would end the table cell
        lines.append(f'| <a id="{c.name}"></a>`{c.name}` | {v} | {text} | '
                     f"[{c.source}]({c.source}) |")
    return "\n".join(lines) + "\n"


def write_counts(counts: Sequence[Count], json_path: str | os.PathLike,
                 md_path: str | os.PathLike, *, title: str = TITLE) -> None:
    """Write ``counts.json`` ({"counts": {name: {value, definition, source}}}) and ``counts.md``
    (sources as given: relative to the directory of these files, so the links work)."""
    names = [c.name for c in counts]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"duplicate count names: {dup[:5]}")
    write_json_atomic(json_path, {"counts": {c.name: {"value": c.value, "definition": c.definition,
                                                      "source": c.source} for c in counts}})
    write_text_atomic(md_path, render_counts_markdown(counts, title))


def read_counts(path: str | os.PathLike) -> dict[str, Any]:
    """{name: value} of a ``counts.json``."""
    if not os.path.isfile(path):
        raise InputError(f"counts file not found: {path}")
    with open(path, encoding="utf-8") as fh:
        data = json.load(fh)
    return {k: v["value"] for k, v in data["counts"].items()}


# ---------------------------------------------------------------------------------------------
# checker
# ---------------------------------------------------------------------------------------------

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def _sig_digits(q: str) -> int:
    """Significant digits of a number as written (leading zeros not counted, trailing ones are:
    ``37`` has 2, ``0.0120`` has 3)."""
    mantissa = re.split(r"[eE]", q)[0].lstrip("+-").replace(".", "").lstrip("0") or "0"
    return max(1, len(mantissa))


def quoted_matches(quote: str, value: float | None) -> bool:
    """True when ``value`` rounded to the significant digits of ``quote`` equals it."""
    q = quote.strip().replace("\u2212", "-")
    if value is None or not _NUMBER.match(q):
        return False
    return float(f"{float(value):.{_sig_digits(q)}g}") == float(q)


def format_like(quote: str, value: float) -> str:
    """``value`` written the way ``quote`` is: the same significant digits and notation (fixed or
    exponent, ``e``/``E``, a leading ``+``, the U+2212 minus). An integer quote of an integral
    value is the integer itself (a count that grows a digit keeps every digit). Raises
    ``InputError`` when the quote is no number or the value is not finite."""
    q = quote.strip()
    plain = q.replace("\u2212", "-")
    if not _NUMBER.match(plain):
        raise InputError(f"quote {quote!r} is not a number")
    if not math.isfinite(value):
        raise InputError(f"value {value!r} is not a finite number")
    sig = _sig_digits(plain)
    exp_char = next((c for c in "eE" if c in plain), "")
    if exp_char:
        mant, e = f"{value:.{sig - 1}e}".split("e")
        q_exp = plain.split(exp_char)[1]
        width = len(q_exp.lstrip("+-"))  # 1.0e-05 stays zero-padded
        sign = "-" if int(e) < 0 else ("+" if q_exp.startswith("+") else "")
        e_txt = f"{sign}{abs(int(e)):0{width}d}"
        out = f"{mant}{exp_char}{e_txt}"
    elif "." not in plain and float(value).is_integer():
        out = str(int(value))
    else:
        r = float(f"{value:.{sig}g}")
        decimals = sig - 1 - (math.floor(math.log10(abs(r))) if r else 0)
        out = f"{r:.{decimals}f}" if decimals >= 0 else str(int(r))
        if decimals == 0 and plain.endswith("."):
            out += "."
    if plain.startswith("+") and not out.startswith("-"):
        out = "+" + out
    if "\u2212" in q:
        out = out.replace("-", "\u2212")
    return out


@dataclasses.dataclass(frozen=True)
class Mismatch:
    """A marker whose quoted number is not the count's value (``value`` None: count missing)."""

    line: int
    name: str
    quote: str
    value: Any
    counts_file: str


def find_markers(text: str) -> list[tuple[int, str, str, str]]:
    """Count markers of a Markdown text: (line number, quote, counts.md path, count name).

    Inline code spans are skipped: a marker shown as an example in backticks is not a quote."""
    out = []
    for i, line in enumerate(text.splitlines(), start=1):
        for m in MARKER.finditer(re.sub(r"`[^`]*`", "", line)):
            out.append((i, m.group("quote"), m.group("file"), m.group("name")))
    return out


def check_markers(md_path: str | os.PathLike) -> tuple[int, list[Mismatch]]:
    """Check every count marker of a Markdown file against the counts.json beside the counts.md
    it links to. Returns (number of markers, mismatches)."""
    md_path = Path(md_path)
    markers = find_markers(md_path.read_text(encoding="utf-8"))
    cache: dict[Path, dict[str, Any] | None] = {}
    bad = []
    for line, quote, file, name in markers:
        json_path = (md_path.parent / file).with_suffix(".json")
        if json_path not in cache:
            cache[json_path] = read_counts(json_path) if json_path.is_file() else None
        values = cache[json_path]
        value = None if values is None else values.get(name)
        if values is None or name not in values or not quoted_matches(quote, value):
            bad.append(Mismatch(line, name, quote, value, str(json_path)))
    return len(markers), bad


_OPTIONS = ("col", "agg", "mul", "abs", "plus", "minus", "argmax", "argmin")


def _same(cell: str, want: str) -> bool:
    if cell == want:
        return True
    try:
        return float(cell) == float(want)
    except ValueError:
        return False


def cell_value(path: str | os.PathLike, selector: str) -> float:
    """The number a table-cell marker's ``selector`` picks in ``path`` (CSV or JSON).

    Raises ``InputError`` naming the problem when the file, a key, the column or the row (exactly
    one unless ``agg``) is missing or the cell is not a number."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"table not found: {path}")
    parts = [unquote(p) for p in selector.split("&")]  # %20 for a space in a key's value
    opts: dict[str, str] = {}
    if path.suffix == ".json":
        keys, rest = parts[0].split("/"), parts[1:]
    else:
        keys, rest = [], parts
    filters: list[tuple[str, str]] = []
    over: dict[str, str] = {}
    less: dict[str, str] = {}
    ranges: list[tuple[str, str, float]] = []
    for part in rest:
        m = re.fullmatch(r"([^<>=]+)(<=|>=|<|>)([^<>=]+)", part)
        if m:  # a numeric range of a key column, e.g. time_s<160
            try:
                ranges.append((m.group(1), m.group(2), float(m.group(3))))
            except ValueError:
                raise InputError(f"selector part {part!r}: not a number after {m.group(2)}") from None
            continue
        k, sep, v = part.partition("=")
        if not sep:
            raise InputError(f"selector part {part!r} is not key=value")
        if k in _OPTIONS:
            opts[k] = v
        elif k.startswith("over."):
            over[k[5:]] = v
        elif k.startswith("less."):
            less[k[5:]] = v
        else:
            filters.append((k, v))
    if path.suffix == ".json":
        with open(path, encoding="utf-8") as fh:
            node: Any = json.load(fh)
        for k in keys:
            if isinstance(node, list) and k.isdigit() and int(k) < len(node):
                node = node[int(k)]  # a list's element by its index
            elif isinstance(node, dict) and k in node:
                node = node[k]
            else:
                raise InputError(f"{path.name}: no key {k!r} on the path {'/'.join(keys)}")
        values = [node]
        if over or less:
            raise InputError(f"{path.name}: over.<key> and less.<key> are for CSV tables")
    else:
        df = _read_csv(path)
        col = opts.get("col")
        if col is None or col not in df.columns:
            raise InputError(f"{path.name}: no column {col!r}")

        def select(filters: list[tuple[str, str]]) -> list[str]:
            mask = np.ones(len(df), dtype=bool)
            for k, v in filters:
                if k not in df.columns:
                    raise InputError(f"{path.name}: no key column {k!r}")
                mask &= np.array([_same(c, v) for c in df[k]])
            for k, op, bound in ranges:
                if k not in df.columns:
                    raise InputError(f"{path.name}: no key column {k!r}")
                x = pd.to_numeric(df[k], errors="coerce").to_numpy(float)
                mask &= {"<": x < bound, ">": x > bound, "<=": x <= bound, ">=": x >= bound}[op]
            for op in ("argmax", "argmin"):  # the selected row where another column peaks
                if op in opts and mask.any():
                    if opts[op] not in df.columns:
                        raise InputError(f"{path.name}: no column {opts[op]!r} ({op}=)")
                    x = pd.to_numeric(df[opts[op]], errors="coerce").to_numpy(float)
                    x = np.where(mask, x if op == "argmax" else -x, -np.inf)
                    mask = np.arange(len(df)) == int(np.argmax(x))
            values = df.loc[mask, col].tolist()
            for op in ("plus", "minus"):  # another column of the same row, added / subtracted
                if op in opts:
                    other = opts[op]
                    if other not in df.columns:
                        raise InputError(f"{path.name}: no column {other!r} ({op}=)")
                    try:
                        sign = 1.0 if op == "plus" else -1.0
                        values = [str(float(a) + sign * float(b))
                                  for a, b in zip(values, df.loc[mask, other], strict=True)]
                    except ValueError:
                        raise InputError(f"{path.name}#{selector}: {col} {op} {other}: "
                                         "not numbers") from None
            if not values:
                raise InputError(f"{path.name}: no row with {dict(filters)}")
            if len(values) > 1 and ("agg" not in opts or over or less):
                raise InputError(f"{path.name}: {len(values)} rows with {dict(filters)} (add keys"
                                 + (")" if over or less else " or agg=min|max|mean|sum)"))
            return values

        values = select(filters)
        if over and less:
            raise InputError(f"{path.name}#{selector}: over.<key> or less.<key>, not both")
        if over or less:  # a ratio or difference of two cells: this row and the row with the
            other = over or less  # keys replaced
            unknown = sorted(set(other) - {k for k, _ in filters})
            if unknown:
                raise InputError(f"{path.name}: over.<key> / less.<key> must replace a key of the "
                                 f"selector: {unknown}")
            den = select([(k, other.get(k, v)) for k, v in filters])
            try:
                a, b = float(values[0]), float(den[0])
                values = [a / b if over else a - b]
            except (TypeError, ValueError, ZeroDivisionError):
                raise InputError(f"{path.name}#{selector}: not two numbers: "
                                 f"{values[0]!r}, {den[0]!r}") from None
    try:
        x = np.array([float(v) for v in values])
    except (TypeError, ValueError):
        raise InputError(f"{path.name}#{selector}: not a number: {values[:3]}") from None
    if opts.get("abs") == "1":
        x = np.abs(x)
    agg = opts.get("agg", "min")
    if agg not in ("min", "max", "mean", "sum"):
        raise InputError(f"agg={agg!r}: min, max, mean or sum")
    v = float({"min": np.min, "max": np.max, "mean": np.mean, "sum": np.sum}[agg](x))
    return v * float(opts.get("mul", "1"))


_CSV_CACHE: dict[tuple[Path, float], pd.DataFrame] = {}


def _read_csv(path: Path) -> pd.DataFrame:
    key = (path.resolve(), path.stat().st_mtime)
    if key not in _CSV_CACHE:
        _CSV_CACHE[key] = pd.read_csv(path, dtype=str, keep_default_na=False)
    return _CSV_CACHE[key]


@dataclasses.dataclass(frozen=True)
class Quote:
    """One marked number of a Markdown page: kind ``count``, ``cell`` or ``untraced``; ``source``
    the linked file (relative to the page) and ``selector`` the count name or cell selector
    (for ``untraced``: the reason given)."""

    line: int
    kind: str
    quote: str
    source: str
    selector: str


def _mask_code(line: str) -> str:
    """``line`` with its inline code spans blanked (same length, so positions stay valid)."""
    return re.sub(r"`[^`]*`", lambda m: " " * len(m.group(0)), line)


def _line_quotes(i: int, line: str) -> list[tuple[re.Match[str], Quote]]:
    """The markers of one line (code spans skipped) with their matches, in order."""
    line = _mask_code(line)
    hits = [(m, Quote(i, "count", m.group("quote"), m.group("file"), m.group("name")))
            for m in MARKER.finditer(line)]
    hits += [(m, Quote(i, "cell", m.group("quote"), m.group("file"), m.group("selector")))
             for m in CELL_MARKER.finditer(line)]
    hits += [(m, Quote(i, "untraced", m.group("quote"), "", m.group("why") or ""))
             for m in UNTRACED_MARKER.finditer(line)]
    return sorted(hits, key=lambda h: h[0].start())


def find_quotes(text: str) -> list[Quote]:
    """Every marker of a Markdown text (count, table cell, untraced), in order of appearance.
    Inline code spans are skipped (a marker shown as an example is not a quote)."""
    return [q for i, line in enumerate(text.splitlines(), start=1)
            for _, q in _line_quotes(i, line)]


def check_quotes(md_path: str | os.PathLike) -> tuple[list[Quote], list[Mismatch]]:
    """Check every count and table-cell marker of a Markdown file (untraced markers are listed,
    not checked). Returns (all markers, mismatches); a mismatch's ``value`` is None when the
    source or cell is missing (then ``counts_file`` says why)."""
    md_path = Path(md_path)
    quotes = find_quotes(md_path.read_text(encoding="utf-8"))
    _, bad = check_markers(md_path)
    for q in quotes:
        if q.kind != "cell":
            continue
        try:
            value: float | None = cell_value(md_path.parent / q.source, q.selector)
            where = str(md_path.parent / q.source)
        except InputError as e:
            value, where = None, str(e)
        if value is None or not quoted_matches(q.quote, value):
            bad.append(Mismatch(q.line, q.selector, q.quote, value, where))
    return quotes, sorted(bad, key=lambda b: b.line)


@dataclasses.dataclass(frozen=True)
class PlainNumber:
    """A number written as plain text (no marker): its line, column (0-based), text and the text
    around it."""

    line: int
    start: int
    text: str
    context: str


_PLAIN = re.compile(r"(?<![\w.^_/#\\\-+\u2212\[])[+\-\u2212]?"
                    r"(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:[eE][+\-]?\d+)?(?![\w\[.]\w|[\w\[/])"
                    r"|(?<=\d[-\u2013])(?:\d+)(?:\.\d+)?(?:[eE][+\-]?\d+)?(?![\w\[])")
_NOT_QUOTES = [  # spans that hold no quoted number (blanked before numbers are looked for)
    re.compile(r"`[^`]*`"),  # code
    re.compile(r"\]\([^()\s]*(?:\([^()\s]*\)[^()\s]*)*(?:\s+\"[^\"]*\")?\)"),  # link targets
    re.compile(r"<[^>]+>"),  # HTML tags (anchors)
    re.compile(r"\[\^[^\]]+\]"),  # footnote references
    re.compile(r"\b\d{4}-\d\d-\d\d\b|\b\d\d:\d\d(?::\d\d)?\b"),  # dates, clock times
    # commits (with a letter: an all-digit 1107083 is a number)
    re.compile(r"\b(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b"),
]
_NAMED = re.compile(  # a number naming a thing, not quoting a value ("Fig 4", "Simulation 2")
    r"(?:\b(?:Figs?|Fig\.|Tables?|Secs?|Sec\.|Section|Lemmas?|Cor\.?|Corollary|Corollaries|"
    r"Theorems?|Remarks?|Examples?|"
    r"Models?|Simulations?|[Cc]ases?|[Pp]apers?|issues?|items?|Eqs?\.?|SPEC|run|commit|"
    r"[Ss]tage|[Ss]tep|[Pp]hase|Hz|Mode|replicate|replicates|iteration|axis|Chapter|line|"
    r"Proposition|Prop\.|Definition|Algorithm|Assumption|[Cc]olumn|factor|gyros?|order|Sim|"
    r"Pixhawk|[A-Z]{2,}\(\s*(?:\d+,\s*)?)"
    r"|§)\s*(?:[\w.]+\s*(?:,|-|\u2013|and|/)\s*)*$")
_DESIGN = re.compile(r"=\s*(?:[^\s|;,()]+\s+(?:\.\.\.|to|-)\s+)?$")
_DESIGN_LIST = re.compile(  # "m = 4096 / 8192 / 16384", "(phi, theta) = (0.9, -0.5), (0.9, 0.5)"
    r"=\s*(?:[(\[]?[-+\u2212]?[\d.]+(?:e[-+]?\d+)?[)\]]?(?:\s*(?:,|/|\.\.\.|and)\s*))*"
    r"[(\[]?[-+\u2212]?$")
_FORMULA_BEFORE = re.compile(r"(?:\+-|\^|\*|\bpi|\bcos\(|\bsin\(|\bln)\s*\(?$")
_FORMULA_AFTER = re.compile(r"\s*(?:\+-|\^|\*|pi\b|ln\b|tau\b|cos\b|sin\b)")
_DENOMINATOR = re.compile(r"\)\**\s*(?:/|of(?:\s+(?:the|its))?)\s*$")  # "[304](...) of 500"
_BOUND = re.compile(r"(?:boundary|\bat|below|reach|cut at)\s*$")  # "at the boundary 0"
_NOMINAL = re.compile(r"^95\s*%\s*(?:CI|interval|confidence|\w*\s*interval)|^95\s*%$")
_DESIGN_UNIT = re.compile(  # a design size: "500 replicates", "a 24-point profile"
    r"[\s-](?:replicates?|replications?|signals|draws|arrays|iterations?|starts|parameters|"
    r"gyros|clusters|lanes?|submodels|point|fits|training)\b")
_SAMPLE_SIZE = re.compile(r"^\d(?:\.\d)?e\+?\d+$")  # T = 1e4 ... 1.6e5, written "at 1.6e5"
_SAMPLE_SIZE_BEFORE = re.compile(r"(?:\bat|\(|T\s*[<>]=?|\bfrom)\s*$")


def _table_columns(header: str) -> list[str]:
    return [c.strip().lower() for c in re.split(r"(?<!\\)\|", header.strip().strip("|"))]


def plain_numbers(text: str) -> list[PlainNumber]:
    """Numbers of a Markdown text written as plain text and outside the classes that stay plain:
    markers (:func:`find_quotes`), code, link targets, footnote labels, dates, commits, headings,
    a number naming a thing (``Fig 4``, ``Simulation 2``, ``AR1``, ``SIN[2]``), a value after
    ``=`` (a design value such as ``T = 1e4`` or a ratio the page computes) or in a clause (up
    to ``;`` or ``|``) marked ``(= ...)`` as computed, a constant of a formula (beside ``+-``,
    ``^``, ``pi``, ``cos``), the bound 0 ("at the boundary 0"), a nominal 95 %, the design
    denominator of a linked count (``[304](...) of 500``), a design size
    (``500 replicates``, ``at 1.6e5``: a sample size in e-notation after "at", "(", "from"), and a table's
    ``paper's claim`` column (the paper's own numbers). What is left is a number quoted without
    a link to its source: the count a page should bring to 0."""
    out = []
    paper_cols: set[int] = set()
    header: list[str] | None = None
    for i, line in enumerate(text.splitlines(), start=1):
        if line.lstrip().startswith("#"):
            continue
        masked = line
        for m_, _q in _line_quotes(i, line):
            masked = masked[:m_.start()] + " " * (m_.end() - m_.start()) + masked[m_.end():]
        for pat in _NOT_QUOTES:
            masked = pat.sub(lambda m: " " * len(m.group(0)), masked)
        if line.startswith("|"):
            cells = _table_columns(line)
            if header is None:
                header = cells
                paper_cols = {k for k, c in enumerate(header) if "paper" in c}
                continue
            if all(re.fullmatch(r":?-+:?", c) for c in cells if c):
                continue
        else:
            header, paper_cols = None, set()
        bounds = [m.start() for m in re.finditer(r"(?<!\\)\|", line)] if header else []
        # a clause with "(= ..." holds numbers the page computes (marked "=" after them)
        computed = [(c.start(), c.end()) for c in re.finditer(r"[^;|]+", masked)
                    if "(=" in c.group(0)]
        for m in _PLAIN.finditer(masked):
            before = masked[max(0, m.start() - 40):m.start()]
            col = sum(b < m.start() for b in bounds) - 1
            after = masked[m.end():m.end() + 14]
            if (col in paper_cols or _NAMED.search(before) or _DESIGN.search(before)
                    or any(a <= m.start() < b for a, b in computed)
                    or _DESIGN_UNIT.match(after) or _DESIGN_LIST.search(before)
                    or _DENOMINATOR.search(line[:m.start()])
                    or (m.group(0) == "0" and _BOUND.search(before))
                    or _NOMINAL.match(masked[m.start():m.end() + 16])
                    or re.search(r"nominal\s*$", before)
                    or _FORMULA_BEFORE.search(before) or _FORMULA_AFTER.match(after)
                    or (_SAMPLE_SIZE.match(m.group(0)) and _SAMPLE_SIZE_BEFORE.search(before))):
                continue
            out.append(PlainNumber(i, m.start(), m.group(0),
                                   line[max(0, m.start() - 40):m.end() + 10]))
    return out


@dataclasses.dataclass(frozen=True)
class Change:
    """One quote :func:`refresh_quotes` rewrites: ``link`` the marker's target as written."""

    line: int
    link: str
    old: str
    new: str
    value: float


def _quote_value(q: Quote, base: Path, counts_cache: dict[Path, dict[str, Any]]) -> float:
    """The current value of a count or cell marker (``InputError`` naming why there is none)."""
    if q.kind == "cell":
        return cell_value(base / q.source, q.selector)
    json_path = (base / q.source).with_suffix(".json")
    if json_path not in counts_cache:
        counts_cache[json_path] = read_counts(json_path)
    counts = counts_cache[json_path]
    if q.selector not in counts:
        raise InputError(f"no count {q.selector!r} in {json_path.name}")
    if counts[q.selector] is None:
        raise InputError(f"count {q.selector!r} is undefined in {json_path.name}")
    return float(counts[q.selector])


def plan_refresh(text: str, base: str | os.PathLike) -> tuple[str, list[Change], list[str]]:
    """Every count and cell marker of a Markdown ``text`` (links relative to ``base``) rewritten
    to its file's current value at the quote's precision (:func:`format_like`); quotes that
    already match are left as written. Returns (new text, changes, errors): an error is one line
    ``line <n>: <marker>: <why>`` for a marker whose file, count or cell is gone."""
    base = Path(base)
    cache: dict[Path, dict[str, Any]] = {}
    changes: list[Change] = []
    errors: list[str] = []
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines, start=1):
        edits = []
        for m, q in _line_quotes(i, line):
            if q.kind == "untraced":
                continue
            link = f"{q.source}#{q.selector}"
            try:
                value = _quote_value(q, base, cache)
                if quoted_matches(q.quote, value):
                    continue
                new = format_like(q.quote, value)
                if not quoted_matches(new, value):  # cannot happen unless the rounding disagrees
                    raise InputError(f"{new!r} does not round back to {value!r}")
            except InputError as e:
                errors.append(f"line {i}: [{q.quote}]({link}): {e}")
                continue
            changes.append(Change(i, link, q.quote, new, value))
            edits.append((m.start("quote"), m.end("quote"), new))
        for start, end, new in reversed(edits):
            line = line[:start] + new + line[end:]
        lines[i - 1] = line
    return "".join(lines), changes, errors


def refresh_quotes(md_path: str | os.PathLike, *, write: bool = True
                   ) -> tuple[list[Change], list[str]]:
    """Bring every count and cell marker of a Markdown file up to its file's current value
    (:func:`plan_refresh`). The page is rewritten atomically, only when ``write``, there is a
    change and no error (a page with a broken link is left as it is). Returns (changes, errors)."""
    md_path = Path(md_path)
    if not md_path.is_file():
        raise InputError(f"page not found: {md_path}")
    text = md_path.read_text(encoding="utf-8")
    new_text, changes, errors = plan_refresh(text, md_path.parent)
    if write and changes and not errors:
        write_text_atomic(md_path, new_text)
    return changes, errors


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gmwm_studies.counts refresh PAGE.md [--check]``: rewrite the page's count and
    cell markers to their files' current values and print each change (``--check``: write
    nothing, exit 1 on any stale quote). Exit 1 on a broken link (nothing written), 2 on bad
    arguments."""
    import argparse
    import sys

    ap = argparse.ArgumentParser(prog="python -m gmwm_studies.counts",
                                 description="Quoted numbers of a Markdown page and their files.")
    sub = ap.add_subparsers(dest="command", required=True)
    rp = sub.add_parser("refresh", help="rewrite every linked quote to its file's current value")
    rp.add_argument("page", help="Markdown page (links relative to its directory)")
    rp.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 when a quote is stale or a link broken")
    args = ap.parse_args(argv)
    try:
        changes, errors = refresh_quotes(args.page, write=not args.check)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    for c in changes:
        print(f"line {c.line}: [{c.old}] -> [{c.new}] ({c.link} = {c.value:.10g})")
    for e in errors:
        print(f"error: {e}", file=sys.stderr)
    if errors:
        print(f"{len(errors)} broken link(s): {args.page} left unchanged", file=sys.stderr)
        return 1
    if args.check:
        print(f"{len(changes)} stale quote(s) in {args.page}" if changes
              else f"every linked quote of {args.page} matches its file")
        return 1 if changes else 0
    print(f"{len(changes)} quote(s) rewritten in {args.page}" if changes
          else f"every linked quote of {args.page} already matches its file")
    return 0


def collect(tables: Iterable[tuple[str, pd.DataFrame, Mapping[str, Any], str, bool]]
            ) -> list[Count]:
    """:func:`study_counts` over (study, table, record, source, label_T) tuples, concatenated."""
    return [c for study, df, rec, src, lab in tables
            for c in study_counts(study, df, rec, src, label_T=lab)]


if __name__ == "__main__":
    raise SystemExit(main())
