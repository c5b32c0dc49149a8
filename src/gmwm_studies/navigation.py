"""Navigation emulation of the vibration-noise paper (000, section 5, Figs. 7-8).

Per iteration b (paper protocol, docs/METHODS.md §12.5): the AR1 + RW estimates of Model 1 (misspecified) and
Model 2 (true) fitted to a Table 5 signal (here: replicate b of the misspecification study, whose
simulation and fits are exactly steps (i)-(ii)) tune two EKFs; a gyro error signal is simulated
from the basic AR1 + RW part of Table 5, added to the ideal IMU of a fixed trajectory, and both
filters process the same corrupted measurements and GNSS fixes. The statistic is the ratio of the
mean (over iterations) l2 position errors, Model 1 / Model 2, at each epoch.

Units: the Table 5 signal is a z-gyroscope in deg/s sampled at 200 Hz; the emulated IMU runs at
100 Hz, so per-sample parameters are converted (:func:`convert_basic`): the AR1 as a first-order
Gauss-Markov process (same correlation time and stationary variance), the RW by its continuous
coefficient K^2 = gamma2 f_s. Values are then scaled deg -> rad for the filter (:mod:`.ekf`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import InputError
from gmwm_studies.seeds import stable_int

from .ekf import FilterSetup, exp_so3, log_so3, run_filter

__all__ = [
    "Trajectory",
    "concat_chunks",
    "convert_basic",
    "emulate",
    "filter_setup",
    "gnss_schedule",
    "iteration_table",
    "make_trajectory",
    "plot_fig7",
    "plot_fig8",
    "ratio_series",
    "ratio_summary",
    "ratio_with_ci",
    "variant_config",
]

DEG = np.pi / 180.0


# ---------------------------------------------------------------------------------------------
# trajectory
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Trajectory:
    """True trajectory at the IMU epochs and the ideal IMU between them (SI units, ENU, FLU body).

    ``t``, ``pos``, ``vel``, ``C`` have N + 1 rows (epochs); ``gyro``, ``accel`` N rows (the rate
    and specific force held over each interval, exact for the mechanisation of :mod:`.ekf`)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    C: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])


def _smooth_box(t: np.ndarray, start: float, stop: float, ramp: float) -> np.ndarray:
    """1 on [start, stop], 0 outside, raised-cosine ramps of ``ramp`` s inside the interval."""
    up = np.clip((t - start) / ramp, 0.0, 1.0)
    down = np.clip((stop - t) / ramp, 0.0, 1.0)
    return 0.25 * (1 - np.cos(np.pi * up)) * (1 - np.cos(np.pi * down))


#: Manoeuvres of the default flight (start s, stop s, value): turn rates [deg/s], positive = left,
#: and climb rates [m/s]. Chosen to turn and climb before, during and after the GNSS outage.
TURNS = ((20.0, 35.0, 6.0), (60.0, 90.0, -6.0), (110.0, 125.0, 6.0), (140.0, 155.0, -4.0),
         (170.0, 185.0, 6.0), (195.0, 205.0, -9.0), (220.0, 230.0, 4.5))
CLIMBS = ((5.0, 35.0, 2.0), (70.0, 85.0, -1.5), (120.0, 140.0, 1.0), (165.0, 180.0, -2.0),
          (190.0, 200.0, 1.5), (215.0, 230.0, -1.0))


