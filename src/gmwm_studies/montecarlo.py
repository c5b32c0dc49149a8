"""Monte Carlo studies: chunked simulation of wavelet variances, GMWM fits, summaries, reports.

The Snakemake workflow calls these functions; all statistics live here. A study is
(model, truth, sample sizes, replicates); replicate ``r`` at sample size ``T`` always uses the
random stream :func:`seeds.replicate_rng` ``(study, T, r, base_seed)``, so results do not
depend on chunking, parallelism or job order.

Conventions: ``truth`` maps canonical parameter names (``'AR1[1].phi'``...) to per-sample values;
estimates are xarray Datasets with dims ``(replicate, parameter)``; the empirical SD uses ddof=1.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from gmwm.atomic import write_text_atomic
from gmwm.errors import GMWMError, InputError, ModelError
from gmwm.settings import FitSettings
from gmwm_studies.seeds import replicate_rng, replicate_seed
from gmwm_studies.store import WVChunk

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

    from gmwm.estimator import GMWMResult

__all__ = [
    "check_truth",
    "chunk_bounds",
    "chunk_replicates",
    "estimator_settings",
    "fit_chunk",
    "format_markdown_table",
    "gather",
    "replicate_fit",
    "replicate_flags",
    "simulate_replicate",
    "simulate_wv_chunk",
    "standardized_errors",
    "summarize",
    "write_table",
]

Progress = Callable[[str], None]


def _noop(_: str) -> None:
    return None


# ---------------------------------------------------------------------------------------------
# chunking
# ---------------------------------------------------------------------------------------------


def chunk_bounds(n_replicates: int, chunk_size: int) -> list[tuple[int, int]]:
    """Half-open replicate ranges ``[start, stop)`` of the chunks, in order; the last may be short."""
    if n_replicates < 1 or chunk_size < 1:
        raise InputError(
            f"replicates ({n_replicates}) and chunk_size ({chunk_size}) must be positive integers"
        )
    return [(s, min(s + chunk_size, n_replicates)) for s in range(0, n_replicates, chunk_size)]


def chunk_replicates(chunk: int, n_replicates: int, chunk_size: int) -> list[int]:
    """Replicate indices of chunk number ``chunk`` (0-based)."""
    bounds = chunk_bounds(n_replicates, chunk_size)
    if not 0 <= chunk < len(bounds):
        raise InputError(f"chunk {chunk} out of range: there are {len(bounds)} chunks")
    start, stop = bounds[chunk]
    return list(range(start, stop))


# ---------------------------------------------------------------------------------------------
# simulation and fits
# ---------------------------------------------------------------------------------------------


def check_truth(model_spec: str, truth: Mapping[str, float]) -> np.ndarray:
    """Validate ``truth`` against the model: every parameter named exactly once, in the domain, and in
    canonical order (AR1 by increasing phi, SIN by decreasing beta...), so that estimates, which are
    reported canonical-ordered, are compared with the right true value. Returns theta."""
    from gmwm.model import Model

    model = Model(model_spec)
    unknown = sorted(set(truth) - set(model.param_names))
    if unknown:
        raise ModelError(
            f"truth of model {model_spec!r} has unknown parameter(s) {unknown}; "
            f"expected {model.param_names}"
        )
    canon = model.theta(dict(truth))  # validated, canonical (relabelled if needed)
    theta = np.array([float(truth[n]) for n in model.param_names])
    if not np.array_equal(canon, theta):
        swapped = [n for n, a, b in zip(model.param_names, theta, canon, strict=True) if a != b]
        raise ModelError(
            f"truth of model {model_spec!r} is not in canonical component order (see docs/API.md): "
            f"renumber {swapped}"
        )
    return theta


SIMULATORS = ("fused", "fast", "reference")


def simulate_replicate(model: Any, theta: np.ndarray, n_samples: int, rng: np.random.Generator,
                       simulator: str = "fast") -> np.ndarray:
    """One replicate signal: ``"fused"`` = the signal of the fused simulation + WV pass
    (:func:`gmwm.fused.simulate_signal`: the distribution of ``"fast"``, its own generator,
    ~1.7x cheaper with the WV, which :func:`simulate_wv_chunk` then computes without the signal),
    ``"fast"`` = :meth:`gmwm.model.Model.simulate_fast` (the same distribution as ``"reference"``
    up to an additive constant, which the WV ignores; NumPy's normals), ``"reference"`` =
    :meth:`gmwm.model.Model.simulate` (the component-by-component stream of the earlier runs).
    The three give different random numbers for the same ``rng``."""
    if simulator == "fused":
        from gmwm.fused import simulate_signal

        return simulate_signal(model, theta, int(n_samples), rng)
    if simulator == "fast":
        return model.simulate_fast(theta, int(n_samples), rng)
    if simulator == "reference":
        return model.simulate(theta, int(n_samples), rng)
    raise InputError(f"unknown simulator {simulator!r}; choose one of {list(SIMULATORS)}")


def simulate_wv_chunk(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicates: Sequence[int],
    study: str,
    base_seed: int,
    levels: int | None = None,
    progress: Progress | None = None,
    simulator: str = "fast",
) -> WVChunk:
    """Simulate each replicate's signal and keep only its wavelet variance.

    One signal is in memory at a time (8 bytes x ``n_samples``; none with ``"fused"``, whose WV
    comes from the same pass). ``levels`` = number of WV levels J (None: the library default
    floor(log2 T) - 1). ``simulator``: see :func:`simulate_replicate`. Returns a
    :class:`WVChunk` with per-replicate timings of the simulation and of the WV [s] (``"fused"``:
    the whole pass in ``seconds_simulate``, ``seconds_wv`` = 0).
    """
    from gmwm.model import Model
    from gmwm.wv import wvar

    progress = progress or _noop
    model = Model(model_spec)
    theta = check_truth(model_spec, truth)
    reps = [int(r) for r in replicates]
    if not reps:
        raise InputError("a chunk needs at least one replicate")
    if simulator not in SIMULATORS:
        raise InputError(f"unknown simulator {simulator!r}; choose one of {list(SIMULATORS)}")
    J = int(n_samples).bit_length() - 2 if levels is None else int(levels)
    rows: list[np.ndarray] = []
    t_sim = np.empty(len(reps))
    t_wv = np.empty(len(reps))
    for i, rep in enumerate(reps):
        t0 = time.perf_counter()
        rng = replicate_rng(study, n_samples, rep, base_seed)
        if simulator == "fused":  # one pass, no signal: its time is all in seconds_simulate
            from gmwm.fused import simulate_wv

            rows.append(simulate_wv(model, theta, n_samples, rng, J))
            t1 = t2 = time.perf_counter()
        else:
            x = simulate_replicate(model, theta, n_samples, rng, simulator)
            t1 = time.perf_counter()
            wv = wvar(x, levels=J, ci=STUDY_WV_CI)  # only the variances are kept
            t2 = time.perf_counter()
            del x
            rows.append(np.asarray(wv.variance, dtype=np.float64))
        t_sim[i], t_wv[i] = t1 - t0, t2 - t1
        progress(
            f"{study} T={n_samples}: replicate {i + 1}/{len(reps)} (id {rep}) "
            f"simulate {t_sim[i]:.2f} s, WV {t_wv[i]:.2f} s"
        )
    lev = np.arange(1, J + 1)
    return WVChunk(
        study=study,
        model=model_spec,
        truth={k: float(v) for k, v in truth.items()},
        n_samples=int(n_samples),
        base_seed=int(base_seed),
        replicates=np.asarray(reps, dtype=np.int64),
        levels=lev.astype(np.int64),
        scales=(2.0 ** lev).astype(np.float64),
        n=(int(n_samples) - (1 << lev) + 1).astype(np.int64),
        variances=np.vstack(rows),
        seconds_simulate=t_sim,
        seconds_wv=t_wv,
    )


def estimator_settings(settings: FitSettings | Mapping[str, Any] | None) -> FitSettings:
    """The :class:`gmwm.settings.FitSettings` of an estimator named in a study's config (a
    mapping of :func:`gmwm.fit` options, validated there; None: the defaults)."""
    if isinstance(settings, FitSettings):
        return settings
    return FitSettings.of(**dict(settings or {}))


#: interval the cached WVs are rebuilt with before a fit. No study output reads a fit's WV
#: interval, and the estimators recompute the interval their weights need ("ci-mixture" weights
#: compute the mixture bounds from the WV), so estimates, SEs and objectives are the same with
#: either kind (tests/test_study_cost.py); the eta_3 bounds cost ~0.07 ms a WV against ~2 ms for
#: the mixture interval (the library default), once per replicate and estimator.
STUDY_WV_CI = "eta3"

#: whether the studies' fits run the goodness-of-fit test: no study table reads its p-value, and
#: on a weak sinusoid (Simulation 2's slow one) the test refits at the competing frequencies,
#: several times a fit's cost. Estimates, SEs, objectives and convergence do not depend on it.
STUDY_GOF = False


def replicate_fit(model_spec: str, truth: Mapping[str, float], n_samples: int, replicate: int, *,
                  study: str, base_seed: int,
                  settings: FitSettings | Mapping[str, Any] | None = None,
                  levels: int | None = None, freq: float = 1.0,
                  simulator: str = "fast") -> GMWMResult:
    """GMWM fit of replicate ``replicate`` of a study, equal to :func:`fit_chunk`'s fit of it.

    The signal uses the replicate's stream (:func:`seeds.replicate_rng`), the WV is
    rebuilt from its variances (CIs from the eta_3 rule, as a cached chunk is) and the fit's starts
    use stream 1. ``freq`` [Hz] is the sampling frequency.
    """
    from gmwm.estimator import fit
    from gmwm.model import Model
    from gmwm.wv import WaveletVariance, wvar

    model = Model(model_spec, freq=freq)
    theta = model.theta(dict(truth))
    x = simulate_replicate(model, theta, n_samples,
                           replicate_rng(study, n_samples, replicate, base_seed), simulator)
    wv = wvar(x, levels=levels, freq=freq, ci=STUDY_WV_CI)
    del x
    wv = WaveletVariance.from_table(wv.scales, wv.variance, n_samples=int(n_samples), freq=freq,
                                    ci=STUDY_WV_CI)
    seed = replicate_seed(study, n_samples, replicate, base_seed, stream=1)
    return fit(wv, model, settings=estimator_settings(settings), seed=seed, gof=STUDY_GOF)


FitOne = Callable[[Any, Any, int], tuple[np.ndarray, np.ndarray, bool, float, str]]
"""Fit of one replicate: (wv, model, seed) -> (params, se, converged, objective, message)."""


def fit_chunk(
    chunk: WVChunk,
    fit_settings: Mapping[str, Any],
    estimator: str = "gmwm",
    progress: Progress | None = None,
    *,
    fit_one: FitOne | None = None,
    freq: float = 1.0,
) -> xr.Dataset:
    """Fit the study model to every replicate's WV of ``chunk``; one row per replicate, none dropped.

    ``fit_one`` fits one replicate (default: :func:`gmwm.fit` with ``fit_settings``); other
    estimators (ARMAV, AVSM in :mod:`gmwm_studies.stim300`) plug in here. ``freq`` [Hz] is the
    sampling frequency of the WV. A replicate whose fit fails with a library error or does not
    converge keeps its row, with ``converged = False`` and the failure in ``message`` (estimates
    NaN if the fit raised). The random starts of the fit use stream 1 of the replicate's seed.
    """
    import xarray as xr  # lazily: a simulate_wv job never needs it (start-up)

    from gmwm.model import Model
    from gmwm.wv import WaveletVariance

    progress = progress or _noop
    if fit_one is None:
        fit_one = _gmwm_fit_one(estimator_settings(fit_settings))
    model = Model(chunk.model, freq=freq)
    theta0 = check_truth(chunk.model, chunk.truth)
    names = list(model.param_names)
    r, p = len(chunk.replicates), len(names)
    est = np.full((r, p), np.nan)
    se = np.full((r, p), np.nan)
    converged = np.zeros(r, dtype=bool)
    objective = np.full(r, np.nan)
    seconds_fit = np.full(r, np.nan)
    messages: list[str] = []
    every = max(1, r // 50)  # at most ~50 progress lines per chunk
    for i, rep in enumerate(chunk.replicates):
        wv = WaveletVariance.from_table(
            chunk.scales, chunk.variances[i], n_samples=chunk.n_samples, freq=freq, ci=STUDY_WV_CI
        )
        seed = replicate_seed(chunk.study, chunk.n_samples, int(rep), chunk.base_seed, stream=1)
        t0 = time.perf_counter()
        try:
            params, ses, converged[i], objective[i], msg = fit_one(wv, model, seed)
            est[i], se[i] = _canonical_with_se(model, np.asarray(params), np.asarray(ses))
        except (GMWMError, np.linalg.LinAlgError, FloatingPointError) as exc:
            msg = f"{type(exc).__name__}: {exc}"
        seconds_fit[i] = time.perf_counter() - t0
        messages.append(msg)
        if (i + 1) % every == 0 or i + 1 == r:
            progress(
                f"{chunk.study} T={chunk.n_samples} {estimator}: replicate {i + 1}/{r} (id {rep}) "
                f"fit {seconds_fit[i]:.2f} s, converged={converged[i]}; "
                f"{int(converged[: i + 1].sum())} converged so far"
            )

    def timing(name: str) -> np.ndarray:
        value = getattr(chunk, name)
        return np.full(r, np.nan) if value is None else np.asarray(value, dtype=np.float64)

    return xr.Dataset(
        {
            "estimate": (("replicate", "parameter"), est),
            "se": (("replicate", "parameter"), se),
            "converged": ("replicate", converged),
            "objective": ("replicate", objective),
            "message": ("replicate", np.asarray(messages, dtype=object)),
            "seconds_simulate": ("replicate", timing("seconds_simulate")),
            "seconds_wv": ("replicate", timing("seconds_wv")),
            "seconds_fit": ("replicate", seconds_fit),
        },
        coords={
            "replicate": np.asarray(chunk.replicates, dtype=np.int64),
            "parameter": np.asarray(names, dtype=object),
            "truth": ("parameter", theta0),
        },
        attrs={
            "study": chunk.study,
            "model": chunk.model,
            "n_samples": int(chunk.n_samples),
            "n_levels": len(chunk.scales),
            "base_seed": int(chunk.base_seed),
            "estimator": estimator,
            "fit_settings": json.dumps(dict(fit_settings), sort_keys=True),
        },
    )


def _gmwm_fit_one(settings: FitSettings) -> FitOne:
    from gmwm.estimator import fit

    def fit_one(wv: Any, model: Any, seed: int):
        # no study output reads the goodness-of-fit test (STUDY_GOF)
        res = fit(wv, model, settings=settings, seed=seed, gof=STUDY_GOF)
        return res.params, res.se, bool(res.converged), float(res.objective), str(res.message)

    return fit_one


def _canonical_with_se(model: Any, theta: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical order of an estimate, with its SEs permuted the same way.

    ``Model.canonical`` sorts whole components; the permutation is recovered by matching values
    (exact copies), which carries each SE along with its parameter.
    """
    canon = model.canonical(theta)
    if np.array_equal(canon, theta):
        return theta, se
    order = np.empty(len(theta), dtype=int)
    used: set[int] = set()
    for k, v in enumerate(canon):
        idx = next(i for i in range(len(theta)) if i not in used and theta[i] == v)
        used.add(idx)
        order[k] = idx
    return canon, se[order]


