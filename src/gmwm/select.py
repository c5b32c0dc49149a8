"""Model selection for the GMWM: fit candidate models to one WV and rank them.

Criterion (the Wavelet Information Criterion, WIC, derived here as a covariance penalty)
-----------------------------------------------------------------------------------------
Write ``nu_hat`` for the estimated WV, ``V`` its covariance, ``Omega`` the GMWM weight matrix,
``nu(theta)`` the model WV and ``||r||^2 = r' Omega r``. Judge a fitted model by how well it
predicts the WV of a *new, independent* signal of the same length, ``nu*``:

    PE = E || nu* - nu(theta_hat) ||^2.

The in-sample objective ``|| nu_hat - nu(theta_hat) ||^2`` is optimistic because ``theta_hat``
was fitted to ``nu_hat``. Writing both residuals around the true WV ``nu_0`` and using the
independence of ``nu*`` from ``theta_hat`` gives exactly

    PE = E[objective] + 2 E[(nu_hat - nu_0)' Omega (nu(theta_hat) - nu_0)].

Linearising the GMWM estimator, ``nu(theta_hat) - nu_0 ~ A G (nu_hat - nu_0)`` with
``A = d nu / d theta'`` and ``G = (A' Omega A)^+ A' Omega``, so the optimism is
``2 tr(Omega A G V)`` and

    WIC = objective + 2 * tr(Omega A (A' Omega A)^+ A' Omega V).

With efficient weights (``Omega = V^-1``) the trace is rank(A) = the number of identified
parameters (an AIC-type penalty); with the default CI weights it adapts to the weights used.
Objective and trace both scale with ``Omega``, so the ranking does not depend on its scale.
``V`` is the covariance the fit used for its standard errors: the Gaussian diagonal
``2 nu_hat_j^2 / eta_j`` (``eta_j`` includes the efficiency loss of a robust WV), or the caller's
matrix when ``weights`` is one (e.g. a bootstrap covariance).

Why this criterion: it needs only quantities every GMWM fit already has (Jacobian, weights, WV
covariance), it costs nothing beyond the fits (cross-validating the WV would need refits on split
signals, whose halves have a different WV precision), and it is the GMWM analogue of AIC/Mallows'
Cp, reducing to them in the efficient case.

The penalty factor: ``criterion="wic"`` uses ``k = 2`` and estimates the prediction error;
``"wic-hq"`` (the default, ``k = 2 log log T``) and ``"wic-log"`` (``k = log T``, the BIC
analogue) penalise more and need more data to admit a weak component (:mod:`gmwm.criteria`
gives the factors and the reasons). By the penalty alone ``wic`` kept weak real components best
(``benchmarks/bench_selection.py``); with the goodness-of-fit split below, a penalty can drop a
real component only where the model without it passes the test, and
``benchmarks/selection_penalty.py`` found ``wic-hq`` at least as good as ``wic`` in every cell,
with fewer spurious components. ``Ranking`` keeps objective and trace,
so :func:`rerank` gives another criterion without refitting, and its notes
(:func:`gmwm.criteria.ranking_notes`) name the near ties of the best model and the components
they disagree on, with their z-values.
Ties (a superset whose extra component is estimated at 0) go to the smaller model.

Consistency with the goodness-of-fit test (:func:`order`): candidates the test accepts rank
above those it rejects, and a first-ranked accepted candidate loses each SIN/GM/AR1 component
whose removal gives another accepted candidate (the parsimony step; those components' shape
parameter is unidentified at scale 0, so the parameter-count penalty does not price them). A
ranking in which every candidate is rejected is the criterion's alone.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .criteria import CRITERIA, DEFAULT, disagreements, factor, near_ties, ranking_notes
from .errors import GMWMError, InputError, ModelError
from .gof import ALPHA as GOF_ALPHA
from .gof import gof_test
from .model import Model, as_model, parse_model, spec_of
from .processes import PROCESSES, SINGLETONS
from .search import shared_memo
from .settings import prepare_wv
from .wv import WaveletVariance

__all__ = ["CRITERIA", "DEFAULT", "PARSIMONY", "RankedModel", "Ranking", "Simplification",
           "auto_candidates", "merge", "optimism", "order", "rank_models", "rerank",
           "select_model"]

_LOG10E = np.log10(np.e)
# caps of the automatic candidate set: up to 3 AR1/GM and 2 SIN components
MAX_AR = 3
MAX_SIN = 2
_SINGLE = tuple(n for n in PROCESSES if n in SINGLETONS)  # QN, WN, RW, DR
#: component types the parsimony step may remove from the first-ranked candidate: those whose
#: shape parameter (a sinusoid's frequency, a GM's beta, an AR1's phi) is not identified when
#: their scale is 0, so neither their z-value nor the criterion's parameter-count penalty
#: measures whether the data hold them (see :func:`order`)
PARSIMONY = ("SIN", "GM", "AR1")


@dataclass(frozen=True)
class RankedModel:
    """One candidate: its criterion value, objective, optimism trace ``penalty`` (the criterion is
    ``objective + k * penalty``), number of parameters and the fit (None if it failed: ``error``)."""

    model: str
    criterion: float
    objective: float
    penalty: float
    n_params: int
    converged: bool
    result: Any = None
    error: str | None = None
    #: goodness-of-fit p-value of this fit (:func:`gmwm.gof.gof_test`; NaN: not tested or not
    #: testable, e.g. as many parameters as scales)
    p_value: float = float("nan")

    def rejected(self, alpha: float = GOF_ALPHA) -> bool:
        """True if the goodness-of-fit test rejects this candidate at ``alpha``."""
        return bool(np.isfinite(self.p_value) and self.p_value < alpha)

    def to_json_dict(self) -> dict[str, Any]:
        out = {"model": self.model, "criterion": _num(self.criterion),
               "objective": _num(self.objective), "n_params": self.n_params,
               "penalty": _num(self.penalty), "converged": self.converged,
               "p_value": _num(self.p_value), "rejected": self.rejected()}
        if self.error is not None:
            out["error"] = self.error
        return out


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


@dataclass(frozen=True)
class Simplification:
    """One step of the parsimony rule (:func:`order`): one ``component`` (a process name) removed
    from ``removed_from`` gives ``model``, which the goodness-of-fit test accepts (``p_value``)."""

    removed_from: str
    model: str
    component: str
    p_value: float

    def describe(self) -> str:
        return (f"{self.component} removed from {self.removed_from}: {self.model} passes the "
                f"goodness-of-fit test (p = {self.p_value:.3g}), so the data do not show the "
                f"{self.component}")

    def to_json_dict(self) -> dict[str, Any]:
        return {"removed_from": self.removed_from, "model": self.model,
                "component": self.component, "p_value": _num(self.p_value)}


@dataclass(frozen=True)
class Ranking:
    """Candidates ranked best first (:func:`order`): the fitted ones the goodness-of-fit test
    does not reject at ``gof_alpha`` by criterion, then the rejected ones by criterion, then
    failed ones; when the first is accepted, the parsimony step may put a candidate without one
    of its SIN/GM/AR1 components first (:attr:`simplified`). A candidate the test rejects is
    never ranked above one it accepts (a lower criterion does not make a wrong model right)."""

    entries: list[RankedModel]
    criterion: str
    factor: float
    wv: WaveletVariance
    #: sign of the signal's mean slope (None when a WV was ranked): the fits' drift sign
    drift_sign: float | None = None
    #: level of the goodness-of-fit test that splits the ranking (accepted first)
    gof_alpha: float = GOF_ALPHA
    #: component types the parsimony step may remove (:data:`PARSIMONY`; () = no such step)
    parsimony: tuple[str, ...] = PARSIMONY
    #: the parsimony steps that moved the first-ranked candidate, in order (:func:`order`)
    simplified: tuple[Simplification, ...] = ()

    @property
    def best(self) -> RankedModel:
        return self.entries[0]

    @property
    def ranked(self) -> list[RankedModel]:
        """The candidates that were fitted, best first."""
        return [e for e in self.entries if e.error is None]

    @property
    def skipped(self) -> list[RankedModel]:
        return [e for e in self.entries if e.error is not None]

    @property
    def notes(self) -> list[str]:
        """What the ranking leaves open: each near tie of the best model and the components they
        disagree on, with their z-values (:func:`gmwm.criteria.ranking_notes`)."""
        return ranking_notes(self)

    def near_ties(self) -> list[dict[str, Any]]:
        """The near ties as data: model, criterion above the best in chi-square units and the
        components it adds or drops against the best (process, the model that has it, z-values
        of that process's components there)."""
        ranked = self.ranked
        if len(ranked) < 2:
            return []
        from .criteria import chi2_unit

        unit = chi2_unit(ranked[0])
        out = []
        for e in near_ties(self):
            diffs = [{"process": d.process, "in_model": d.in_model,
                      "change": "adds" if d.in_model == e.model else "drops",
                      "z": [_num(z) for z in d.z]} for d in disagreements(ranked[0], e)]
            out.append({"model": e.model,
                        "delta_chi2": _num((e.criterion - ranked[0].criterion) / unit),
                        "differences": diffs})
        return out

    def to_json_dict(self) -> dict[str, Any]:
        """criterion, penalty_factor, ranking (best first), near_ties (:meth:`near_ties`), notes
        (:attr:`notes`), skipped (if any)."""
        out: dict[str, Any] = {"criterion": self.criterion, "penalty_factor": self.factor,
                               "gof_alpha": self.gof_alpha,
                               "ranking": [e.to_json_dict() for e in self.ranked],
                               "near_ties": self.near_ties(), "notes": self.notes,
                               "parsimony": list(self.parsimony),
                               "simplified": [st.to_json_dict() for st in self.simplified]}
        if self.skipped:
            out["skipped"] = [{"model": e.model, "error": e.error} for e in self.skipped]
        return out

    def summary(self) -> str:
        lines = [(f"model ranking by {self.criterion.upper()} = objective + {self.factor:.3g} x "
                  f"penalty (best first)"),
                 (f"{'rank':>4}  {'model':<24}{'criterion':>12}{'objective':>12}{'penalty':>10}"
                  f"{'params':>7}  converged{'GOF p':>10}")]
        for i, e in enumerate(self.ranked, 1):
            lines.append(f"{i:>4}  {e.model:<24}{e.criterion:>12.5g}{e.objective:>12.5g}"
                         f"{e.penalty:>10.4g}{e.n_params:>7}  {'yes' if e.converged else 'NO ':<9}"
                         f"{e.p_value:>10.3g}{'  REJECTED' if e.rejected(self.gof_alpha) else ''}")
        for e in self.skipped:
            lines.append(f"   -  {e.model:<24} skipped: {e.error}")
        lines += [f"parsimony: {st.describe()}" for st in self.simplified]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


# -- criterion ------------------------------------------------------------------------------------
def optimism(result: Any, cov: np.ndarray | None = None) -> float:
    """``tr(Omega A (A' Omega A)^+ A' Omega V)`` of a GMWM fit (see the module docstring): the
    effective number of fitted parameters in units of the objective. ``cov`` = V of ``nu_hat``
    (default: the Gaussian diagonal ``2 nu_hat^2 / eta`` that the fit's standard errors use)."""
    wv = result.wv
    nu_hat = np.asarray(wv.variance, dtype=float)
    A = result.model.jacobian(result.params, wv.scales)
    V = np.diag(2.0 * nu_hat**2 / wv.edof) if cov is None else np.asarray(cov, dtype=float)
    if getattr(result, "method", "gmwm") == "armav":
        nu_model = np.maximum(result.model.wv(result.params, wv.scales), 1e-300)
        A = A * (_LOG10E / nu_model)[:, None]
        F = _LOG10E / nu_hat
        V = V * np.outer(F, F)
    omega = np.asarray(result.weights, dtype=float)
    with np.errstate(all="ignore"):
        # scale columns (parameters span 1e-12..1) so the pseudo-inverse keeps small directions;
        # columns that vanish (e.g. an AR1 phi whose variance is 0) carry no fitted direction
        d = np.sqrt(np.einsum("jp,jk,kp->p", A, omega, A))
        keep = np.isfinite(d) & (d > 0)
        if not np.any(keep):
            return 0.0
        As = A[:, keep] / d[keep]
        B = np.linalg.pinv(As.T @ omega @ As, hermitian=True, rtol=1e-10)
        H = omega @ As @ B @ As.T @ omega
        trace = float(np.sum(H * V.T))
    return trace if np.isfinite(trace) else float("nan")


# -- candidates -----------------------------------------------------------------------------------
def _spec(counts: dict[str, int]) -> str:
    return Model(spec_of(counts)).spec


def auto_candidates(base: str | Model, *, max_ar: int = MAX_AR, max_sin: int = MAX_SIN
                    ) -> list[str]:
    """Candidate set around a base model: the base, every model with one or two of its components
    removed, and every model with one component added (QN, WN, RW, DR if absent; one more AR1 -
    or GM if the base uses GM - while AR1 + GM < ``max_ar``; one more SIN while SIN < ``max_sin``).

    Size: at most 31 candidates over all admissible bases (QN+WN+AR1+GM+SIN+RW+DR; counted by
    enumeration), so a search costs a bounded number of fits. The base itself comes first; the
    order of the rest is fixed (removals, then additions).
    """
    spec = base.spec if isinstance(base, Model) else base
    counts = parse_model(spec)
    if counts.get("AR1", 0) + counts.get("GM", 0) > max_ar or counts.get("SIN", 0) > max_sin:
        raise ModelError(f"base model {spec!r} exceeds the automatic caps ({max_ar} AR1/GM, "
                         f"{max_sin} SIN)")
    order = list(PROCESSES)
    base_c = {k: counts.get(k, 0) for k in order}
    out: list[str] = [_spec(base_c)]

    def add(c: dict[str, int]) -> None:
        if sum(c.values()) == 0:
            return
        s = _spec(c)
        if s not in out:
            out.append(s)

    present = [k for k in order if base_c[k] > 0]
    # one removal, then two (two of one repeated type, or one each of two types)
    for k in present:
        add({**base_c, k: base_c[k] - 1})
    for a, b in itertools.combinations_with_replacement(present, 2):
        c = dict(base_c)
        c[a] -= 1
        c[b] -= 1
        if min(c.values()) >= 0:
            add(c)
    for k in _SINGLE:
        if base_c[k] == 0:
            add({**base_c, k: 1})
    if base_c["AR1"] + base_c["GM"] < max_ar:
        slow = "GM" if base_c["GM"] and not base_c["AR1"] else "AR1"
        add({**base_c, slow: base_c[slow] + 1})
    if base_c["SIN"] < max_sin:
        add({**base_c, "SIN": base_c["SIN"] + 1})
    return out


# -- ranking --------------------------------------------------------------------------------------
def rank_models(data: Any, models: Iterable[str | Model], *, criterion: str = DEFAULT,
                levels: int | None = None, freq: float | None = None,
                weights: str | np.ndarray = "ci", robust: bool = False, eff: float = 0.6,
                alpha: float = 0.05, n_starts: int | None = None, seed: int = 0,
                progress: Callable[[int, int, str], None] | None = None,
                cov: str = "gaussian", fit_kwargs: dict[str, Any] | None = None,
                gof_alpha: float = GOF_ALPHA,
                parsimony: Sequence[str] = PARSIMONY) -> Ranking:
    """Fit every candidate model to the WV of ``data`` and rank them, best first.

    Parameters
    ----------
    data : 1-D signal (per-sample units) or a :class:`~gmwm.wv.WaveletVariance`.
    models : model strings or Models (duplicates are fitted once). See :func:`auto_candidates`.
    criterion : ``"wic-hq"`` (default; factor 2 log log T), ``"wic"`` (objective + 2 x
        optimism, the estimated WV prediction error) or ``"wic-log"`` (factor log T); see the
        module docstring and :mod:`gmwm.criteria`.
    levels, freq, alpha : as in :func:`gmwm.fit` (the WV is computed once and shared).
    weights : as in :func:`gmwm.fit`; a (J, J) covariance also becomes V of the penalty.
    robust, eff : rank on the robust WV (``wvar(x, robust=True, eff=eff)``; needs a signal).
    n_starts, seed : passed to :func:`gmwm.fit`.
    progress : called as ``progress(i, n, model)`` before fitting candidate ``i`` of ``n``.
    cov : V of the penalty: ``"gaussian"`` (default; the diagonal ``2 nu_hat^2 / eta``, the same
        for every candidate, cheap) or ``"model"`` (the fit's own ``wv_cov``, the covariance of
        the WV estimate under each fitted candidate with the between-scale correlation; it
        penalises extra components less). Ignored when ``weights`` is a covariance matrix.
    fit_kwargs : further keywords for :func:`gmwm.fit` (default: with ``cov="gaussian"``,
        ``se_cov="gaussian"``, skipping the fit's own model-based WV covariance).
    gof_alpha : level of the goodness-of-fit test (:func:`gmwm.gof.gof_test`, run on every
        fitted candidate): a candidate it rejects is ranked below every candidate it accepts.
    parsimony : component types the parsimony step may remove from the first-ranked accepted
        candidate (default :data:`PARSIMONY`: SIN, GM, AR1; ``()`` turns the step off): see
        :func:`order`; the steps taken are :attr:`Ranking.simplified`.

    Candidates that cannot be fitted (e.g. more parameters than scales) are listed as skipped.
    """
    from . import fit  # the public estimator function (its module may move)

    wv, drift_sign, _ = prepare_wv(data, levels=levels, alpha=alpha, robust=robust, eff=eff,
                                   freq=freq)
    k = factor(criterion, wv.n_samples)
    specs: list[str] = []
    for m in models:
        spec = as_model(m, wv.freq).spec
        if spec not in specs:
            specs.append(spec)
    if not specs:
        raise InputError("no candidate models to rank")
    if not 0 < gof_alpha < 1:
        raise InputError(f"gof_alpha must lie in (0, 1), got {gof_alpha}")
    if cov not in ("gaussian", "model"):
        raise InputError(f"unknown cov {cov!r}; use 'gaussian' or 'model'")
    user_cov = None if isinstance(weights, str) else np.asarray(weights, dtype=float)
    if fit_kwargs is not None:
        options = dict(fit_kwargs)
    else:
        options = {"se_cov": "gaussian"} if cov == "gaussian" else {}
    if n_starts is not None:
        options["n_starts"] = n_starts
    entries: list[RankedModel] = []
    # the candidates nest each other: in one memo each distinct (sub)model is searched once
    with shared_memo():
        for i, spec in enumerate(specs, 1):
            if progress is not None:
                progress(i, len(specs), spec)
            model = Model(spec, wv.freq)
            try:
                res = fit(wv, model, weights=weights, seed=seed, **options)
            except GMWMError as exc:
                entries.append(RankedModel(spec, np.inf, np.inf, np.nan, model.n_params, False,
                                           error=str(exc).splitlines()[0]))
                continue
            res = res.with_drift_sign(drift_sign)
            V = user_cov
            if V is None and cov == "model":
                V = getattr(res, "wv_cov", None)
                if V is not None and wv.robust:  # the model covariance is the classical WV's
                    V = np.asarray(V) / wv.efficiency
            pen = optimism(res, V)
            crit = float(res.objective) + k * pen
            g = res.gof if res.gof is not None else gof_test(res)
            entries.append(RankedModel(spec, crit if np.isfinite(crit) else np.inf,
                                       float(res.objective), pen, model.n_params,
                                       bool(res.converged), res, p_value=float(g.p_value)))
    bad = [e for e in entries if e.error is not None]
    if len(bad) == len(entries):
        raise GMWMError("no candidate model could be fitted: " + "; ".join(
            f"{e.model}: {e.error}" for e in bad))
    kinds = _parsimony_kinds(parsimony)
    ordered, steps = order([e for e in entries if e.error is None], gof_alpha, kinds)
    return Ranking(ordered + bad, criterion, k, wv, drift_sign, gof_alpha, kinds, tuple(steps))


def _parsimony_kinds(kinds: Sequence[str]) -> tuple[str, ...]:
    out = tuple(kinds)
    unknown = [k for k in out if k not in PROCESSES]
    if unknown:
        raise InputError(f"unknown process(es) for the parsimony step: {', '.join(unknown)}")
    return out


def order(entries: Sequence[RankedModel], gof_alpha: float = GOF_ALPHA,
          parsimony: Sequence[str] = PARSIMONY
          ) -> tuple[list[RankedModel], list[Simplification]]:
    """Rank fitted candidates, best first, and say which parsimony steps moved the first.

    1. The candidates the goodness-of-fit test accepts at ``gof_alpha`` (or cannot test) come
       first, then those it rejects, each group by criterion. Criteria equal up to the
       optimiser's precision (relative 1e-7: a superset whose extra component sits at 0
       reproduces the submodel's fit, and a variance-like parameter at 0 has a zero Jacobian
       column) count as ties, won by fewer parameters.
    2. Parsimony (only when the first candidate is accepted, so a ranking where every candidate
       is rejected is left as step 1 made it): while the first candidate has a component of a
       type in ``parsimony`` whose removal gives another candidate that the test *accepts*
       (a finite p-value >= ``gof_alpha``), that candidate becomes the first (of several such
       removals, the one with the lowest criterion). The criterion's penalty counts parameters
       as a regular model would, but a SIN, GM or AR1 at scale 0 leaves its frequency, beta or
       phi unidentified, so the fit maximises over it and the objective drop it brings is
       larger than the penalty allows for when the data hold no such component: such a
       component is kept only when the model without it is rejected (the data show it).

    Returns the ordered entries (the first as chosen, then the others in the order of step 1)
    and the steps taken. Works on any entries with ``model``, ``criterion``, ``n_params`` and
    ``p_value`` (e.g. :class:`RankedModel` rebuilt from stored values).
    """
    kinds = tuple(parsimony)
    accepted = _by_criterion([e for e in entries if not e.rejected(gof_alpha)])
    rejected = _by_criterion([e for e in entries if e.rejected(gof_alpha)])
    steps: list[Simplification] = []
    if accepted and kinds:
        by_counts = {tuple(sorted(parse_model(e.model).items())): e for e in accepted
                     if np.isfinite(e.p_value) and e.p_value >= gof_alpha}
        top = accepted[0]
        while True:
            counts = parse_model(top.model)
            options = []
            for kind in kinds:
                if not counts.get(kind):
                    continue
                less = {k: v - (k == kind) for k, v in counts.items()}
                cand = by_counts.get(tuple(sorted((k, v) for k, v in less.items() if v > 0)))
                if cand is not None:
                    options.append((cand.criterion, cand.n_params, kind, cand))
            if not options:
                break
            _, _, kind, nxt = min(options, key=lambda o: (o[0], o[1]))
            steps.append(Simplification(top.model, nxt.model, kind, float(nxt.p_value)))
            top = nxt
        if steps:
            accepted = [top] + [e for e in accepted if e is not top]
    return accepted + rejected, steps


def _by_criterion(entries: list[RankedModel]) -> list[RankedModel]:
    ranked = sorted(entries, key=lambda e: e.criterion)
    out: list[RankedModel] = []
    i = 0
    while i < len(ranked):
        tol = 1e-7 * abs(ranked[i].criterion) + 1e-300
        j = i + 1
        while j < len(ranked) and ranked[j].criterion - ranked[i].criterion <= tol:
            j += 1
        out += sorted(ranked[i:j], key=lambda e: e.n_params)
        i = j
    return out


def rerank(ranking: Ranking, criterion: str) -> Ranking:
    """The same fits ranked by another criterion of :data:`CRITERIA` (no refitting)."""
    k = factor(criterion, ranking.wv.n_samples)
    entries = [dataclasses.replace(e, criterion=e.objective + k * e.penalty)
               for e in ranking.ranked]
    ordered, steps = order(entries, ranking.gof_alpha, ranking.parsimony)
    return Ranking(ordered + ranking.skipped, criterion, k, ranking.wv, ranking.drift_sign,
                   ranking.gof_alpha, ranking.parsimony, tuple(steps))


def merge(rankings: Sequence[Ranking]) -> Ranking:
    """One ranking of the candidates of several rankings of the same WV by the same criterion
    (e.g. candidates fitted in stages); a model in more than one keeps its first entry."""
    if not rankings:
        raise InputError("no rankings to merge")
    first = rankings[0]
    seen: set[str] = set()
    entries: list[RankedModel] = []
    for r in rankings:
        if r.criterion != first.criterion or r.gof_alpha != first.gof_alpha or \
                r.parsimony != first.parsimony or \
                r.wv.n_samples != first.wv.n_samples or \
                not np.array_equal(r.wv.variance, first.wv.variance):
            raise InputError("rankings to merge must rank the same WV by the same criterion")
        for e in r.entries:
            if e.model not in seen:
                seen.add(e.model)
                entries.append(e)
    fitted = [e for e in entries if e.error is None]
    ordered, steps = order(fitted, first.gof_alpha, first.parsimony)
    return Ranking(ordered + [e for e in entries if e.error is not None], first.criterion,
                   first.factor, first.wv, first.drift_sign, first.gof_alpha, first.parsimony,
                   tuple(steps))


def select_model(data: Any, models: Sequence[str | Model] | str | Model, **kwargs: Any) -> Any:
    """The fit (:class:`~gmwm.fit.GMWMResult`) of the best candidate by :func:`rank_models`
    (keywords as there). A single model string or Model is expanded with
    :func:`auto_candidates`. The winner is refitted with :func:`gmwm.fit`'s own standard-error
    covariance when the ranking skipped it (see ``fit_kwargs``), so the result is what
    ``gmwm.fit`` returns for that model."""
    from . import fit

    if isinstance(models, (str, Model)):
        models = auto_candidates(models)
    ranking = rank_models(data, models, **kwargs)
    best = ranking.best.result
    if kwargs.get("fit_kwargs") is None and kwargs.get("cov", "gaussian") == "gaussian":
        options = {k: kwargs[k] for k in ("weights", "seed", "n_starts") if kwargs.get(k) is not None}
        best = fit(ranking.wv, best.model, **options).with_drift_sign(ranking.drift_sign)
    return best