def make_trajectory(duration: float = 235.0, rate: float = 100.0, speed: float = 12.0,
                    altitude0: float = 50.0, g: float = 9.80665,
                    turns: Sequence[tuple[float, float, float]] = TURNS,
                    climbs: Sequence[tuple[float, float, float]] = CLIMBS) -> Trajectory:
    """A fixed drone-like flight: ground speed ``speed`` +- 2 m/s [m/s], smoothed turns and
    climbs (``turns`` in deg/s, ``climbs`` in m/s), coordinated-turn bank, nose along the flight path.

    Built from analytic rates: heading and altitude are integrated on a 10x finer grid; the IMU
    increments are obtained by inverting the discrete mechanisation between epochs, so an error-free
    IMU reproduces the trajectory to rounding; positions are the trapezoidal integral of velocity."""
    n = round(duration * rate)
    if n < 2:
        raise InputError(f"trajectory needs at least 2 IMU samples, got duration {duration} s")
    dt = 1.0 / rate
    fine = 10
    tf = np.arange(n * fine + 1) * (dt / fine)
    turn = sum(w * DEG * _smooth_box(tf, a, b, 2.0) for a, b, w in turns)
    climb = sum(c * _smooth_box(tf, a, b, 3.0) for a, b, c in climbs)
    vh = speed + 2.0 * np.sin(2 * np.pi * tf / 90.0)
    # trapezoid on the fine grid, then every `fine`-th point
    psi = np.concatenate([[0.0], np.cumsum((turn[1:] + turn[:-1]) * (dt / fine) / 2)]) + 0.3
    t = tf[::fine]
    psi, turn, climb, vh = psi[::fine], turn[::fine], climb[::fine], vh[::fine]
    vel = np.column_stack([vh * np.cos(psi), vh * np.sin(psi), climb])
    pos = np.zeros((n + 1, 3))
    pos[0, 2] = altitude0
    pos[1:] = pos[0] + np.cumsum((vel[1:] + vel[:-1]) * (dt / 2), axis=0)
    pitch = np.arctan2(climb, vh)
    roll = -np.arctan(vh * turn / g)  # bank into the turn (body left axis down for a left turn)
    C = exp_so3(np.column_stack([0 * psi, 0 * psi, psi])) @ exp_so3(
        np.column_stack([0 * psi, -pitch, 0 * psi])) @ exp_so3(np.column_stack([roll, 0 * psi,
                                                                                0 * psi]))
    dR = np.swapaxes(C[:-1], -1, -2) @ C[1:]
    gyro = log_so3(dR) / dt
    Cmid = C[:-1] @ exp_so3(gyro * dt / 2)
    acc_n = np.diff(vel, axis=0) / dt - np.array([0.0, 0.0, -g])
    accel = np.einsum("kji,kj->ki", Cmid, acc_n)  # Cmid^T acc_n
    return Trajectory(t=t, pos=pos, vel=vel, C=C, gyro=gyro, accel=accel)


def gnss_schedule(traj: Trajectory, rate: float = 1.0,
                  outage: tuple[float, float] = (160.0, 210.0)) -> np.ndarray:
    """IMU epoch indices of the GNSS fixes: every 1/``rate`` s from 1/``rate`` on, none strictly
    inside the outage (fixes at its two ends are kept: a 50 s gap for (160, 210))."""
    step = round(1.0 / (rate * traj.dt))
    steps = np.arange(step, len(traj.t), step)
    tt = traj.t[steps]
    return steps[~((tt > outage[0] + 1e-9) & (tt < outage[1] - 1e-9))]


# ---------------------------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------------------------


def convert_basic(theta: np.ndarray, freq_from: float, freq_to: float) -> np.ndarray:
    """Per-sample (phi, sigma2, gamma2) of AR1 + RW at ``freq_from`` -> at ``freq_to`` [Hz].

    AR1 as a Gauss-Markov process: correlation time and stationary variance kept, so
    phi' = phi**(freq_from / freq_to) and sigma2' = q (1 - phi'^2), q = sigma2 / (1 - phi^2).
    RW: K^2 = gamma2 freq_from kept, gamma2' = gamma2 freq_from / freq_to. ``theta`` (..., 3).
    Requires 0 < phi < 1 (a Gauss-Markov correlation)."""
    theta = np.asarray(theta, dtype=float)
    phi, s2, g2 = theta[..., 0], theta[..., 1], theta[..., 2]
    if np.any(~(phi > 0) | ~(phi < 1)):
        raise InputError("AR1 phi must be in (0, 1) to convert between sampling rates")
    q = s2 / (1.0 - phi * phi)
    phi2 = phi ** (freq_from / freq_to)
    return np.stack([phi2, q * (1.0 - phi2 * phi2), g2 * freq_from / freq_to], axis=-1)