def gather(datasets: Iterable[xr.Dataset]) -> xr.Dataset:
    """Concatenate chunk Datasets along ``replicate``, sorted by replicate id; duplicates rejected."""
    import xarray as xr  # lazily: a simulate_wv job never needs it (start-up)

    parts = list(datasets)
    if not parts:
        raise InputError("nothing to gather: no chunk estimates given")
    keys = ("study", "model", "n_samples", "estimator")
    for part in parts[1:]:
        for key in keys:
            if part.attrs.get(key) != parts[0].attrs.get(key):
                raise InputError(
                    f"chunks disagree on {key}: {part.attrs.get(key)!r} vs {parts[0].attrs.get(key)!r}"
                )
    ds = xr.concat(parts, dim="replicate", combine_attrs="override").sortby("replicate")
    ids = ds["replicate"].values
    if len(np.unique(ids)) != len(ids):
        raise InputError("duplicate replicate ids across chunks")
    return ds


# ---------------------------------------------------------------------------------------------
# summaries
# ---------------------------------------------------------------------------------------------


def _converged_estimates(ds: xr.Dataset) -> xr.DataArray:
    """Estimates of the converged replicates only (non-converged ones are counted, not used)."""
    return ds["estimate"].where(ds["converged"]).dropna("replicate", how="all")


