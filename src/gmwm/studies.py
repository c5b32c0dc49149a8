"""Monte Carlo studies: chunked simulation of wavelet variances, GMWM fits, summaries, reports.

The Snakemake workflow calls these functions; all statistics live here. A study is
(model, truth, sample sizes, replicates); replicate ``r`` at sample size ``T`` always uses the
random stream :func:`gmwm.seeds.replicate_rng` ``(study, T, r, base_seed)``, so results do not
depend on chunking, parallelism or job order.

Conventions: ``truth`` maps canonical parameter names (``'AR1[1].phi'``...) to per-sample values;
estimates are xarray Datasets with dims ``(replicate, parameter)``; the empirical SD uses ddof=1.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import GMWMError, InputError, ModelError
from gmwm.io import write_json_atomic, write_text_atomic
from gmwm.seeds import replicate_rng, replicate_seed
from gmwm.store import WVChunk

__all__ = [
    "check_truth",
    "chunk_bounds",
    "chunk_replicates",
    "config_hash",
    "fit_chunk",
    "format_markdown_table",
    "gather",
    "make_archive",
    "read_benchmarks",
    "render_index",
    "replicate_flags",
    "run_summary",
    "simulate_wv_chunk",
    "standardized_errors",
    "summarize",
    "write_table",
]

Progress = Callable[[str], None]
FIT_KEYS = ("weights", "n_starts", "reweight", "method")


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


def simulate_wv_chunk(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicates: Sequence[int],
    study: str,
    base_seed: int,
    levels: int | None = None,
    progress: Progress | None = None,
) -> WVChunk:
    """Simulate each replicate's signal and keep only its wavelet variance.

    One signal is in memory at a time (8 bytes x ``n_samples``). ``levels`` = number of WV levels J
    (None: the library default floor(log2 T) - 1). Returns a :class:`WVChunk` with per-replicate
    timings of the simulation and of the WV [s].
    """
    from gmwm.model import Model
    from gmwm.wv import wvar

    progress = progress or _noop
    model = Model(model_spec)
    theta = check_truth(model_spec, truth)
    reps = [int(r) for r in replicates]
    if not reps:
        raise InputError("a chunk needs at least one replicate")
    rows: list[np.ndarray] = []
    t_sim = np.empty(len(reps))
    t_wv = np.empty(len(reps))
    wv = None
    for i, rep in enumerate(reps):
        t0 = time.perf_counter()
        x = model.simulate(theta, int(n_samples), replicate_rng(study, n_samples, rep, base_seed))
        t1 = time.perf_counter()
        wv = wvar(x, levels=levels)
        t2 = time.perf_counter()
        del x
        rows.append(np.asarray(wv.variance, dtype=np.float64))
        t_sim[i], t_wv[i] = t1 - t0, t2 - t1
        progress(
            f"{study} T={n_samples}: replicate {i + 1}/{len(reps)} (id {rep}) "
            f"simulate {t_sim[i]:.2f} s, WV {t_wv[i]:.2f} s"
        )
    assert wv is not None
    return WVChunk(
        study=study,
        model=model_spec,
        truth={k: float(v) for k, v in truth.items()},
        n_samples=int(n_samples),
        base_seed=int(base_seed),
        replicates=np.asarray(reps, dtype=np.int64),
        levels=np.asarray(wv.levels, dtype=np.int64),
        scales=np.asarray(wv.scales, dtype=np.float64),
        n=np.asarray(wv.n, dtype=np.int64),
        variances=np.vstack(rows),
        seconds_simulate=t_sim,
        seconds_wv=t_wv,
    )


def fit_settings_kwargs(fit_settings: Mapping[str, Any]) -> dict[str, Any]:
    """Keyword arguments of ``gmwm.fit`` from a study's fit settings (unknown keys rejected)."""
    unknown = sorted(set(fit_settings) - set(FIT_KEYS))
    if unknown:
        raise InputError(f"unknown fit setting(s) {unknown}; allowed: {list(FIT_KEYS)}")
    return dict(fit_settings)


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
    estimators (ARMAV, AVSM in :mod:`gmwm.allan_comparison`) plug in here. ``freq`` [Hz] is the
    sampling frequency of the WV. A replicate whose fit fails with a library error or does not
    converge keeps its row, with ``converged = False`` and the failure in ``message`` (estimates
    NaN if the fit raised). The random starts of the fit use stream 1 of the replicate's seed.
    """
    from gmwm.model import Model
    from gmwm.wv import WaveletVariance

    progress = progress or _noop
    if fit_one is None:
        fit_one = _gmwm_fit_one(fit_settings_kwargs(fit_settings))
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
            chunk.scales, chunk.variances[i], n_samples=chunk.n_samples, freq=freq
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


def _gmwm_fit_one(kwargs: Mapping[str, Any]) -> FitOne:
    from gmwm.estimator import fit

    def fit_one(wv: Any, model: Any, seed: int):
        res = fit(wv, model, seed=seed, **kwargs)
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


# ---------------------------------------------------------------------------------------------
# run bookkeeping: config hash, timings, index page, archive
# ---------------------------------------------------------------------------------------------


def config_hash(config: Mapping[str, Any], length: int = 10) -> str:
    """Short SHA-256 of the config (keys sorted), naming the archive of a run with this config."""
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:length]


def read_benchmarks(paths: Iterable[str | os.PathLike]) -> pd.DataFrame:
    """Collect Snakemake ``benchmark:`` files laid out as ``.../<rule>/<study>/<job>.tsv``.

    Missing files are skipped (their job ran in an earlier session whose benchmark was removed).
    Returns one row per job: rule, study, job, seconds (wall), max_rss_mb, cpu_time [s].
    """
    rows = []
    for path in map(Path, paths):
        if not path.exists():
            continue
        table = pd.read_csv(path, sep="\t")
        if table.empty:
            continue
        last = table.iloc[-1]
        rows.append(
            {
                "rule": path.parent.parent.name,
                "study": path.parent.name,
                "job": path.stem,
                "seconds": _num(last.get("s", np.nan)),
                "max_rss_mb": _num(last.get("max_rss", np.nan)),
                "cpu_time": _num(last.get("cpu_time", np.nan)),
            }
        )
    return pd.DataFrame(rows, columns=["rule", "study", "job", "seconds", "max_rss_mb", "cpu_time"])


def _num(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def run_summary(bench: pd.DataFrame) -> pd.DataFrame:
    """Jobs and summed wall time [s] per study and rule (from :func:`read_benchmarks`)."""
    if bench.empty:
        return pd.DataFrame(columns=["study", "rule", "jobs", "seconds"])
    return (
        bench.groupby(["study", "rule"], sort=True)
        .agg(jobs=("job", "count"), seconds=("seconds", "sum"))
        .reset_index()
    )


def render_index(studies: Sequence[Mapping[str, Any]], summary: pd.DataFrame,
                 config_id: str) -> str:
    """Markdown index page: per study its description, figures, key numbers and run time.

    Each entry of ``studies``: name, model, description, n_samples (list), replicates, figures
    (relative paths), table (relative path of the Markdown table), key (DataFrame of key numbers).
    """
    lines = [
        "# GMWM reproduction: studies at a glance",
        "",
        ("Verdict for every figure and table of the papers (agrees / differs / not reproducible): "
         "[REPRODUCTION.md](REPRODUCTION.md)."),
        "",
        f"Config hash `{config_id}`; generated {datetime.now(UTC):%Y-%m-%d %H:%M} UTC.",
        "",
    ]
    for s in studies:
        lines += [f"## {s['name']}: `{s['model']}`", ""]
        if s.get("description"):
            lines += [str(s["description"]), ""]
        sizes = ", ".join(str(t) for t in s["n_samples"])
        lines += [
            (f"Sample sizes {sizes}; {s['replicates']} replicates each. "
             f"Full table: [{s['table']}]({s['table']})."),
            "",
        ]
        for fig in s.get("figures", []):
            lines += [f"![{Path(fig).stem}]({fig})", ""]
        key = s.get("key")
        if key is not None and len(key):
            lines += [format_markdown_table(key, digits=3), ""]
        own = summary[summary["study"] == s["name"]] if len(summary) else summary
        if len(own):
            total = own["seconds"].sum()
            per_rule = ", ".join(
                f"{r.rule} {r.jobs} jobs {r.seconds:.1f} s" for r in own.itertuples(index=False)
            )
            lines += [f"Run time (summed job wall time): {total:.1f} s ({per_rule}).", ""]
    return "\n".join(lines) + "\n"


def package_versions(names: Sequence[str] = ("gmwm", "numpy", "scipy", "numba", "xarray",
                                              "h5py", "netCDF4", "pandas", "matplotlib",
                                              "snakemake", "snakemake-executor-plugin-slurm")
                     ) -> dict[str, str]:
    """Installed versions of the packages a run depends on ("not installed" if absent)."""
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def git_commit(repo: str | os.PathLike = ".") -> str:
    """``git describe``-style commit of ``repo`` (with ``-dirty``), or "unknown" outside git."""
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--abbrev=40"],
            cwd=repo, capture_output=True, text=True, check=True, timeout=20,
        )
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def make_archive(
    archive_root: str | os.PathLike,
    config: Mapping[str, Any],
    files: Iterable[str | os.PathLike],
    bench: pd.DataFrame,
    repo: str | os.PathLike = ".",
    base: str | os.PathLike = ".",
) -> Path:
    """Copy a run's reports into a new ``<archive_root>/<UTC timestamp>-<config hash>/``.

    Never overwrites: if the directory exists a numeric suffix is added. The archive holds the
    files (paths kept relative to ``base``), ``config.json``, ``versions.json``, ``git.txt`` and
    ``timings.csv`` (one row per job). It is assembled under a hidden temporary name and renamed
    into place, so a partial archive never looks complete.
    """
    root = Path(archive_root)
    root.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    name = f"{stamp}-{config_hash(config)}"
    tmp = root / f".{name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        base = Path(base)
        for f in files:
            src = Path(f)
            rel = src.resolve().relative_to(base.resolve()) if src.is_absolute() else src
            dst = tmp / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
        write_json_atomic(tmp / "config.json", dict(config))
        write_json_atomic(tmp / "versions.json", package_versions())
        write_text_atomic(tmp / "git.txt", git_commit(repo) + "\n")
        write_text_atomic(tmp / "timings.csv", bench.to_csv(index=False))
        target = root / name
        k = 1
        while True:
            try:
                # os.rename onto an existing non-empty directory fails, so this never overwrites.
                os.rename(tmp, target)
                return target
            except OSError:
                if not target.exists():
                    raise
                target = root / f"{name}-{k}"
                k += 1
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