def filter_setup(cfg: Mapping[str, Any], rate: float) -> FilterSetup:
    """FilterSetup from the ``navigation`` config (datasheet-style units, see config/README.md)."""
    axes = tuple({"x": 0, "y": 1, "z": 2}[a] for a in cfg["gyro_axes"])
    vrw = cfg["accel_vrw"] / 60.0  # m/s/sqrt(h) -> m/s/sqrt(s)
    gnss = cfg["gnss_sd"]
    gnss = tuple(float(s) for s in (gnss if isinstance(gnss, list | tuple) else [gnss] * 3))
    init = cfg["initial_sd"]
    return FilterSetup(dt=1.0 / rate, axes=axes, accel_sd=vrw * np.sqrt(rate), gnss_sd=gnss,
                       p0_sd=(init["position"], init["velocity"], init["roll_pitch"] * DEG,
                              init["yaw"] * DEG))


# ---------------------------------------------------------------------------------------------
# emulation
# ---------------------------------------------------------------------------------------------


def _iteration_rng(study: str, iteration: int, base_seed: int) -> list[np.random.Generator]:
    """Four independent streams of one iteration: gyro errors, accel noise, GNSS, initial errors."""
    ss = np.random.SeedSequence(entropy=int(base_seed), spawn_key=(stable_int(study), int(iteration)))
    return [np.random.default_rng(s) for s in ss.spawn(4)]


def emulate(
    traj: Trajectory,
    setup: FilterSetup,
    truth_basic: np.ndarray,
    filter_params: np.ndarray,
    iterations: Sequence[int],
    study: str,
    base_seed: int,
    gnss_steps: np.ndarray,
    unit_scale: float = DEG,
    record_every: int = 10,
    return_states: bool = False,
) -> dict[str, np.ndarray]:
    """Emulate ``len(iterations)`` flights, each filtered by every parameter set of the iteration.

    ``truth_basic`` (3,): (phi, sigma2, gamma2) of the gyro error per IMU sample in the signal's
    units (deg/s); ``filter_params`` (I, M, 3): the M filters' parameters per iteration, same units;
    ``unit_scale`` converts the signal unit to rad/s. Iteration b draws from the streams keyed by
    (study, b), so results do not depend on chunking. Returns ``time`` (R,) [s], ``pos_err_norm``
    (I, M, R) [m], ``pos_sd`` (I, M, R) = sqrt(trace P_pos) [m]; with ``return_states`` also the
    raw :func:`.ekf.run_filter` output (batch index = iteration * M + model)."""
    from gmwm.model import Model

    fp = np.asarray(filter_params, dtype=float)
    iters = [int(i) for i in iterations]
    if fp.ndim != 3 or fp.shape[0] != len(iters) or fp.shape[2] != 3:
        raise InputError(f"filter_params must have shape ({len(iters)}, M, 3), got {fp.shape}")
    n_it, n_mod = fp.shape[:2]
    N = len(traj.gyro)
    basic = Model("AR1+RW")
    theta = np.asarray(truth_basic, dtype=float)  # AR1+RW canonical order: phi, sigma2, gamma2
    gyro = np.repeat(traj.gyro[None], n_it, axis=0)
    accel = np.repeat(traj.accel[None], n_it, axis=0)
    fixes = np.repeat(traj.pos[gnss_steps][None], n_it, axis=0)
    p0 = np.repeat(traj.pos[:1], n_it, axis=0)
    v0 = np.repeat(traj.vel[:1], n_it, axis=0)
    C0 = np.repeat(traj.C[:1], n_it, axis=0)
    sd0 = np.sqrt(setup.initial_nav_cov())
    for i, it in enumerate(iters):
        r_gyro, r_acc, r_gnss, r_init = _iteration_rng(study, it, base_seed)
        for a in setup.axes:
            gyro[i, :, a] += unit_scale * basic.simulate(theta, N, r_gyro)
        accel[i] += setup.accel_sd * r_acc.standard_normal((N, 3))
        fixes[i] += np.asarray(setup.gnss_sd) * r_gnss.standard_normal(fixes[i].shape)
        e0 = sd0 * r_init.standard_normal(9)  # truth minus estimate
        p0[i] -= e0[0:3]
        v0[i] -= e0[3:6]
        C0[i] = exp_so3(-e0[6:9]) @ C0[i]
    rep = np.repeat  # batch index = iteration * M + model
    params = fp.reshape(n_it * n_mod, 3) * np.array([1.0, unit_scale**2, unit_scale**2])
    res = run_filter(setup, params, rep(gyro, n_mod, 0), rep(accel, n_mod, 0), gnss_steps,
                     rep(fixes, n_mod, 0), rep(p0, n_mod, 0), rep(v0, n_mod, 0), rep(C0, n_mod, 0),
                     traj.pos, traj.C if return_states else None, record_every=record_every)
    norm = np.linalg.norm(res["pos_err"], axis=-1).reshape(n_it, n_mod, -1)
    sd = np.sqrt(np.trace(res["pos_cov"], axis1=-2, axis2=-1)).reshape(n_it, n_mod, -1)
    out = {"time": traj.t[res["step"]], "pos_err_norm": norm, "pos_sd": sd}
    if return_states:
        out["raw"] = res
    return out