def standardized_errors(ds: xr.Dataset, *, with_flags: bool = False
                        ) -> dict[str, np.ndarray] | dict[str, dict[str, np.ndarray]]:
    """(estimate - truth) / empirical SD per parameter, converged replicates only (paper Fig. 4).

    ``with_flags``: per parameter ``{"z": ..., "boundary": bool mask, "switched": bool mask}``
    (same length as ``z``; see :func:`replicate_flags`) so a figure can mark those replicates.
    """
    est = _converged_estimates(ds)
    flags = replicate_flags(ds).sel(replicate=est["replicate"]) if with_flags else None
    out: dict[str, Any] = {}
    for name in ds["parameter"].values:
        x = est.sel(parameter=name).values
        keep = np.isfinite(x)
        x = x[keep]
        sd = np.std(x, ddof=1) if len(x) > 1 else np.nan
        truth = float(ds["truth"].sel(parameter=name))
        z = (x - truth) / sd if sd > 0 else np.full(len(x), np.nan)
        if flags is None:
            out[str(name)] = z
        else:
            out[str(name)] = {
                "z": z,
                "boundary": flags["boundary"].sel(parameter=name).values[keep],
                "switched": flags["switched"].sel(parameter=name).values[keep],
            }
    return out


BOUNDARY_REL = 1e-8
"""A scale parameter (variance, amplitude, drift) below this fraction of its true value is at the
boundary 0 (the estimator sets a vanished component to exactly 0)."""
PHI_EDGE = 1e-8
"""An AR1 ``|phi|`` within this distance of 1 is at the domain edge."""


