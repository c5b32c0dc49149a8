"""The boundary of a fit: its settings (:class:`FitSettings`, validated once) and the wavelet
variance it starts from (:func:`prepare_wv`).

:func:`gmwm.fit` builds one :class:`FitSettings` from its keywords (or takes one), stores it on
the result as ``result.settings``, and ``result.fit_kwargs()`` repeats the fit from it; the model
selection, the bootstrap and the paper studies take the same object, so the options of a fit are
named, checked and defaulted here and nowhere else.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from .errors import InputError

__all__ = ["METHODS", "N_STARTS", "SE_COV_KINDS", "WEIGHT_KINDS", "FitSettings", "PreparedWV",
           "prepare_wv"]

#: Estimators: GMWM (f(x) = x), ARMAV (f = log10 of the Allan variance), AVSM (the Allan-variance
#: slope method, :mod:`gmwm.avsm`).
METHODS = ("gmwm", "armav", "avsm")
#: Named weight matrices (otherwise a (J, J) covariance of the WV estimate).
WEIGHT_KINDS = ("ci", "ci-eta3", "ci-mixture", "gaussian", "identity", "efficient")
#: Named covariances of the WV estimate behind the standard errors (otherwise a (J, J) matrix).
SE_COV_KINDS = ("model", "gaussian")
#: Default number of starts refined per model and submodel.
N_STARTS = 4

#: options that only the optimising estimators (GMWM, ARMAV) use, and only AVSM
_OPTIMISER_ONLY = ("weights", "n_starts", "reweight", "nested", "se_cov", "max_nfev")
_AVSM_ONLY = ("min_edof", "slope_tol")


def _int(name: str, v: Any, low: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
        what = "a positive" if low == 1 else "a non-negative"
        raise InputError(f"{name} must be {what} integer, got {v!r}")
    return int(v)


def _number(name: str, v: Any, ok: Any, what: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        x = float("nan")
    if isinstance(v, bool) or not np.isfinite(x) or not ok(x):
        raise InputError(f"{name} must be {what}, got {v!r}")
    return x


def _bool(name: str, v: Any) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise InputError(f"{name} must be True or False, got {v!r}")
    return bool(v)


def _kind_or_matrix(name: str, v: Any, kinds: tuple[str, ...], what: str) -> str | np.ndarray:
    if isinstance(v, str):
        if v not in kinds:
            raise InputError(f"unknown {name} {v!r}; use {', '.join(kinds)} or a covariance "
                             "matrix")
        return v
    try:
        V = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be one of {', '.join(kinds)} or a covariance matrix, "
                         f"got {type(v).__name__}") from None
    if V.ndim != 2 or V.shape[0] != V.shape[1] or V.shape[0] == 0:
        raise InputError(f"{what} must be a square (J, J) matrix, got shape {V.shape}")
    if not np.all(np.isfinite(V)) or np.any(np.diag(V) <= 0):
        raise InputError(f"{what} must be finite with a positive diagonal")
    V.setflags(write=False)
    return V


@dataclass(frozen=True, eq=False)
class FitSettings:
    """Every option of a fit, validated (one-line :class:`~gmwm.errors.InputError`).

    method : ``"gmwm"``, ``"armav"`` or ``"avsm"``.
    weights : ``"ci"`` (inverse squared width of the eta_3 WV interval; ``"ci-eta3"`` names it
        explicitly, ``"ci-mixture"`` uses the mixture-EDF interval), ``"gaussian"``
        (eta_j / (2 nu_j^2)),
        ``"identity"``, ``"efficient"`` (two-step: CI weights, then the inverse of the model
        covariance of the WV estimate at the first estimate), or a (J, J) covariance of
        ``nu_hat`` whose inverse is the weight and which also feeds the standard errors.
    n_starts : distinct starting points refined per model and submodel.
    seed : seed of the randomised start placements (results are deterministic given it).
    reweight : extra passes re-weighting with the fitted model's WV (Gaussian weights).
    nested : include the fits of the submodels (one component dropped, recursively), so that the
        result is never worse than any submodel's.
    se_cov : covariance V of the WV estimate behind the standard errors: ``"model"`` (under the
        fitted model, between-scale correlation included), ``"gaussian"`` (the diagonal
        ``2 nu_hat^2 / eta``) or a (J, J) matrix.
    max_nfev : evaluation budget per start.
    alpha : CI level of a WV computed from a signal.
    levels : number of dyadic levels J (None: all of a given WV, or floor(log2 T) - 1).
    robust, eff : compute the robust WV (Tukey biweight, Gaussian efficiency ``eff``) of a signal.
    min_edof, slope_tol : AVSM's level filter and slope window (:func:`gmwm.avsm.fit_avsm`).

    Options of one kind of estimator given with another (``weights`` with AVSM, ``min_edof``
    with GMWM) are errors, not silently ignored.
    """

    method: str = "gmwm"
    weights: str | np.ndarray = "ci"
    n_starts: int = N_STARTS
    seed: int = 0
    reweight: int = 0
    nested: bool = True
    se_cov: str | np.ndarray = "model"
    max_nfev: int = 1000
    alpha: float = 0.05
    levels: int | None = None
    robust: bool = False
    eff: float = 0.6
    min_edof: float = 2.0
    slope_tol: float = 0.1

    def __post_init__(self) -> None:
        set_ = lambda name, v: object.__setattr__(self, name, v)
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r}; use one of {', '.join(METHODS)}")
        set_("weights", _kind_or_matrix("weights", self.weights, WEIGHT_KINDS,
                                        "weight covariance"))
        set_("n_starts", _int("n_starts", self.n_starts, 1))
        set_("seed", _int("seed", self.seed, 0))
        set_("reweight", _int("reweight", self.reweight, 0))
        set_("nested", _bool("nested", self.nested))
        set_("se_cov", _kind_or_matrix("se_cov", self.se_cov, SE_COV_KINDS, "se_cov matrix"))
        set_("max_nfev", _int("max_nfev", self.max_nfev, 1))
        set_("alpha", _number("alpha", self.alpha, lambda a: 0 < a < 1, "in (0, 1)"))
        if self.levels is not None:
            set_("levels", _int("levels", self.levels, 1))
        set_("robust", _bool("robust", self.robust))
        set_("eff", _number("eff", self.eff, lambda e: 0.05 <= e <= 0.99, "in [0.05, 0.99]"))
        set_("min_edof", _number("min_edof", self.min_edof, lambda e: e > 0, "positive"))
        set_("slope_tol", _number("slope_tol", self.slope_tol, lambda e: e > 0, "positive"))
        foreign = _OPTIMISER_ONLY if self.method == "avsm" else _AVSM_ONLY
        default = {f.name: f.default for f in fields(self)}
        bad = [n for n in foreign if not _same(getattr(self, n), default[n])]
        if bad:
            raise InputError(f"option(s) {', '.join(bad)} do not apply to method "
                             f"{self.method!r}")

    # -- construction -----------------------------------------------------------------------------
    @classmethod
    def of(cls, settings: FitSettings | None = None, **options: Any) -> FitSettings:
        """``settings`` (default: the defaults) with ``options`` replaced, validated; unknown
        option names are an InputError."""
        base = _DEFAULTS if settings is None else settings
        if not isinstance(base, FitSettings):
            raise InputError(f"settings must be a FitSettings, got {type(base).__name__}")
        return base.replace(**options) if options else base

    def replace(self, **changes: Any) -> FitSettings:
        """A copy with ``changes`` (validated)."""
        unknown = sorted(set(changes) - set(_FIELDS))
        if unknown:
            raise InputError(f"unknown fit option(s) {', '.join(unknown)}; known: "
                             f"{', '.join(_FIELDS)}")
        method = changes.get("method", self.method)
        foreign = [n for n in (_OPTIMISER_ONLY if method == "avsm" else _AVSM_ONLY)
                   if n in changes]
        if foreign:  # given explicitly, even at its default value
            raise InputError(f"option(s) {', '.join(foreign)} do not apply to method {method!r}")
        return dataclasses.replace(self, **changes)

    # -- views --------------------------------------------------------------------------------------
    @property
    def weights_kind(self) -> str:
        """The weights' name, ``"covariance"`` for a matrix."""
        return self.weights if isinstance(self.weights, str) else "covariance"

    @property
    def se_cov_kind(self) -> str:
        return self.se_cov if isinstance(self.se_cov, str) else "covariance"

    @property
    def user_cov(self) -> np.ndarray | None:
        """The caller's covariance given as ``weights`` (None for named weights)."""
        return None if isinstance(self.weights, str) else self.weights

    def applicable(self) -> tuple[str, ...]:
        """Names of the options that apply to this method."""
        foreign = _OPTIMISER_ONLY if self.method == "avsm" else _AVSM_ONLY
        return tuple(n for n in _FIELDS if n not in foreign)

    def fit_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`gmwm.fit` that repeat a fit with these settings."""
        return {n: getattr(self, n) for n in self.applicable()}

    def to_json_dict(self) -> dict[str, Any]:
        """Readable JSON-able summary: the applicable options, matrices by kind
        (``"covariance"``)."""
        out = {n: getattr(self, n) for n in self.applicable()}
        if "weights" in out:
            out["weights"], out["se_cov"] = self.weights_kind, self.se_cov_kind
        return out

    def to_tree(self) -> dict[str, Any]:
        """Lossless dict (matrices as arrays): every option by name, read by :meth:`from_tree`."""
        return {n: getattr(self, n) for n in _FIELDS}

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> FitSettings:
        """Inverse of :meth:`to_tree`; also reads the settings dicts stored by earlier versions
        (``weights: "covariance"`` with the matrix in ``weights_cov``; other keys ignored)."""
        d = {k: v for k, v in tree.items() if k in _FIELDS}
        if _is(d.get("weights"), "covariance"):
            if "weights_cov" not in tree:
                raise InputError("stored settings name a weight covariance but do not hold it")
            d["weights"] = tree["weights_cov"]
        if _is(d.get("se_cov"), "covariance"):
            raise InputError("stored settings name an se_cov matrix but do not hold it (written "
                             "by an earlier version); refit")
        for name in ("weights", "se_cov"):
            if isinstance(d.get(name), list):
                d[name] = np.asarray(d[name], dtype=float)
        return cls(**d)

    # -- comparison ------------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FitSettings):
            return NotImplemented
        return all(_same(getattr(self, n), getattr(other, n)) for n in _FIELDS)

    def __hash__(self) -> int:
        return hash(tuple(v.tobytes() if isinstance(v, np.ndarray) else v
                          for v in (getattr(self, n) for n in _FIELDS)))

    def __repr__(self) -> str:
        parts = [f"{n}={getattr(self, n)!r}" if not isinstance(getattr(self, n), np.ndarray)
                 else f"{n}=<{getattr(self, n).shape[0]}x{getattr(self, n).shape[1]} matrix>"
                 for n in self.applicable()]
        return f"FitSettings({', '.join(parts)})"


def _is(v: Any, name: str) -> bool:
    return isinstance(v, str) and v == name


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
                and np.array_equal(a, b))
    return a == b


_FIELDS = tuple(f.name for f in fields(FitSettings))
_DEFAULTS = FitSettings()


# -- the data a fit starts from -------------------------------------------------------------------
class PreparedWV(NamedTuple):
    """The WV a fit uses; ``drift_sign`` the sign of the signal's mean slope (None when only a
    WV was given: the WV does not see the sign of a drift); ``seconds`` spent computing the WV."""

    wv: Any
    drift_sign: float | None
    seconds: float


def prepare_wv(data: Any, settings: FitSettings | None = None, *, freq: float | None = None,
               ci: str = "mixture", **options: Any) -> PreparedWV:
    """The wavelet variance of ``data`` (a 1-D signal, per-sample units, or a
    :class:`~gmwm.wv.WaveletVariance`) under ``settings`` (or the options ``levels``, ``alpha``,
    ``robust``, ``eff``) and the drift sign of a signal. A WV is cut to ``levels`` and given
    ``freq`` [Hz] if that differs; a signal's WV is computed at ``freq`` (default 1 Hz) with the
    interval kind ``ci`` (:func:`gmwm.wv.wvar`; a given WV keeps its own)."""
    from .wv import WaveletVariance, wvar

    s = FitSettings.of(settings, **options)
    if isinstance(data, WaveletVariance):
        if s.robust:
            raise InputError("robust=True needs the signal, not a precomputed wavelet variance")
        wv = data if s.levels is None else data.subset(np.arange(1, s.levels + 1))
        if freq is not None and freq != wv.freq:
            wv = dataclasses.replace(wv, freq=float(freq))
        return PreparedWV(wv, None, 0.0)
    t0 = time.perf_counter()
    wv = wvar(data, levels=s.levels, alpha=s.alpha, freq=1.0 if freq is None else freq,
              robust=s.robust, eff=s.eff, ci=ci)
    seconds = time.perf_counter() - t0
    x = np.asarray(data, dtype=float)
    drift = (x[-1] - x[0]) / max(x.size - 1, 1)
    return PreparedWV(wv, 1.0 if drift >= 0 else -1.0, seconds)