def emulation_dataset(result: Mapping[str, np.ndarray], iterations: Sequence[int],
                      models: Sequence[str], filter_params: np.ndarray,
                      attrs: Mapping[str, Any]) -> xr.Dataset:
    """The emulation output of one chunk as a Dataset (dims iteration, model, time)."""
    return xr.Dataset(
        {
            "pos_err_norm": (("iteration", "model", "time"), result["pos_err_norm"]),
            "pos_sd": (("iteration", "model", "time"), result["pos_sd"]),
            "filter_params": (("iteration", "model", "parameter"), np.asarray(filter_params)),
        },
        coords={"iteration": np.asarray(iterations, dtype=np.int64),
                "model": np.asarray(models, dtype=object),
                "time": result["time"],
                "parameter": np.asarray(["AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2"],
                                        dtype=object)},
        attrs=dict(attrs),
    )


BASIC = ("AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2")
UNIT_SCALE = {"deg/s": DEG, "rad/s": 1.0}


def filter_params_from_fits(fits: Mapping[str, xr.Dataset], models: Sequence[str],
                            iterations: Sequence[int], freq_from: float, freq_to: float
                            ) -> tuple[np.ndarray, list[int], dict[int, str]]:
    """The AR1 + RW estimates of each model for each iteration (= replicate id), converted from
    ``freq_from`` to ``freq_to``. An iteration is dropped (with its reason) when any model's fit
    did not converge or its AR1 is not a Gauss-Markov correlation (phi outside (0, 1)).

    Returns (params (I, M, 3) in signal units per IMU sample, kept iterations, dropped reasons)."""
    rows, kept, dropped = [], [], {}
    for it in iterations:
        thetas, why = [], ""
        for m in models:
            ds = fits[m]
            if it not in ds["replicate"].values:
                raise InputError(f"iteration {it}: replicate missing from the {m} estimates")
            rep = ds.sel(replicate=it)
            th = np.array([float(rep["estimate"].sel(parameter=p)) for p in BASIC])
            if not bool(rep["converged"]) or not np.all(np.isfinite(th)):
                why = f"{m} fit did not converge"
            elif not 0 < th[0] < 1:
                why = f"{m} AR1 phi = {th[0]:.3g} outside (0, 1)"
            thetas.append(th)
        if why:
            dropped[int(it)] = why
            continue
        rows.append(convert_basic(np.array(thetas), freq_from, freq_to))
        kept.append(int(it))
    params = np.array(rows).reshape(len(kept), len(models), 3)
    return params, kept, dropped


def run_chunk(cfg: Mapping[str, Any], fits: Mapping[str, xr.Dataset], truth: Mapping[str, float],
              iterations: Sequence[int], study: str = "navigation") -> xr.Dataset:
    """One chunk of the emulation from the ``navigation`` config: filter parameters from the
    misspecification fits, error truth from the AR1 + RW part of ``truth``. Dataset with dims
    (iteration, model, time); dropped iterations are listed in the attribute ``dropped``."""
    import json

    rate, f_cal = float(cfg["imu_rate"]), float(cfg["freq_calibration"])
    traj = make_trajectory(duration=float(cfg["duration"]), rate=rate)
    steps = gnss_schedule(traj, float(cfg["gnss_rate"]), tuple(cfg["outage"]))
    setup = filter_setup(cfg, rate)
    models = list(cfg["models"])
    params, kept, dropped = filter_params_from_fits(fits, models, iterations, f_cal, rate)
    theta = convert_basic(np.array([float(truth[p]) for p in BASIC]), f_cal, rate)
    every = max(1, round(rate / float(cfg["record_rate"])))
    attrs = {"study": study, "truth_basic_imu_rate": json.dumps(theta.tolist()),
             "dropped": json.dumps(dropped), "config": json.dumps(dict(cfg), sort_keys=True)}
    if not kept:
        t = traj.t[::every]
        empty = {"time": t, "pos_err_norm": np.zeros((0, len(models), len(t))),
                 "pos_sd": np.zeros((0, len(models), len(t)))}
        return emulation_dataset(empty, [], models, params, attrs)
    res = emulate(traj, setup, theta, params, kept, study, int(cfg["seed"]), steps,
                  unit_scale=UNIT_SCALE[cfg["gyro_unit"]], record_every=every)
    return emulation_dataset(res, kept, models, params, attrs)