def _shape_distance(kind: str, name: str, est: np.ndarray, truth: float) -> np.ndarray:
    """Squared distance of estimates from the truth on the parameter's natural scale: atanh for the
    AR1 phi, log for every positive parameter (0 estimates are clipped far from any truth)."""
    if kind == "AR1" and name == "phi":
        lim = 1.0 - 1e-15
        return (np.arctanh(np.clip(est, -lim, lim)) - np.arctanh(np.clip(truth, -lim, lim))) ** 2
    tiny = abs(truth) * 1e-12 + 1e-300
    return (np.log(np.maximum(np.abs(est), tiny)) - np.log(abs(truth))) ** 2


def replicate_flags(ds: xr.Dataset) -> xr.Dataset:
    """Which replicates are at a boundary and which are label-switched (study estimates ``ds``).

    * ``boundary`` (replicate, parameter): a scale parameter below ``BOUNDARY_REL`` x truth (the
      component vanished or was absorbed), an AR1 ``|phi|`` within ``PHI_EDGE`` of 1, or a SIN
      beta at pi.
    * ``switched`` (replicate, parameter; set on every parameter of the type): for a process type with several components (2*AR1, 2*SIN), some
      true component is estimated in another component's column: the estimated component nearest
      to it (sum of squared log/atanh distances over the component's parameters) has another label
      and is at least twice as close as its own. This happens when the canonical labels (AR1 by
      phi, SIN by decreasing beta) shift because one component was absorbed and a spurious one
      took its place, or when two components trade places.

    Non-converged replicates are never flagged (they are counted separately).
    """
    import xarray as xr  # lazily: a simulate_wv job never needs it (start-up)

    from gmwm.model import Model

    model = Model(ds.attrs["model"])
    est = ds["estimate"]
    conv = ds["converged"].values.astype(bool)
    names = [str(n) for n in ds["parameter"].values]
    boundary = np.zeros((ds.sizes["replicate"], len(names)), dtype=bool)
    by_type: dict[str, list[Any]] = {}
    for c in model.components:
        by_type.setdefault(c.process.name, []).append(c)
        for k, pname in enumerate(c.param_names):
            if pname not in names:
                continue
            j = names.index(pname)
            x = est.sel(parameter=pname).values
            truth = float(ds["truth"].sel(parameter=pname))
            if k == c.process.scale_index:
                boundary[:, j] = np.abs(x) <= BOUNDARY_REL * abs(truth)
            elif c.process.name == "AR1" and c.process.param_names[k] == "phi":
                boundary[:, j] = np.abs(x) >= 1.0 - PHI_EDGE
            elif c.process.name == "SIN" and c.process.param_names[k] == "beta":
                boundary[:, j] = x >= np.pi * (1.0 - 1e-9)
    switched = np.zeros_like(boundary)
    for kind, comps in by_type.items():
        if len(comps) < 2 or any(p not in names for c in comps for p in c.param_names):
            continue
        # dist[a, b]: distance of component a's estimate from component b's truth, per replicate
        dist = np.zeros((len(comps), len(comps), ds.sizes["replicate"]))
        for a, ca in enumerate(comps):
            for b, cb in enumerate(comps):
                for pa, pb, short in zip(ca.param_names, cb.param_names, ca.process.param_names):
                    x = est.sel(parameter=pa).values
                    t = float(ds["truth"].sel(parameter=pb))
                    dist[a, b] += _shape_distance(kind, short, x, t)
        hit = np.zeros(ds.sizes["replicate"], dtype=bool)
        for b in range(len(comps)):
            nearest = np.argmin(dist[:, b], axis=0)
            hit |= (nearest != b) & (np.min(dist[:, b], axis=0) < 0.5 * dist[b, b])
        cols = [names.index(p) for c in comps for p in c.param_names]
        switched[:, cols] |= hit[:, None]
    boundary &= conv[:, None]
    switched &= conv[:, None]
    return xr.Dataset(
        {"boundary": (("replicate", "parameter"), boundary),
         "switched": (("replicate", "parameter"), switched)},
        coords={"replicate": ds["replicate"].values, "parameter": names},
    )


