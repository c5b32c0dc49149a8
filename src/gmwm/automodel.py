"""A default error model chosen by the data, for one sensor axis (``docs/METHODS.md`` §6.1).

:func:`choose_model` answers "which model?" when the user gives none: it builds the usual IMU
candidates, ranks them with the WIC of :mod:`gmwm.select` and returns the best-ranked candidate
that the goodness-of-fit test of :mod:`gmwm.gof` does not reject, with the whole ranking.

Why a module of its own: :mod:`gmwm.select` ranks a *given* candidate set by a criterion (the
statistics); this module is policy on top of it and of :mod:`gmwm.gof` -- which candidates an
IMU axis gets, when a sinusoid is worth trying, how far the Gauss-Markov ladder is climbed, and
what is reported when the data reject every candidate.

The rule
--------
1. Candidates. Sums of white noise (WN), quantisation noise (QN), random walk (RW), drift (DR)
   and 0..``max_gm`` Gauss-Markov terms (GM; an AR1 with phi in (0, 1), the usual model of bias
   instability over a finite band of scales). For a gyroscope or an accelerometer every
   candidate contains WN and RW (:data:`REQUIRED`): they are the two terms a navigation filter
   needs, and a random walk the data cannot distinguish from 0 is then reported with an interval
   from 0 (the filter configuration writes its upper bound) instead of being silently absent.
   Without a kind, every non-empty sum is a candidate. Candidates with as many parameters as
   scales are left out (their fit could not be tested).
2. Sinusoid. SIN candidates are added when the WV shows a *bump*
   (:func:`wv_bump`): between two adjacent scales it falls significantly faster than
   ``tau^-1`` (the upper CI bound of the longer scale below the lower CI bound of the shorter
   one times ``tau_j / tau_{j+1}``) after a significant rise (some shorter scale whose upper CI
   bound is below that lower bound). No sum of WN, RW, DR and GM falls faster than ``tau^-1``
   (a GM's WV falls at most like ``tau^-1``), and QN, which does (``tau^-2``), is largest at the
   shortest scale, so it cannot follow a rise; a sinusoid rises like ``tau^2`` and falls like
   ``tau^-2`` past its period. A sinusoid whose WV peaks at the first scale (period of a few
   samples) looks like QN to the WV and is not flagged. In each stage the SIN candidates are the
   stage's best candidate plus one SIN, and that without each optional linear term (QN, DR) in
   turn (:func:`_sin_variants`); the rule only adds candidates: the criterion still decides.
3. Stages. Candidates with k GM terms are fitted as stage k, k = 0, 1, ...: stage k + 1 is fitted
   only while stage k improved the best criterion of the earlier stages, or while no candidate
   fitted so far passes the goodness-of-fit test, stage k did not improve it by less than a near
   tie (:data:`gmwm.criteria.TIE_CHI2` chi-square units) and the *probe* -- the best candidate so
   far plus one GM, fitted first -- improves it by at least a near tie: when every candidate is
   rejected (motion, a process outside the candidates) and a GM term no longer helps, a further
   one will not make a candidate pass. A further GM term costs the most (its shape is searched
   jointly with the others). From stage 1 on, an optional linear term (QN, DR) at zero in every
   candidate of a stage that has it is left out of the later stages (:attr:`Choice.dropped_terms`).
   All stages share one search memo (:func:`gmwm.search.shared_memo`).
4. Choice. The candidates are ranked by the criterion (default :data:`gmwm.criteria.DEFAULT`,
   WIC-HQ). The chosen model is the best-ranked one whose goodness-of-fit p-value is at
   least ``alpha`` (:data:`gmwm.gof.ALPHA`, 1 %); a candidate whose test cannot be computed
   does not pass. When every
   candidate is rejected, the best-ranked one is returned with a warning saying so
   (:attr:`Choice.warnings`) and naming the likely causes in the order the data show them
   (:attr:`Choice.rejection_hint`, :func:`gmwm.verdict.rejection_causes`: too short, on-board
   low-pass filtering, and -- from what the calibration path passes in
   (:meth:`Choice.with_evidence`) -- motion and temperature); its fit carries the test's own
   rejection warning too. The chosen
   model is refitted with :func:`gmwm.fit`'s default standard errors, so ``Choice.result`` is
   what ``gmwm.fit(x, choice.model)`` returns.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .criteria import DEFAULT, TIE_CHI2, chi2_unit
from .errors import GMWMError, InputError
from .gof import ALPHA as GOF_ALPHA
from .model import Model, parse_model, spec_of
from .processes import PROCESSES
from .search import shared_memo
from .select import Ranking, merge, rank_models
from .settings import prepare_wv

__all__ = ["KINDS", "MAX_GM", "REQUIRED", "Bump", "Choice", "candidate_models", "choose_model",
           "wv_bump"]

KINDS = ("gyroscope", "accelerometer")
#: the most GM terms a candidate gets
MAX_GM = 3
#: components every candidate of a sensor kind contains (the terms a navigation filter needs)
#: (the processes with a ``filter_term``: WN and RW)
REQUIRED: dict[str, tuple[str, ...]] = {
    k: tuple(n for n, p in PROCESSES.items() if p.filter_term is not None) for k in KINDS}
# the roles of the processes in the candidates (attributes of their classes): the one-per-model
# terms each candidate has or not, the slow correlated terms it has 0..max_gm of, the periodic one
_LINEAR = tuple(n for n, p in PROCESSES.items() if p.singleton)
_SLOW = tuple(n for n, p in PROCESSES.items() if p.slow_term)
_PERIODIC = next(n for n, p in PROCESSES.items() if p.oscillating)


# -- candidates -----------------------------------------------------------------------------------
def _check_kind(kind: str | None) -> None:
    if kind is not None and kind not in KINDS:
        raise InputError(f"unknown sensor kind {kind!r}; use one of {', '.join(KINDS)} or None")


def candidate_models(kind: str | None = None, *, max_gm: int = MAX_GM, sin: bool = False,
                     slow: str = "GM", n_gm: int | None = None) -> list[str]:
    """The candidate model strings of :func:`choose_model` (module docstring, rule 1), fewest
    components first: sums of QN, WN, RW, DR (those of :data:`REQUIRED` for ``kind`` always) and
    0..``max_gm`` ``slow`` terms (``"GM"`` or ``"AR1"``); with ``sin`` each also with one SIN.
    ``n_gm``: only the candidates with exactly that many slow terms (one stage)."""
    _check_kind(kind)
    if slow not in _SLOW:
        raise InputError(f"slow must be one of {', '.join(_SLOW)}, got {slow!r}")
    if not isinstance(max_gm, (int, np.integer)) or not 0 <= max_gm <= 5:
        raise InputError(f"max_gm must be an integer in 0..5, got {max_gm!r}")
    required = REQUIRED.get(kind, ()) if kind else ()
    optional = [c for c in _LINEAR if c not in required]
    counts_gm = range(max_gm + 1) if n_gm is None else [n_gm] if 0 <= n_gm <= max_gm else []
    out: list[str] = []
    for k in counts_gm:
        for r in range(len(optional) + 1):
            for extra in itertools.combinations(optional, r):
                counts = {c: 1 for c in (*required, *extra)}
                counts[slow] = k
                if sum(counts.values()) == 0:
                    continue
                for s in ((0, 1) if sin else (0,)):
                    spec = Model(spec_of({**counts, _PERIODIC: s})).spec
                    if spec not in out:
                        out.append(spec)
    return sorted(out, key=lambda m: (parse_model(m).get(slow, 0), Model(m).n_params))


@dataclass(frozen=True)
class Bump:
    """A significant rise of the WV to scale ``peak_s`` [s] followed by a fall faster than
    ``tau^-1`` to the next scale (``fall_to_s`` [s]); ``rise_from_s`` [s] the shortest scale of
    the rise. See :func:`wv_bump`."""

    rise_from_s: float
    peak_s: float
    fall_to_s: float

    def describe(self) -> str:
        return (f"the WV rises from {self.rise_from_s:.3g} s to {self.peak_s:.3g} s and falls "
                f"faster than tau^-1 to {self.fall_to_s:.3g} s (a periodic component?)")

    def to_json_dict(self) -> dict[str, float]:
        return {"rise_from_s": self.rise_from_s, "peak_s": self.peak_s,
                "fall_to_s": self.fall_to_s}


def wv_bump(wv: Any) -> Bump | None:
    """The first bump of a :class:`~gmwm.wv.WaveletVariance` by the rule of the module docstring
    (rule 2), judged with the WV's own confidence intervals, or None."""
    lo = np.asarray(wv.ci_low, float)
    hi = np.asarray(wv.ci_high, float)
    tau = np.asarray(wv.scales, float)
    for j in range(1, len(tau) - 1):
        steep = hi[j + 1] < lo[j] * tau[j] / tau[j + 1]
        rose = np.flatnonzero(hi[:j] < lo[j])
        if steep and rose.size:
            return Bump(float(tau[rose[0]] / wv.freq), float(tau[j] / wv.freq),
                        float(tau[j + 1] / wv.freq))
    return None