# Keys a variant (config navigation.variants.<name>) may override; everything else (trajectory,
# sensors, filter, seeds) is the main study's, so a variant isolates the effect of these keys.
VARIANT_KEYS = ("gyro_axes", "iterations", "chunk_size")
RESERVED_VARIANT_NAMES = ("chunks", "replicates")  # directories of the main study


def variant_config(nav: Mapping[str, Any], name: str) -> dict[str, Any]:
    """The ``navigation`` config of variant ``name``: the main study's keys (same order, without
    ``variants``) with the variant's overrides (:data:`VARIANT_KEYS`) substituted. The seed is the
    main study's and :func:`run_chunk` keys the streams by the study name ``navigation``, so
    iteration b of a variant draws the same accelerometer, GNSS and initial errors as iteration b
    of the main study (and its gyro errors from the same stream)."""
    variants = nav.get("variants") or {}
    if name not in variants:
        raise InputError(f"navigation: unknown variant {name!r} (configured: {sorted(variants)})")
    if name in RESERVED_VARIANT_NAMES:
        raise InputError(f"navigation: variant name {name!r} is reserved ({RESERVED_VARIANT_NAMES})")
    over = dict(variants[name])
    bad = sorted(set(over) - set(VARIANT_KEYS))
    if bad:
        raise InputError(f"navigation.variants.{name}: keys {bad} cannot be varied "
                         f"(allowed: {list(VARIANT_KEYS)})")
    out = {k: over.get(k, v) for k, v in nav.items() if k != "variants"}
    out["variant"] = name
    return out


def concat_chunks(parts: Sequence[xr.Dataset]) -> tuple[xr.Dataset, dict[int, str]]:
    """The chunk Datasets of :func:`run_chunk` joined along ``iteration`` (sorted), and the
    dropped iterations of all chunks (iteration -> reason)."""
    import json

    if not parts:
        raise InputError("navigation: no chunk to gather")
    ds = xr.concat(list(parts), dim="iteration", combine_attrs="override").sortby("iteration")
    dropped = {int(k): v for p in parts for k, v in json.loads(p.attrs["dropped"]).items()}
    return ds, dropped


# ---------------------------------------------------------------------------------------------
# statistics
# ---------------------------------------------------------------------------------------------


def ratio_with_ci(e1: np.ndarray, e2: np.ndarray, level: float = 0.95) -> dict[str, np.ndarray]:
    """Ratio of mean errors mean(e1) / mean(e2) per column, paired over rows (iterations), with a
    delta-method CI: var(ratio) ~ (var e1 - 2 r cov(e1, e2) + r^2 var e2) / (n mean(e2)^2)."""
    from scipy.stats import norm

    e1, e2 = np.asarray(e1, dtype=float), np.asarray(e2, dtype=float)
    n = e1.shape[0]
    if n < 2 or e1.shape != e2.shape:
        raise InputError("ratio_with_ci needs two equally shaped arrays with >= 2 rows")
    m1, m2 = e1.mean(0), e2.mean(0)
    r = m1 / m2
    c = np.cov(e1.T, e2.T, ddof=1) if e1.ndim == 1 else None
    if c is not None:
        v1, v2, c12 = c[0, 0], c[1, 1], c[0, 1]
    else:
        d1, d2 = e1 - m1, e2 - m2
        v1 = (d1 * d1).sum(0) / (n - 1)
        v2 = (d2 * d2).sum(0) / (n - 1)
        c12 = (d1 * d2).sum(0) / (n - 1)
    se = np.sqrt(np.maximum(v1 - 2 * r * c12 + r * r * v2, 0.0) / n) / m2
    z = norm.ppf(0.5 + level / 2)
    return {"ratio": r, "se": se, "lo": r - z * se, "hi": r + z * se}