def summarize(ds: xr.Dataset) -> pd.DataFrame:
    """Per parameter: truth, mean, bias, SD, RMSE, relative bias/SD, standardized bias, MC SE of the
    bias (SD / sqrt(n)), the share of replicates whose fit did not converge, and how many converged
    replicates have the parameter at a boundary (``n_boundary``) or are label-switched
    (``n_switched``, per replicate; :func:`replicate_flags`).

    Statistics use the converged replicates; ``n_used`` says how many.
    """
    import pandas as pd  # lazily: a simulate_wv job never needs it (start-up)

    est = _converged_estimates(ds)
    n_total = int(ds.sizes["replicate"])
    n_conv = int(ds["converged"].sum())
    try:
        flags = replicate_flags(ds)
    except (KeyError, ModelError):  # estimates without a parseable model: no flags
        flags = None
    rows = []
    for name in ds["parameter"].values:
        x = est.sel(parameter=name).values
        x = x[np.isfinite(x)]
        truth = float(ds["truth"].sel(parameter=name))
        n = len(x)
        mean = float(np.mean(x)) if n else np.nan
        sd = float(np.std(x, ddof=1)) if n > 1 else np.nan
        bias = mean - truth
        rmse = float(np.sqrt(np.mean((x - truth) ** 2))) if n else np.nan
        rows.append(
            {
                "study": ds.attrs.get("study", ""),
                "estimator": ds.attrs.get("estimator", ""),
                "n_samples": int(ds.attrs.get("n_samples", 0)),
                "parameter": str(name),
                "truth": truth,
                "mean": mean,
                "bias": bias,
                "sd": sd,
                "rmse": rmse,
                "rel_bias": bias / truth if truth != 0 else np.nan,
                "rel_sd": sd / abs(truth) if truth != 0 else np.nan,
                "std_bias": bias / sd if sd and sd > 0 else np.nan,
                "mc_se_bias": sd / math.sqrt(n) if n > 1 else np.nan,
                "n_used": n,
                "n_replicates": n_total,
                "share_not_converged": 1.0 - n_conv / n_total if n_total else np.nan,
                "n_boundary": (int(flags["boundary"].sel(parameter=name).sum())
                               if flags is not None else 0),
                "n_switched": (int(flags["switched"].sel(parameter=name).sum())
                               if flags is not None else 0),
            }
        )
    return pd.DataFrame(rows)


def format_markdown_table(df: pd.DataFrame, digits: int = 4) -> str:
    """GitHub Markdown table; floats in ``digits`` significant digits."""

    def fmt(v: Any) -> str:
        if isinstance(v, float | np.floating):
            return "nan" if not np.isfinite(v) else f"{v:.{digits}g}"
        return str(v)

    header = "| " + " | ".join(map(str, df.columns)) + " |"
    rule = "|" + "|".join("---" for _ in df.columns) + "|"
    body = ["| " + " | ".join(fmt(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([header, rule, *body]) + "\n"


def write_table(df: pd.DataFrame, csv_path: str | os.PathLike, md_path: str | os.PathLike,
                title: str | None = None) -> None:
    """Write a summary table as CSV (full precision) and Markdown (4 significant digits), atomically."""
    write_text_atomic(csv_path, df.to_csv(index=False, float_format="%.10g"))
    md = (f"# {title}\n\n" if title else "") + format_markdown_table(df)
    write_text_atomic(md_path, md)
