"""Penalty factors of the model-selection criteria and what a ranking leaves open.

A criterion is ``objective + k * penalty`` with ``penalty`` the optimism trace of
:func:`gmwm.select.optimism` (the effective number of fitted parameters in objective units) and
``k`` a factor that may grow with the signal length ``T``:

* ``wic``: ``k = 2`` (an AIC-type estimate of the WV prediction error; R gmwm's rank_models);
* ``wic-hq``: ``k = 2 log log T`` (Hannan-Quinn: the slowest growth that still selects the
  generating model with probability -> 1; 4.5 at T = 2^14, 5.3 at T = 2^20);
* ``wic-log``: ``k = log T`` (BIC-type; 9.7 at T = 2^14, 13.9 at T = 2^20).

With efficient weights a component with one parameter enters when its squared z-value exceeds
about ``k``: ``wic`` keeps components from about 1.4 standard errors on, ``wic-hq`` from about
2.1-2.3, ``wic-log`` only from 3.1-3.7. Dropping a real random walk makes a navigation filter
over-confident, which costs more than a small spurious term; ``benchmarks/bench_selection.py``
measured the hit rates and the random-walk error of each criterion by the penalty alone
(``wic-log`` dropped a random walk at 3 SE in 85-100 % of the fits, ``wic`` in 0-3 %). Since
candidates the goodness-of-fit test rejects rank below those it accepts, a penalty can drop a
real component only where the model without it passes the test, and
``benchmarks/selection_penalty.py`` (the ranking as the library does it, with the parsimony step
of :func:`gmwm.select.order`) sets the default: ``DEFAULT`` = ``wic-hq``.

:func:`near_ties` and :func:`disagreements` say what a ranking does not settle: the models whose
criterion is within a few chi-square units of the best, and the components they add or drop
against the best, with the z-values of those components in the fits that have them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InputError
from .model import parse_model

__all__ = ["CRITERIA", "DEFAULT", "Difference", "disagreements", "factor", "near_ties",
           "ranking_notes"]

CRITERIA = ("wic", "wic-hq", "wic-log")
#: the criterion chosen by ``benchmarks/selection_penalty.py`` (benchmarks/README.md, its
#: block): under the library's ranking (accepted candidates first, then the parsimony step)
#: ``wic-hq`` ranked the generating model first at least as often as ``wic`` in every cell where
#: each component is >= 3 SE from 0, with fewer spurious components at 2^17-2^20 samples; the
#: accepted-first split already keeps a real component the test sees, which was ``wic``'s reason
#: (``benchmarks/bench_selection.py`` ranked by the penalty alone)
DEFAULT = "wic-hq"
#: a model is a near tie of the best when its criterion is within this many chi-square units
#: (the objective divided by ``tr(Omega V) / J``) of the best's
TIE_CHI2 = 2.0


def factor(criterion: str, n_samples: int) -> float:
    """Penalty factor ``k`` of ``criterion`` for a signal of ``n_samples`` samples."""
    T = max(int(n_samples), 16)
    if criterion == "wic":
        return 2.0
    if criterion == "wic-hq":
        return float(2.0 * np.log(np.log(T)))
    if criterion == "wic-log":
        return float(np.log(T))
    raise InputError(f"unknown criterion {criterion!r}; use one of {', '.join(CRITERIA)}")


def chi2_unit(entry: Any) -> float:
    """Objective units per chi-square unit of a ranked fit: ``tr(Omega V) / J`` with V its
    WV covariance (1 for efficient weights)."""
    res = entry.result
    V = getattr(res, "wv_cov", None)
    if V is None:
        return float("nan")
    try:
        return float(res.problem().chi2_scale(np.asarray(V, float)))
    except Exception:  # noqa: BLE001 - a ranking note must never break a ranking
        return float("nan")


def near_ties(ranking: Any, tol: float = TIE_CHI2) -> list[Any]:
    """Ranked entries (best excluded) whose criterion exceeds the best's by less than ``tol``
    chi-square units (criterion difference / the best fit's ``tr(Omega V) / J``). A candidate
    the goodness-of-fit test rejects is no tie of an accepted best, whatever its criterion."""
    ranked = ranking.ranked
    if len(ranked) < 2:
        return []
    unit = chi2_unit(ranked[0])
    if not np.isfinite(unit) or unit <= 0:
        return []
    best = ranked[0].criterion
    alpha = getattr(ranking, "gof_alpha", None)

    def rejected(e: Any) -> bool:
        return alpha is not None and hasattr(e, "rejected") and e.rejected(alpha)

    same = [e for e in ranked[1:] if rejected(e) == rejected(ranked[0])]
    return [e for e in same if (e.criterion - best) / unit < tol]


@dataclass(frozen=True)
class Difference:
    """A component type present in one of two models and not (as often) in the other, with its
    z-values (scale estimate / SE) in the fit that has it (NaN at the boundary: z = 0)."""

    process: str
    in_model: str
    z: tuple[float, ...]


def _z_values(result: Any, process: str) -> tuple[float, ...]:
    out = []
    theta = np.asarray(result.params, float)
    se = np.asarray(result.se, float)
    for c in result.model.components:
        if c.process.name == process:
            i = c.start + c.process.scale_index
            out.append(0.0 if theta[i] == 0 else
                       float(abs(theta[i]) / se[i]) if np.isfinite(se[i]) and se[i] > 0
                       else float("nan"))
    return tuple(out)


def disagreements(best: Any, other: Any) -> list[Difference]:
    """Components on which two ranked entries differ (by process count), each with its z-values
    in the fit that has more of that process."""
    cb, co = parse_model(best.model), parse_model(other.model)
    out = []
    for proc in sorted(set(cb) | set(co)):
        nb, no = cb.get(proc, 0), co.get(proc, 0)
        if nb == no:
            continue
        holder = best if nb > no else other
        z = _z_values(holder.result, proc) if holder.result is not None else ()
        out.append(Difference(proc, holder.model, z))
    return out


def ranking_notes(ranking: Any, tol: float = TIE_CHI2) -> list[str]:
    """Lines for a ranking's output: each near tie of the best and the components they disagree
    on, with z-values, e.g. ``near tie: WN+AR1 (criterion +0.8 chi2 units) drops RW (z = 3.6 in
    WN+AR1+RW)``."""
    ranked = ranking.ranked
    if len(ranked) < 2:
        return []
    unit = chi2_unit(ranked[0])
    lines = []
    for e in near_ties(ranking, tol):
        parts = []
        for d in disagreements(ranked[0], e):
            verb = "adds" if d.in_model == e.model else "drops"
            zs = ", ".join(f"{z:.2g}" for z in d.z) if d.z else "?"
            parts.append(f"{verb} {d.process} (z = {zs} in {d.in_model})")
        lines.append(f"near tie: {e.model} (criterion +{(e.criterion - ranked[0].criterion) / unit:.2g}"
                     f" chi2 units) " + ("; ".join(parts) if parts else "same components"))
    return lines