def ratio_summary(ds: xr.Dataset, models: tuple[str, str] = ("model1", "model2"),
                  outage: tuple[float, float] = (160.0, 210.0), n_boot: int = 999,
                  seed: int = 0, level: float = 0.95) -> pd.DataFrame:
    """Key numbers of Fig. 8: the maximum of the ratio (overall and inside the outage), its epoch,
    the pointwise delta-method CI there, and a paired bootstrap percentile CI of the maximum itself
    (iterations resampled); also the mean position errors of both filters at that epoch."""
    e1 = ds["pos_err_norm"].sel(model=models[0]).values
    e2 = ds["pos_err_norm"].sel(model=models[1]).values
    t = ds["time"].values
    ci = ratio_with_ci(e1, e2, level)
    rng = np.random.default_rng(seed)
    n = e1.shape[0]
    W = rng.multinomial(n, np.full(n, 1.0 / n), size=n_boot).astype(float)  # (boot, n) counts
    rb = (W @ e1) / (W @ e2)
    rows = []
    for label, mask in (("whole flight", np.ones_like(t, dtype=bool)),
                        ("GNSS outage", (t >= outage[0]) & (t <= outage[1]))):
        k = int(np.flatnonzero(mask)[np.argmax(ci["ratio"][mask])])
        mx = rb[:, mask].max(axis=1)
        rows.append({
            "window": label, "n_iterations": n, "time_s": float(t[k]),
            "max_ratio": float(ci["ratio"][k]), "ci_lo": float(ci["lo"][k]), "ci_hi": float(ci["hi"][k]),
            "boot_max_lo": float(np.quantile(mx, (1 - level) / 2)),
            "boot_max_hi": float(np.quantile(mx, (1 + level) / 2)),
            "mean_err_model1_m": float(e1[:, k].mean()), "mean_err_model2_m": float(e2[:, k].mean()),
            "share_ratio_ci_above_1": float(np.mean(ci["lo"][mask] > 1)),
        })
    return pd.DataFrame(rows)


def ratio_series(ds: xr.Dataset, models: tuple[str, str] = ("model1", "model2"),
                 level: float = 0.95) -> pd.DataFrame:
    """Fig. 8 in numbers (``ratio_series.csv``): per recorded epoch ``time_s``, the ratio of mean
    position errors with its pointwise delta-method CI, both filters' mean errors [m] and mean
    predicted position SDs [m]. The columns name the models as model1 / model2 (first / second)."""
    e1 = ds["pos_err_norm"].sel(model=models[0]).values
    e2 = ds["pos_err_norm"].sel(model=models[1]).values
    ci = ratio_with_ci(e1, e2, level)
    return pd.DataFrame({"time_s": ds["time"].values, "ratio": ci["ratio"], "ci_lo": ci["lo"],
                         "ci_hi": ci["hi"], "mean_err_model1_m": e1.mean(0),
                         "mean_err_model2_m": e2.mean(0),
                         "mean_sd_model1_m": ds["pos_sd"].sel(model=models[0]).values.mean(0),
                         "mean_sd_model2_m": ds["pos_sd"].sel(model=models[1]).values.mean(0)})