# -- the choice -----------------------------------------------------------------------------------
def _num(v: Any) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


@dataclass(frozen=True, eq=False)
class Choice:
    """What :func:`choose_model` chose and why.

    ``result``: the chosen model's fit (:class:`gmwm.estimator.GMWMResult`, default standard
    errors, its ``gof`` set); ``ranking``: every fitted candidate, best first
    (:class:`gmwm.select.Ranking`); ``p_values``: model -> goodness-of-fit p-value of its ranking
    fit (NaN: not testable); ``passed``: the chosen model passes the test at ``alpha`` (False:
    every candidate is rejected); ``kind`` the sensor kind; ``bump`` the WV bump that admitted
    SIN candidates (None: none seen, or ``sin`` given); ``not_fitted``: (stage, reason) of the
    GM stages left out; ``excluded``: candidates left out for having as many parameters as
    scales; ``cpu_seconds``/``seconds``: process CPU and wall time of the whole choice;
    ``dropped_terms``: (term, stage) of the optional linear terms no longer tried from that stage
    on (rule 3: at zero in every candidate of the stage before); ``slow``: the slow term the
    stages add (``"GM"``, or ``"AR1"`` with ``slow="AR1"``)."""

    result: Any
    ranking: Ranking
    p_values: dict[str, float]
    passed: bool
    alpha: float
    kind: str | None
    bump: Bump | None = None
    not_fitted: list[tuple[int, str]] = field(default_factory=list)
    excluded: list[str] = field(default_factory=list)
    cpu_seconds: float = 0.0
    seconds: float = 0.0
    dropped_terms: list[tuple[str, int]] = field(default_factory=list)
    slow: str = "GM"
    #: what the calibration path knows beyond the WV (motion, temperature:
    #: :class:`gmwm.verdict.Evidence`) for the "every candidate rejected" hint; None: the WV alone
    evidence: Any = None
    #: (samples, :func:`gmwm.verdict.identifiability` of the chosen fit at that length) where the
    #: calibration path computed it beside the fit; None: the hint computes it
    identified: tuple[int, Any] | None = None

    def with_evidence(self, evidence: Any) -> Choice:
        """This choice with the calibration path's :class:`gmwm.verdict.Evidence` (motion flagged
        in this channel, a bias following the temperature) for its rejection hint."""
        return dataclasses.replace(self, evidence=evidence)

    @functools.cached_property
    def rejection_hint(self) -> str:
        """Why every candidate may be rejected: the likely causes in the order the data show
        them (:func:`gmwm.verdict.rejection_causes` on the chosen fit and :attr:`evidence`)."""
        from .verdict import causes_text, rejection_causes

        n = int(getattr(self.result.wv, "n_samples", 0))
        weak = self.identified[1] if self.identified and self.identified[0] == n else None
        return causes_text(rejection_causes(self.result, evidence=self.evidence, weak=weak))

    # -- the result protocol, delegated to the chosen fit ---------------------------------------
    @property
    def model(self) -> Model:
        return self.result.model

    @property
    def params(self) -> np.ndarray:
        return self.result.params

    @property
    def param_names(self) -> list[str]:
        return self.result.param_names

    @property
    def se(self) -> np.ndarray:
        return self.result.se

    @property
    def settings(self) -> Any:
        return self.result.settings

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        return self.result.conf_int(alpha)

    # -- the choice ------------------------------------------------------------------------------
    @property
    def rank(self) -> int:
        """1-based rank of the chosen model in the ranking."""
        return 1 + [e.model for e in self.ranking.ranked].index(self.result.model.spec)

    @property
    def notes(self) -> list[str]:
        """Why this model: candidates with a lower criterion that the test rejects (ranked below
        every accepted one), the parsimony steps, the ranking's near ties, the bump, the stages
        not fitted."""
        out = []
        chosen = self.result.model.spec
        mine = next((e.criterion for e in self.ranking.ranked if e.model == chosen), np.inf)
        lower = [e.model for e in self.ranking.ranked
                 if e.criterion < mine and e.rejected(self.alpha)]
        if lower and self.passed:
            rej = ", ".join(f"{m} (p {fmt_p(self.p_values.get(m, np.nan))})" for m in lower)
            out.append(f"lower {self.ranking.criterion.upper()} than {chosen} but rejected by "
                       f"the goodness-of-fit test, so ranked below every accepted candidate: "
                       f"{rej}")
        # the parsimony step (gmwm.select.order): components the data do not show, removed
        out += [f"parsimony: {st.describe()}" for st in self.ranking.simplified]
        out += self.ranking.notes
        if self.bump is not None:
            out.append(f"SIN candidates tried: {self.bump.describe()}")
        if self.not_fitted:
            ks = ", ".join(str(k) for k, _ in self.not_fitted)
            out.append(f"candidates with {ks} slow terms not fitted: {self.not_fitted[0][1]}")
        for term, k in self.dropped_terms:
            out.append(f"{term} not tried with {k} or more {self.slow} terms: it was at zero in "
                       f"every candidate with {k - 1}")
        if self.excluded:
            out.append(f"{len(self.excluded)} candidate(s) left out: as many parameters as "
                       f"scales ({', '.join(self.excluded)})")
        return out

    @property
    def warnings(self) -> list[str]:
        """The choice's own warning (every candidate rejected), then the chosen fit's warnings
        (the test's rejection warning among them)."""
        out = []
        if not self.passed:
            tested = [p for p in self.p_values.values() if np.isfinite(p)]
            best = f"largest p {fmt_p(max(tested))}" if tested else "no candidate testable"
            out.append(
                f"every candidate model is rejected by the goodness-of-fit test at "
                f"{self.alpha:g} ({len(self.ranking.ranked)} candidates, {best}): the reported "
                f"model {self.result.model.spec} is only the best-ranked; its coefficients "
                f"describe a wrong model ({self.rejection_hint})")
        return out + list(self.result.warnings)

    def rows(self) -> list[dict[str, Any]]:
        """The ranking as rows: rank, model, n_params, delta_chi2 (criterion above the best in
        chi-square units of the best fit; see :mod:`gmwm.criteria`), p_value, rejected, chosen."""
        from .criteria import chi2_unit

        ranked = self.ranking.ranked
        unit = chi2_unit(ranked[0]) if ranked else float("nan")
        chosen = self.result.model.spec
        out = []
        for i, e in enumerate(ranked, 1):
            p = self.p_values.get(e.model, float("nan"))
            out.append({"rank": i, "model": e.model, "n_params": e.n_params,
                        "delta_chi2": _num((e.criterion - ranked[0].criterion) / unit),
                        "p_value": _num(p), "rejected": bool(np.isfinite(p) and p < self.alpha),
                        "chosen": e.model == chosen})
        return out

    def table(self) -> tuple[list[str], list[tuple[str, ...]]]:
        """Headers and text rows of the ranking table (report and :meth:`summary`)."""
        headers = ["rank", "model", "params", f"{self.ranking.criterion.upper()} - best [chi2]",
                   "GOF p", "choice"]
        rows = []
        for r in self.rows():
            d = r["delta_chi2"]
            p = r["p_value"]
            rows.append((str(r["rank"]), r["model"], str(r["n_params"]),
                         "–" if d is None else f"{d:.3g}",
                         "–" if p is None else fmt_p(p).lstrip("= "),
                         "chosen" if r["chosen"] else ("rejected" if r["rejected"] else "")))
        return headers, rows

    def headline(self) -> str:
        """One line, e.g. ``model WN+GM+RW chosen for the gyroscope: rank 1 of 16 by WIC,
        goodness of fit p = 0.57``."""
        p = self.p_values.get(self.result.model.spec, np.nan)
        who = f" for the {self.kind}" if self.kind else ""
        verdict = (f"goodness of fit p {fmt_p(p)}" if self.passed
                   else f"REJECTED like every candidate (p {fmt_p(p)})")
        return (f"model {self.result.model.spec} chosen{who}: rank {self.rank} of "
                f"{len(self.ranking.ranked)} by {self.ranking.criterion.upper()}, {verdict}")

    def summary(self) -> str:
        """The headline, the ranking table with each candidate's goodness-of-fit p-value, the
        notes and warnings, then the chosen fit's own summary."""
        headers, rows = self.table()
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
        fmt = lambda cells: "  ".join(c.rjust(w) if i != 1 else c.ljust(w)
                                      for i, (c, w) in enumerate(zip(cells, widths, strict=True)))
        lines = [self.headline(), fmt(headers), *(fmt(r) for r in rows)]
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"warning: {w}" for w in self.warnings[:1] if not self.passed]
        return "\n".join(lines + ["", self.result.summary()])

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """model, kind, passed, alpha, rank, criterion, candidates (:meth:`rows`), near_ties,
        notes, warnings, bump, not_fitted, dropped_terms, excluded, cpu_seconds, seconds, result (the chosen
        fit's :meth:`~gmwm.estimator.GMWMResult.to_json_dict`)."""
        from .results import json_safe

        return json_safe({
            "model": self.result.model.spec, "kind": self.kind, "passed": self.passed,
            "alpha": self.alpha, "rank": self.rank, "criterion": self.ranking.criterion,
            "penalty_factor": self.ranking.factor, "candidates": self.rows(),
            "near_ties": self.ranking.near_ties(), "notes": self.notes,
            "warnings": self.warnings,
            "bump": None if self.bump is None else self.bump.to_json_dict(),
            "not_fitted": [{"n_gm": k, "reason": why} for k, why in self.not_fitted],
            "dropped_terms": [{"term": t, "from_n_gm": k} for t, k in self.dropped_terms],
            "excluded": list(self.excluded), "cpu_seconds": self.cpu_seconds,
            "seconds": self.seconds, "result": self.result.to_json_dict()})


