"""Navchip real-data analysis ([GMWFM] Sec. V, docs/METHODS.md §10.5): GMWM fits per axis, the datasheet model,
goodness of fit.

Input: the public Navchip wavelet variance (Haar MODWT, 20 levels, 95 % chi-square CI; gyroscope in
rad/s, accelerometer in m/s^2, 250 Hz, T = 3,105,250), obtained by :func:`gmwm_studies.data.obtain`.

* Fit: ``QN + WN + 2*GM + RW + DR`` by :func:`gmwm.fit` on each axis (the WV is all there is: the
  raw signal is not public, so the drift sign is not identified and reported positive).
* Standard errors: those of :func:`gmwm.fit` (sandwich of docs/METHODS.md §5.9 with the model covariance of
  the WV estimate, :mod:`gmwm.inference`); the bootstrap CIs are a separate step reading the fits
  file written here. Components at the boundary 0 get no SE.
* Datasheet model: WN + bias instability (:func:`gmwm_studies.sensors.navchip_datasheet`), BI drawn as
  band-limited flicker; the datasheet gives no RW, QN or DR.
* Goodness of fit: share of scales where a model WV lies inside the empirical WV's CI.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gmwm import units
from gmwm.errors import InputError
from gmwm_studies import sensors

__all__ = [
    "AXES",
    "ChannelFit",
    "channels_from_fits",
    "datasheet_label",
    "estimates_table",
    "figure_decomposition",
    "figure_wv_datasheet",
    "fit_channel",
    "fit_channels",
    "fits_to_json",
    "gof_table",
    "inside_ci",
    "load_fits",
    "obtain_navchip",
    "write_tables",
]

AXES = ("X", "Y", "Z")
BOUNDARY_SHARE = 1e-6
UNITS = {"gyroscope": "rad/s", "accelerometer": "m/s^2"}


@dataclass(frozen=True)
class ChannelFit:
    """GMWM fit of one channel with its SEs, boundary flags and goodness of fit."""

    sensor: str
    axis: str
    wv: Any                 # gmwm.wv.WaveletVariance (with the file's CI)
    model: Any              # gmwm.model.Model at the WV's frequency
    params: np.ndarray      # estimates, canonical order, per-sample units (GM beta in 1/s)
    se: np.ndarray          # sandwich SE in free coordinates, delta method (NaN at the boundary)
    se_library: np.ndarray  # SE reported by gmwm.fit (sandwich in theta coordinates)
    boundary: np.ndarray    # bool per parameter: its component contributes < 1e-6 of the WV
    inside: np.ndarray      # bool per scale: model WV inside the WV CI
    inside_datasheet: np.ndarray
    converged: bool
    objective: float
    message: str
    warnings: tuple[str, ...] = ()
    seconds_fit: float = 0.0

    @property
    def param_names(self) -> list[str]:
        return list(self.model.param_names)

    def as_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.params)

    def model_wv(self) -> np.ndarray:
        return self.model.wv(self.params, self.wv.scales)

    def component_wv(self) -> dict[str, np.ndarray]:
        return self.model.component_wv(self.params, self.wv.scales)

    @property
    def gof(self) -> float:
        return float(np.mean(self.inside))

    @property
    def gof_datasheet(self) -> float:
        return float(np.mean(self.inside_datasheet))


def obtain_navchip(dest_dir: str | os.PathLike, dataset: str = "navchip_wv",
                   data_dir: str | os.PathLike | None = None, allow_download: bool = True) -> Path:
    """Put the dataset's CSV (and .json sidecar) into ``dest_dir``; return the CSV path.

    Raises :class:`~gmwm.errors.DataUnavailableError` naming the file and its public source when it
    is neither in ``data_dir`` (None: the registry's ``local_dir``) nor downloadable.
    """
    from gmwm_studies.data import obtain

    dest = Path(dest_dir)
    dest.mkdir(parents=True, exist_ok=True)
    return obtain(dataset, dest, local_dir=data_dir, allow_download=allow_download)


def inside_ci(wv: Any, model_wv: np.ndarray) -> np.ndarray:
    """Bool per scale: ``ci_low <= model_wv <= ci_high``."""
    m = np.asarray(model_wv, dtype=float)
    return (m >= np.asarray(wv.ci_low)) & (m <= np.asarray(wv.ci_high))


def _boundary(result: Any) -> np.ndarray:
    """Per parameter: its component is at the boundary 0 (as reported by the fit)."""
    gone = set(result.diagnostics.get("at_boundary", []))
    return np.array([n.split(".")[0] in gone for n in result.model.param_names], dtype=bool)


def datasheet_wv(sensor: str, scales: np.ndarray, freq: float) -> dict[str, np.ndarray]:
    """Datasheet model WV (keys WN, BI, total) at ``scales`` [samples]; BI band-limited flicker."""
    return sensors.datasheet_wv(sensors.navchip_datasheet(sensor, freq), scales, bi_form="band-limited")


def datasheet_label(sensor: str, freq: float = 250.0) -> str:
    """How the datasheet model is drawn, for legends and captions."""
    ds = sensors.navchip_datasheet(sensor, freq)
    bi = ds.components["BI"]
    return (f"Datasheet: WN {ds.datasheet['WN']} + BI {ds.datasheet['BI']} "
            f"(band-limited flicker, f0 = {bi['f0']:g} Hz); RW not given")


def fit_channel(wv: Any, model: str, sensor: str, axis: str,
                fit_settings: Mapping[str, Any] | None = None) -> ChannelFit:
    """GMWM fit of ``model`` to one channel's WV (at the WV's frequency), SEs and GOF."""
    from gmwm.estimator import fit

    settings = dict(fit_settings or {})
    res = fit(wv, model, freq=wv.freq, **settings)
    boundary = _boundary(res)
    sheet = datasheet_wv(sensor, wv.scales, wv.freq)["total"]
    return ChannelFit(sensor=sensors.canonical_sensor(sensor), axis=str(axis).upper(), wv=res.wv,
                      model=res.model, params=np.asarray(res.params, float),
                      se=np.asarray(res.se, float), se_library=np.asarray(res.se, float),
                      boundary=boundary, inside=inside_ci(wv, res.model_wv()),
                      inside_datasheet=inside_ci(wv, sheet), converged=bool(res.converged),
                      objective=float(res.objective), message=str(res.message),
                      warnings=tuple(res.diagnostics.get("warnings", [])),
                      seconds_fit=float(res.seconds_fit))


def channels_from_fits(data_path: str | os.PathLike, fits_path: str | os.PathLike
                       ) -> list[ChannelFit]:
    """Rebuild the channel fits from the data file and a fits file (no refit)."""
    from gmwm.model import Model
    from gmwm_studies.data import load_navchip_wv

    out = []
    for (sensor, axis), rec in load_fits(fits_path).items():
        wv = load_navchip_wv(data_path, sensor, axis)
        model = Model(rec["model"], freq=float(rec["freq"]))
        names = model.param_names
        params = model.theta(rec["params"], estimate=True)
        sheet = datasheet_wv(sensor, wv.scales, wv.freq)["total"]
        out.append(ChannelFit(
            sensor=sensor, axis=axis, wv=wv, model=model, params=params,
            se=np.array([rec["se"][n] for n in names], dtype=float),
            se_library=np.array([rec["se_library"][n] for n in names], dtype=float),
            boundary=np.array([rec["boundary"][n] for n in names], dtype=bool),
            inside=inside_ci(wv, model.wv(params, wv.scales)),
            inside_datasheet=inside_ci(wv, sheet), converged=bool(rec["converged"]),
            objective=float(rec["objective"]), message=str(rec["message"]),
            warnings=tuple(rec.get("warnings", []))))
    return out


def fit_channels(path: str | os.PathLike, model: str, sensors: Sequence[str] = ("gyroscope",),
                 axes: Sequence[str] = AXES, fit_settings: Mapping[str, Any] | None = None,
                 progress: Any = None) -> list[ChannelFit]:
    """Fit every requested channel of the Navchip WV CSV at ``path``."""
    from gmwm_studies.data import load_navchip_wv

    out = []
    for sensor in sensors:
        for axis in axes:
            wv = load_navchip_wv(path, sensor, axis)
            cf = fit_channel(wv, model, sensor, axis, fit_settings)
            if progress is not None:
                progress(f"{cf.sensor} {cf.axis}: converged={cf.converged}, "
                         f"GOF {cf.gof:.2f} (datasheet {cf.gof_datasheet:.2f}), "
                         f"{cf.seconds_fit:.1f} s")
            out.append(cf)
    return out


# ---------------------------------------------------------------------------------------------
# the fits file (hook for the bootstrap step) and tables
# ---------------------------------------------------------------------------------------------


def fits_to_json(fits: Sequence[ChannelFit], fit_settings: Mapping[str, Any],
                 source: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """JSON-able record of all channel fits: model, freq, T, estimates, SEs, flags, GOF, the WV
    with its CI and the fit settings -- everything a parametric bootstrap needs to refit."""
    channels = []
    for cf in fits:
        names = cf.param_names
        channels.append({
            "sensor": cf.sensor, "axis": cf.axis, "unit": UNITS[cf.sensor],
            "model": cf.model.spec, "freq": float(cf.wv.freq), "n_samples": int(cf.wv.n_samples),
            "params": cf.as_dict(),
            "se": dict(zip(names, map(float, cf.se), strict=True)),
            "se_library": dict(zip(names, map(float, cf.se_library), strict=True)),
            "boundary": dict(zip(names, map(bool, cf.boundary), strict=True)),
            "converged": cf.converged, "message": cf.message, "objective": cf.objective,
            "warnings": list(cf.warnings),
            "gof": cf.gof, "gof_datasheet": cf.gof_datasheet,
            "inside_ci": [bool(v) for v in cf.inside],
            "wv": cf.wv.to_dict(),
        })
    return {"analysis": "navchip", "fit_settings": dict(fit_settings),
            "source": dict(source or {}), "channels": channels}


def load_fits(path: str | os.PathLike) -> dict[tuple[str, str], dict[str, Any]]:
    """Read a fits file written by the navchip_fit rule: {(sensor, axis): channel record}.

    Each record has ``model``, ``freq``, ``n_samples``, ``params`` (canonical names, per-sample
    units), ``se``, ``boundary``, ``converged``, ``gof`` and ``wv`` (levels, scales, variance, CI).
    """
    import json

    path = Path(path)
    if not path.is_file():
        raise InputError(f"Navchip fits file not found: {path} (run the navchip_fit rule)")
    with open(path, encoding="utf-8") as fh:
        data = json.load(fh)
    return {(c["sensor"], c["axis"]): c for c in data["channels"]}


def estimates_table(fits: Sequence[ChannelFit]) -> pd.DataFrame:
    """Long table: sensor, axis, parameter, estimate, SE, relative SE, unit note, boundary flag."""
    rows = []
    for cf in fits:
        for k, name in enumerate(cf.param_names):
            est = float(cf.params[k])
            rows.append({
                "sensor": cf.sensor, "axis": cf.axis, "parameter": name, "estimate": est,
                "se": float(cf.se[k]), "rel_se": float(cf.se[k] / abs(est)) if est else np.nan,
                "unit": _param_unit(name, UNITS[cf.sensor]), "at_boundary": bool(cf.boundary[k]),
                "converged": cf.converged,
            })
    return pd.DataFrame(rows)


def _param_unit(name: str, u: str) -> str:
    ctype, par = name.split("[", 1)[0], name.split(".", 1)[1]
    if ctype == "GM" and par == "beta":
        return "1/s"
    if ctype == "DR":
        return f"{u} per sample"
    return f"({u})^2"


def gof_table(fits: Sequence[ChannelFit], threshold: float) -> pd.DataFrame:
    """Per channel: share of scales inside the WV CI for the GMWM and the datasheet model, the
    verdict ``model_fits`` (share >= threshold), the white-noise density against the datasheet."""
    rows = []
    for cf in fits:
        sheet = sensors.navchip_datasheet(cf.sensor, cf.wv.freq)
        n_est = float(units.wn_density_from_sigma2(cf.as_dict()["WN[1].sigma2"], cf.wv.freq))
        n_sheet = float(sheet.components["WN"]["density"])
        outside = [int(j) for j, ok in zip(cf.wv.levels, cf.inside, strict=True) if not ok]
        rows.append({
            "sensor": cf.sensor, "axis": cf.axis, "n_scales": int(cf.wv.n_levels),
            "gof_gmwm": cf.gof, "gof_datasheet": cf.gof_datasheet,
            "model_fits": bool(cf.gof >= threshold), "converged": cf.converged,
            "objective": cf.objective,
            "levels_outside_ci": " ".join(map(str, outside)),
            "wn_density_est": n_est, "wn_density_datasheet": n_sheet,
            "wn_density_ratio": n_est / n_sheet, "density_unit": f"{UNITS[cf.sensor]}/sqrt(Hz)",
        })
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------


def _grid(fits: Sequence[ChannelFit]) -> tuple[Any, np.ndarray, list[str]]:
    from gmwm.plots import subplots

    sensors = list(dict.fromkeys(cf.sensor for cf in fits))
    fig, axes = subplots(len(sensors), len(AXES), figsize=(4.0 * len(AXES), 3.4 * len(sensors)),
                         squeeze=False)
    return fig, axes, sensors


def _ax_for(axes: np.ndarray, sensors: list[str], cf: ChannelFit) -> Any:
    return axes[sensors.index(cf.sensor), AXES.index(cf.axis)]


def figure_wv_datasheet(fits: Sequence[ChannelFit], threshold: float) -> Any:
    """Figure 3 of [GMWFM] per axis: empirical WV with its 95 % CI, the GMWM model WV and the
    datasheet model WV (WN + band-limited BI; RW not given), with the GOF shares in the title."""
    from gmwm.plots import PALETTE, plot_wv

    fig, axes, sensors = _grid(fits)
    for cf in fits:
        ax = _ax_for(axes, sensors, cf)
        plot_wv(cf.wv, model=cf.model, theta=cf.params, components=False, ax=ax,
                units=UNITS[cf.sensor], label="Empirical WV")
        ax.lines[-1].set_label("GMWM model WV")
        x = cf.wv.scales / cf.wv.freq
        ax.plot(x, datasheet_wv(cf.sensor, cf.wv.scales, cf.wv.freq)["total"], ls="--",
                color=PALETTE[2], lw=1.3, label="Datasheet model WV")
        verdict = "fits" if cf.gof >= threshold else "does not fit"
        ax.set_title(f"{cf.sensor} {cf.axis}: in CI {cf.gof:.0%} GMWM ({verdict}), "
                     f"{cf.gof_datasheet:.0%} datasheet", fontsize=8)
        ax.legend(loc="lower left", fontsize=6)
    fig.suptitle("\n".join(f"{s}: {datasheet_label(s)}" for s in sensors), fontsize=8,
                 color=PALETTE[2])
    return fig


def figure_decomposition(fits: Sequence[ChannelFit]) -> Any:
    """Figure 4 of [GMWFM] per axis: empirical WV with CI, GMWM model WV and its components
    (components at the boundary 0 are not drawn)."""
    from gmwm.plots import plot_wv

    fig, axes, sensors = _grid(fits)
    for cf in fits:
        ax = _ax_for(axes, sensors, cf)
        plot_wv(cf.wv, model=cf.model, theta=cf.params, components=True, ax=ax,
                units=UNITS[cf.sensor])
        # drop lines of boundary components (they would sit decades below the data)
        names = {c.name for c in cf.model.components if cf.boundary[c.slice].any()}
        for line in list(ax.lines):
            if line.get_label() in names:
                line.remove()
        ax.set_title(f"{cf.sensor} {cf.axis}: {cf.model.spec}", fontsize=8)
        ax.legend(loc="lower left", fontsize=6, ncol=2)
    return fig


def write_tables(estimates: pd.DataFrame, gof: pd.DataFrame, threshold: float, model: str,
                 estimates_csv: str | os.PathLike, estimates_md: str | os.PathLike,
                 gof_csv: str | os.PathLike, gof_md: str | os.PathLike) -> None:
    """Write the estimates and goodness-of-fit tables as CSV and Markdown (atomically)."""
    from gmwm.atomic import write_text_atomic
    from gmwm_studies.montecarlo import format_markdown_table

    write_text_atomic(estimates_csv, estimates.to_csv(index=False))
    write_text_atomic(gof_csv, gof.to_csv(index=False))
    write_text_atomic(estimates_md, "\n".join([
        f"# Navchip: GMWM estimates of `{model}` per axis", "",
        ("Per-sample parameters (signal in rad/s or m/s^2, 250 Hz; GM beta in 1/s, GM sigma2 the "
        "stationary variance). SE: gmwm.fit's sandwich with the covariance of the WV estimate "
        "under the fitted model (between-scale correlation included; it assumes the model is "
        "right, which the GOF table questions for accelerometer X and Y; bootstrap CIs are a "
        "separate step). `at_boundary`: the component contributes < 1e-6 of the WV at every scale "
        "(estimate exactly 0, no SE). The drift sign is not identified from a WV."),
        "", format_markdown_table(estimates, digits=4)]))
    verdict = ", ".join(f"{r.sensor} {r.axis}: {'fits' if r.model_fits else 'does not fit'}"
                        for r in gof.itertuples())
    write_text_atomic(gof_md, "\n".join([
        "# Navchip: goodness of fit", "",
        ("Share of the 20 scales where the model WV lies inside the empirical WV's 95 % CI, for the "
        f"GMWM model and for the datasheet model; the model 'fits' an axis when the GMWM share is "
        f">= {threshold:g}. Verdict: {verdict}. `wn_density_*`: white-noise density of the GMWM "
        "estimate and of the datasheet."), "", format_markdown_table(gof, digits=4)]))