def iteration_table(ds: xr.Dataset, dropped: Mapping[int, str], iterations: Sequence[int],
                    peak_time: float, outage: tuple[float, float] = (160.0, 210.0)
                    ) -> pd.DataFrame:
    """One row per configured iteration and model (``reports/navigation/replicates/
    iterations.csv``): ``dropped`` (1/0) and its ``reason`` (:func:`filter_params_from_fits`), the
    filter's AR1 + RW parameters (per IMU sample, signal units; empty when dropped) and the
    iteration's position errors [m]: ``err_at_peak_m`` at ``peak_time`` (the epoch of the ratio's
    maximum, so the ratio of the two models' means there is the table's ``max_ratio``),
    ``max_err_m`` over the flight and ``mean_err_outage_m`` over the outage."""
    models = [str(m) for m in ds["model"].values]
    t = ds["time"].values
    k = int(np.argmin(np.abs(t - float(peak_time))))
    out_mask = (t >= outage[0]) & (t <= outage[1])
    kept = {int(i): n for n, i in enumerate(ds["iteration"].values)}
    unknown = sorted((set(kept) | {int(i) for i in dropped}) - {int(i) for i in iterations})
    if unknown:
        raise InputError(f"navigation: iterations {unknown[:5]} are not configured ones")
    rows = []
    for it in sorted(int(i) for i in iterations):
        if it not in kept and it not in dropped:
            raise InputError(f"navigation: iteration {it} is neither in the results nor dropped")
        for m, model in enumerate(models):
            row: dict[str, Any] = {"iteration": it, "model": model, "dropped": int(it not in kept),
                                   "reason": dropped.get(it, "")}
            if it in kept:
                n = kept[it]
                e = ds["pos_err_norm"].values[n, m]
                row.update({p: float(v) for p, v in zip(BASIC, ds["filter_params"].values[n, m],
                                                         strict=True)})
                row.update({"err_at_peak_m": float(e[k]), "max_err_m": float(e.max()),
                            "mean_err_outage_m": float(e[out_mask].mean())})
            rows.append(row)
    cols = ["iteration", "model", "dropped", "reason", *BASIC, "err_at_peak_m", "max_err_m",
            "mean_err_outage_m"]
    return pd.DataFrame(rows).reindex(columns=cols)


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------


def plot_fig7(traj: Trajectory, gnss_steps: np.ndarray, outage: tuple[float, float]) -> Any:
    """Fig. 7: the horizontal path (GNSS fixes dotted, outage stretch highlighted) and the altitude
    profile with the outage shaded. Returns the Figure."""
    from gmwm.plots import PALETTE, subplots

    fig, (a, b) = subplots(1, 2, figsize=(8.0, 3.4))
    t = traj.t
    inside = (t >= outage[0]) & (t <= outage[1])
    a.plot(traj.pos[:, 0], traj.pos[:, 1], color=PALETTE[1], label="trajectory")
    a.plot(traj.pos[inside, 0], traj.pos[inside, 1], color=PALETTE[2], linewidth=2.2,
           label=f"GNSS outage ({outage[0]:g}-{outage[1]:g} s)")
    a.plot(traj.pos[gnss_steps, 0], traj.pos[gnss_steps, 1], ".", color="black", markersize=1.8,
           label="GNSS fixes (1 Hz)")
    a.plot(*traj.pos[0, :2], "o", color=PALETTE[3], label="start")
    a.set_xlabel("East [m]")
    a.set_ylabel("North [m]")
    a.set_aspect("equal", adjustable="datalim")
    a.legend(loc="best")
    b.plot(t, traj.pos[:, 2], color=PALETTE[1])
    b.axvspan(*outage, color="grey", alpha=0.25, label="GNSS outage")
    b.set_xlabel("Time [s]")
    b.set_ylabel("Altitude [m]")
    b.legend(loc="best")
    return fig


def plot_fig8(ds: xr.Dataset, outage: tuple[float, float],
              models: tuple[str, str] = ("model1", "model2"), level: float = 0.95) -> Any:
    """Fig. 8: ratio of mean position errors Model 1 / Model 2 over time with its pointwise CI,
    outage shaded, reference line at 1. Returns the Figure."""
    from gmwm.plots import PALETTE, subplots

    e1 = ds["pos_err_norm"].sel(model=models[0]).values
    e2 = ds["pos_err_norm"].sel(model=models[1]).values
    ci = ratio_with_ci(e1, e2, level)
    t = ds["time"].values
    keep = t > 0  # at t = 0 both filters hold the same initial estimate (ratio exactly 1)
    fig, ax = subplots(1, 1, figsize=(6.0, 3.2))
    ax.axvspan(*outage, color="grey", alpha=0.25, label="GNSS outage")
    ax.fill_between(t[keep], ci["lo"][keep], ci["hi"][keep], color=PALETTE[1], alpha=0.3,
                    linewidth=0, label=f"{level:.0%} CI")
    ax.plot(t[keep], ci["ratio"][keep], color=PALETTE[1], linewidth=0.9, label="ratio")
    ax.axhline(1.0, color="black", linestyle="--", linewidth=0.8)
    ax.set_xlabel("Time [s]")
    ax.set_ylabel("Position error ratio (Model 1 / Model 2)")
    ax.set_title(f"{e1.shape[0]} iterations")
    ax.legend(loc="upper left")
    return fig