def fmt_p(p: float) -> str:
    from .gof import fmt_p as fmt

    return "not testable" if not np.isfinite(p) else fmt(p)


def _with(spec: str, term: str, n: int = 1) -> str:
    """``spec`` with ``n`` more ``term`` components (canonical model string)."""
    counts = dict(parse_model(spec))
    counts[term] = counts.get(term, 0) + n
    return Model(spec_of(counts)).spec


def _sin_variants(spec: str, kind: str | None) -> list[str]:
    """The SIN variants rule 2 fits for a stage whose best candidate is ``spec``: ``spec`` with
    one SIN, and that without each of its optional linear terms (a sinusoid can stand in for QN
    or DR)."""
    required = REQUIRED.get(kind, ()) if kind else ()
    counts = dict(parse_model(spec))
    out = [_with(spec, _PERIODIC)]
    for c in _LINEAR:
        if counts.get(c) and c not in required and sum(counts.values()) > 1:
            out.append(_with(Model(spec_of({**counts, c: 0})).spec, _PERIODIC))
    return out


def choose_model(data: Any, *, freq: float | None = None, kind: str | None = None,
                 max_gm: int = MAX_GM, sin: bool | str = "auto", slow: str = "GM",
                 criterion: str = DEFAULT, alpha: float = GOF_ALPHA, levels: int | None = None,
                 robust: bool = False, eff: float = 0.6, seed: int = 0,
                 n_starts: int | None = None,
                 progress: Callable[[int, int, str], None] | None = None) -> Choice:
    """Choose an error model for one sensor axis (the rule: module docstring).

    Parameters
    ----------
    data : 1-D signal (per-sample units) or a :class:`~gmwm.wv.WaveletVariance` (then a drift's
        sign is not identified and ``robust`` is not available).
    freq : sampling frequency [Hz] of a signal (GM correlation times in seconds use it).
    kind : ``"gyroscope"``, ``"accelerometer"`` (every candidate then has WN and RW) or None;
        from a signal unit: ``gmwm.units.unit_system(units).sensor``.
    max_gm : the most GM (or ``slow``) terms of a candidate (0..5, default 3).
    sin : ``"auto"`` (SIN candidates when :func:`wv_bump` sees a bump), True or False.
    slow : ``"GM"`` (default) or ``"AR1"`` (also negative correlation) for the slow terms.
    criterion : ranking criterion of :mod:`gmwm.criteria` (default :data:`DEFAULT`, WIC-HQ).
    alpha : level of the goodness-of-fit test a chosen model must pass (default
        :data:`gmwm.gof.ALPHA`, 0.01).
    levels, robust, eff, seed, n_starts : as in :func:`gmwm.fit` (one WV for all candidates).
    progress : called as ``progress(i, n, model)`` before fitting candidate ``i`` (``n`` an
        upper bound: the number of candidates if every stage and SIN variant were fitted).

    Returns a :class:`Choice`; :class:`~gmwm.errors.GMWMError` if no candidate can be fitted.
    """
    from . import fit

    _check_kind(kind)
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha}")
    if sin not in ("auto", True, False):
        raise InputError(f"sin must be 'auto', True or False, got {sin!r}")
    cpu0, wall0 = time.process_time(), time.perf_counter()
    wv_opts = {"levels": levels, "robust": robust, "eff": eff}
    wv = prepare_wv(data, freq=freq, **wv_opts).wv
    bump = wv_bump(wv) if sin == "auto" else None
    use_sin = bool(bump) if sin == "auto" else bool(sin)
    everything = candidate_models(kind, max_gm=max_gm, sin=use_sin, slow=slow)
    excluded = [m for m in everything if Model(m).n_params >= wv.n_levels]
    n_total = len(everything) - len(excluded)
    done = 0

    def report(i: int, n: int, spec: str) -> None:
        if progress is not None:
            progress(done + i, n_total, spec)

    # one memo for every stage and the refit: a stage's candidates nest the earlier stages'
    with shared_memo():
        rankings: list[Ranking] = []
        p_values: dict[str, float] = {}
        not_fitted: list[tuple[int, str]] = []
        dropped: list[tuple[str, int]] = []  # (optional linear term, first stage without it)
        best_so_far = best_before = stage_best = np.inf

        def rank(specs: list[str]) -> Ranking:
            nonlocal done
            r = rank_models(data, specs, criterion=criterion, freq=freq, seed=seed,
                            n_starts=n_starts, progress=report, gof_alpha=alpha, **wv_opts)
            done += len(specs)
            rankings.append(r)
            for e in r.ranked:
                p_values[e.model] = e.p_value
            return r

        for k in range(max_gm + 1):
            gone = {t for t, _ in dropped}
            base = [m for m in candidate_models(kind, max_gm=max_gm, slow=slow, n_gm=k)
                    if m not in excluded and not gone & set(parse_model(m))]
            if not base:
                continue
            n_before = len(rankings)
            if rankings:
                passing = any(p >= alpha for p in p_values.values() if np.isfinite(p))
                best = merge(rankings).ranked[0]
                tie = TIE_CHI2 * chi2_unit(best)
                why = None
                probe = _with(best.model, slow)
                if passing and stage_best >= best_before:
                    why = (f"{k - 1} {slow} did not lower the best {criterion.upper()} of the "
                           f"candidates with fewer, and a candidate already passes the "
                           "goodness-of-fit test")
                elif not passing and np.isfinite(tie) and stage_best > best_before - tie:
                    why = (f"{k - 1} {slow} lowered the best {criterion.upper()} of the "
                           f"candidates with fewer by less than a near tie ({TIE_CHI2:g} "
                           "chi-square units) and every candidate is rejected: a further term "
                           "would not make one pass")
                elif not passing and np.isfinite(tie) and probe not in excluded:
                    # every candidate is rejected: the stage is fitted only if one more slow term
                    # on the best candidate gains a near tie (rule 3)
                    try:
                        gain = best.criterion - rank([probe]).best.criterion
                    except GMWMError:
                        gain = -np.inf
                    if not gain >= tie:
                        why = (f"a further {slow} on the best candidate {best.model} lowered its "
                               f"{criterion.upper()} by less than a near tie ({TIE_CHI2:g} "
                               "chi-square units) and every candidate is rejected: a further "
                               "term would not make one pass")
                if why is not None:
                    not_fitted += [(m, why) for m in range(k, max_gm + 1)]
                    break
            try:
                todo = [m for m in base if m not in p_values]  # the probe is already fitted
                if todo:
                    rank(todo)
                if use_sin:  # rule 2: SIN variants of the stage's best and its simplifications
                    fitted = [e for e in merge(rankings).ranked if e.model in base]
                    sins = [m for m in _sin_variants(fitted[0].model, kind)
                            if m not in excluded and m not in p_values] if fitted else []
                    if sins:
                        rank(sins)
            except GMWMError:
                if rankings:  # every candidate of this stage failed: the earlier stages stand
                    not_fitted.append((k, "no candidate with this many terms could be fitted"))
                    continue
                raise
            # rule 3: from one slow term on, an optional linear term at zero in every candidate
            # of this stage that has it is not tried with more slow terms (a further one takes
            # scales from it rather than give; not from stage 0, where the first slow term moves
            # the whole fit: measured, QN at zero without a GM was needed with one)
            stage_entries = [e for r_ in rankings[n_before:] for e in r_.ranked]
            for term in _LINEAR:
                if k == 0 or term in gone or term in (REQUIRED.get(kind, ()) if kind else ()):
                    continue
                having = [e for e in stage_entries if parse_model(e.model).get(term)]
                if having and all(f"{term}[1]" in (e.result.diagnostics or {}).get("at_boundary", ())
                                  for e in having):
                    dropped.append((term, k + 1))
            best_before = best_so_far
            stage_best = min(e.criterion for e in stage_entries)
            best_so_far = min(best_so_far, stage_best)
        if not rankings:
            raise GMWMError("no candidate model could be fitted")
        ranking = merge(rankings)
        ranked = ranking.ranked
        pick = next((e for e in ranked if p_values[e.model] >= alpha), None)
        passed = pick is not None
        pick = pick if pick is not None else ranked[0]
        result = fit(data, pick.model, freq=wv.freq, seed=seed, alpha=wv.alpha,
                     **({"n_starts": n_starts} if n_starts is not None else {}), **wv_opts)
        if result.gof is not None:  # the refit's own test (the same estimate: the same p-value)
            p_values[pick.model] = float(result.gof.p_value)
            passed = passed and p_values[pick.model] >= alpha
    return Choice(result, ranking, p_values, passed, alpha, kind, bump if use_sin else None,
                  not_fitted, excluded, time.process_time() - cpu0, time.perf_counter() - wall0,
                  [(t, k) for t, k in dropped  # the drops that shaped a fitted stage
                   if k in {parse_model(e.model).get(slow, 0) for e in ranking.ranked}], slow)
