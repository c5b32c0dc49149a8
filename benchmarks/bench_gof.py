"""Size and power of the goodness-of-fit test (gmwm.gof), by simulation.

    python benchmarks/bench_gof.py [--R 400] [--R-power 100] [--lengths 14 17] [--write]

Size: ``R`` seeded signals of each true model, fitted with the defaults (CI weights; some rows
with efficient weights or ARMAV); the share of p-values below 1 %, 5 %, 10 % and the KS test of
their uniformity, for the test (:func:`gmwm.gof.gof_test`, Imhof) and alternatives read off the
same fits: the same statistic with the Satterthwaite (moment-matched scaled chi-square) p-value,
the minimised objective against its own weighted chi-square null (``objective_test``) and the
generalised Wald statistic ``r' (M V M')^+ r`` (``generalised_wald``). Power: ``R_power``
signals of a generating model fitted with a model that lacks a component (its strength set by
its expected z-value in the generating model); the share rejected at 5 % by the test and by
the objective. ``--write`` replaces this benchmark's section of ``benchmarks/README.md``.

    python benchmarks/bench_gof.py --calibration [--R 400] [--R-power 200] [--workers 1]
        [--seed 2031] [--models ...] [--write]

Calibration (the p-value's law under true models, before and after the boundary correction of
:func:`gmwm.gof.gof_test`): for each model of ``CALIBRATION`` at T = 2^15 and 2^18 (and the two
``SELECTION_CELLS`` of ``selection_penalty.py`` at their own lengths and values), ``R`` seeded
signals fitted with the defaults (CI weights); from each fit the test as it is and as it was
(``hold_boundary=True``: a component at 0 held there), on the same fits; the share of p-values
below 1 % and 5 % with their Monte Carlo SEs, the KS test of uniformity and the share of fits
with a component at the boundary; as a diagnostic, the test with the WV covariance at the true
parameters. Power: ``R_power`` signals of each ``POWER_PLAIN`` generating
model fitted with a model that lacks a component, at fixed strengths. ``--write`` replaces the
calibration block of ``benchmarks/README.md`` (its own markers); ``--R-power 0`` skips the power
rows, ``--seed`` and ``--models`` rerun rows on other seeds (printed, for a recheck).

    python benchmarks/bench_gof.py --calibration --sin [--R 400] [--R-power 200] [--write]
        [--sin-compete 6.635]

The sinusoid rows (``SIN_CELLS``: the gyro WN+SIN+RW of the selection study at 2^17 and 2^18,
WN+AR1+SIN at 2^15 and 2^18) before and after the frequency correction of
:func:`gmwm.gof.gof_test` (before: ``sin_frequency=False``, the test at the fit's own frequency),
on the same fits, with the test's CPU time per fit, and the power of ``SIN_POWER`` (a component
missing beside a weak sinusoid). ``--write`` replaces its own block of ``benchmarks/README.md``
(``bench_gof_sin``); ``--sin-compete`` sets :data:`gmwm.gof.SIN_COMPETE` (``inf``: every cell
of the frequency grid, whatever its objective; printed only).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

import gmwm
from gmwm.gof import generalised_wald, gof_test, objective_test
from gmwm.inference import model_wv_cov
from gmwm.model import Model

HERE = Path(__file__).resolve().parent

_AR1_RW = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 1e-3, "RW[1].gamma2": 1e-6}
_GM = {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6, "RW[1].gamma2": 1e-9}
# label -> (model, truth, freq, fit options)
SIZE: dict[str, tuple[str, dict[str, float], float, dict]] = {
    "WN+RW": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5}, 1.0, {}),
    "WN+AR1+RW": ("WN+AR1+RW", _AR1_RW, 1.0, {}),
    "QN+WN+RW+DR": ("QN+WN+RW+DR", {"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-3,
                                     "DR[1].omega": 1e-3}, 1.0, {}),
    "WN+AR1+SIN": ("WN+AR1+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975,
                                   "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
                                   "SIN[1].beta": 0.35}, 1.0, {}),
    "WN+GM+RW (100 Hz)": ("WN+GM+RW", _GM, 100.0, {}),
    "WN+AR1+RW, efficient weights": ("WN+AR1+RW", _AR1_RW, 1.0, {"weights": "efficient"}),
    "WN+AR1+RW, ARMAV": ("WN+AR1+RW", _AR1_RW, 1.0, {"method": "armav"}),
}
# label -> (generating model, base truth, missing component, freq); the fitted model lacks the
# component, whose strength is set by its expected z-value in the generating model
POWER: dict[str, tuple[str, dict[str, float], str, float]] = {
    "WN+RW fitted to WN+AR1+RW (AR1 missing)": ("WN+AR1+RW", _AR1_RW, "AR1[1]", 1.0),
    "WN+RW fitted to WN+GM+RW (gyro, GM missing)": ("WN+GM+RW", _GM, "GM[1]", 100.0),
    "WN+GM fitted to WN+GM+RW (RW missing)": ("WN+GM+RW", _GM, "RW[1]", 100.0),
    "WN+AR1+RW, sinusoid missing": (
        "WN+AR1+SIN+RW", {**_AR1_RW, "SIN[1].alpha": 0.1, "SIN[1].beta": 0.05}, "SIN[1]", 1.0),
    "QN+WN+RW, drift missing": (
        "QN+WN+RW+DR", {"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4,
                        "DR[1].omega": 2e-4}, "DR[1]", 1.0),
    "WN fitted to a ramp in white noise": (
        "WN+DR", {"WN[1].sigma2": 1.0, "DR[1].omega": 1e-4}, "DR[1]", 1.0),
}
#: expected z-values of the missing component
POWER_Z = (3.0, 5.0, 10.0)

# -- calibration study (--calibration) ------------------------------------------------------------
# IMU-like true models: label -> (model, truth, freq). The AR1 row is issue 40's case (its RW is
# at 1-2 SE at 2^15, at the boundary 0 in about a third of the fits); 2*AR1 stands for the
# two-time-constant (bias instability-like) gyro models.
CALIBRATION: dict[str, tuple[str, dict[str, float], float]] = {
    "WN+RW": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5}, 1.0),
    "WN+AR1+RW": ("WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                                "RW[1].gamma2": 2e-5}, 1.0),
    "WN+GM+RW (100 Hz)": ("WN+GM+RW", _GM, 100.0),
    "QN+WN+RW+DR": SIZE["QN+WN+RW+DR"][:3],
    "WN+2*AR1": ("WN+2*AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.05,
                              "AR1[2].phi": 0.999, "AR1[2].sigma2": 1e-4}, 1.0),
}
CAL_LENGTHS = (15, 18)
# the two cells of benchmarks/selection_penalty.py whose true model the test rejected most often
# (issue 40): the generating values of that study at each length (its weak components at an
# expected z of 4, so they change with T), at the lengths of those cells and the next one
SELECTION_CELLS: dict[str, tuple[str, tuple[int, int]]] = {
    "accel QN+WN+RW (selection study)": ("accel QN+WN+RW", (14, 15)),
    "gyro WN+SIN+RW (selection study)": ("gyro WN+SIN+RW", (17, 18)),
}
# plain misspecifications at fixed strengths: label -> (generating model, truth, fitted, freq)
POWER_PLAIN: dict[str, tuple[str, dict[str, float], str, float]] = {
    **{f"WN+RW fitted to WN+AR1 (phi 0.999, AR1 sigma2 {s2:g})": (
        "WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.999, "AR1[1].sigma2": s2}, "WN+RW", 1.0)
       for s2 in (1e-5, 1e-6)},
    **{f"WN fitted to WN+RW (gamma2 {g:g})": (
        "WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": g}, "WN", 1.0) for g in (1e-7, 1e-8)},
    **{f"WN+RW fitted to WN+GM+RW (100 Hz, GM sigma2 {s2:g})": (
        "WN+GM+RW", {**_GM, "GM[1].sigma2": s2}, "WN+RW", 100.0) for s2 in (1e-6, 3e-7)},
}


# the sinusoid rows of the frequency correction (--sin): label -> lengths (log2 T); the gyro
# row is the selection study's (its SIN at an expected z of 4, period 2000 samples), WN+AR1+SIN
# the size table's (a strong fast SIN beside an AR1)
SIN_CELLS: dict[str, tuple[int, ...]] = {
    "gyro WN+SIN+RW (selection study)": (17, 18),
    "WN+AR1+SIN": (15, 18),
}
# a component missing beside a weak sinusoid: label -> (selection-study setting, fitted model,
# values replacing the setting's at every length); the RW at fixed strengths (at the study's
# expected z of 4 every fit without it is rejected)
SIN_POWER: dict[str, tuple[str, str, dict[str, float]]] = {
    f"WN+SIN fitted to the gyro WN+SIN+RW (RW missing, gamma2 {g:g})": (
        "gyro WN+SIN+RW", "WN+SIN", {"RW[1].gamma2": g}) for g in (1e-8, 3e-9)}


def cal_lengths(label: str) -> tuple[int, ...]:
    """The lengths (log2 T) of a calibration row."""
    return SELECTION_CELLS[label][1] if label in SELECTION_CELLS else CAL_LENGTHS


def cal_truth(label: str, k: int) -> tuple[Model, np.ndarray, float]:
    """The true model of a calibration row at T = 2^k: (model, theta, freq)."""
    if label in SELECTION_CELLS:
        import selection_penalty as sp

        s = next(s for s in sp.settings() if s.label == SELECTION_CELLS[label][0])
        model, theta = s.truth(2**k)
        return model, theta, s.freq
    spec, truth, freq = CALIBRATION[label] if label in CALIBRATION else SIZE[label][:3]
    model = Model(spec, freq)
    return model, model.theta(truth), freq


def calibration_cell(label: str, k: int, R: int, seed: int = 2031) -> dict:
    """p-values of the test after / before the boundary correction on R default fits of the
    true model ``label`` at T = 2^k, and which fits hold a component at the boundary."""
    model, theta, freq = cal_truth(label, k)
    T = 2**k
    after, before, oracle, boundary, off = [], [], [], [], []
    # a sinusoid's frequency (beta, rad/sample), to tell the fits that put it elsewhere
    beta = [c.start + 1 for c in model.components if c.process.name == "SIN"]
    t0 = time.process_time()
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, model, freq=freq)
        after.append(res.gof.p_value)
        before.append(gof_test(res, hold_boundary=True).p_value)
        # diagnostic: the covariance of the WV estimate at the truth instead of the estimate
        oracle.append(gof_test(res, model_wv_cov(model, theta, res.wv)).p_value)
        boundary.append(bool(res.diagnostics.get("at_boundary")))
        b = np.asarray(res.params, float)[beta]
        off.append(bool(np.any(np.abs(np.log(b / theta[beta])) > math.log(1.5))))
    return {"after": np.array(after), "before": np.array(before), "oracle": np.array(oracle),
            "boundary": np.array(boundary), "off": np.array(off) if beta else None,
            "cpu": time.process_time() - t0}


def plain_power_cell(label: str, k: int, R: int, seed: int = 2032) -> dict:
    """p-values after / before the correction of the misspecified fits ``label`` at 2^k."""
    spec, truth, fitted, freq = POWER_PLAIN[label]
    model = Model(spec, freq)
    theta = model.theta(truth)
    T = 2**k
    after, before = [], []
    t0 = time.process_time()
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, fitted, freq=freq)
        after.append(res.gof.p_value)
        before.append(gof_test(res, hold_boundary=True).p_value)
    return {"after": np.array(after), "before": np.array(before),
            "cpu": time.process_time() - t0}


def sin_cell(label: str, k: int, R: int, seed: int = 2031) -> dict:
    """p-values of the test after / before the sinusoid frequency correction on the same R
    default fits of the true model ``label`` at 2^k, the CPU time of each test, and which fits
    seat the SIN more than 1.5x from its true frequency."""
    model, theta, freq = cal_truth(label, k)
    T = 2**k
    after, before, off, t_after, t_before, truth = [], [], [], 0.0, 0.0, []
    beta = [c.start + 1 for c in model.components if c.process.name == "SIN"]
    t0 = time.process_time()
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, model, freq=freq)
        t1 = time.process_time()
        before.append(gof_test(res, sin_frequency=False).p_value)
        t2 = time.process_time()
        after.append(gof_test(res).p_value)
        t3 = time.process_time()
        t_before += t2 - t1
        t_after += t3 - t2
        truth.append(held_at_truth(res, theta))
        b = np.asarray(res.params, float)[beta]
        off.append(bool(np.any(np.abs(np.log(b / theta[beta])) > math.log(1.5))))
    return {"after": np.array(after), "before": np.array(before), "off": np.array(off),
            "truth": np.array(truth),
            "ms_before": 1e3 * t_before / R, "ms_after": 1e3 * t_after / R,
            "cpu": time.process_time() - t0}


def held_at_truth(res: gmwm.GMWMResult, theta: np.ndarray) -> float:
    """Diagnostic (not available on data): the p-value of the test of ``res``'s model with every
    SIN frequency held at the truth (the fit's own refit there, one more df per SIN)."""
    from gmwm import gof
    from gmwm.inference import Problem
    from gmwm.search import VP, shapes_of

    model, prob = res.model, Problem.of(res)
    vp = VP(model, prob.tau, prob.nu_hat, prob.white, 1.0, np.random.default_rng(0))
    shapes = shapes_of(model, np.asarray(res.params, float), prob.tau)
    sins = [k for k, c in enumerate(model.components) if c.process.name == "SIN"]
    for k in sins:
        shapes[k] = math.log(theta[model.components[k].start + 1])
    q, th = gof._held_fit(res, vp, shapes, sins[0], 1.0)
    return gof._held_test(res, None, [model.components[k].name for k in sins], q, th).p_value


def sin_power_cell(label: str, k: int, R: int, seed: int = 2032) -> dict:
    """p-values after / before the frequency correction of the misspecified fits ``label``."""
    import selection_penalty as sp

    setting, fitted, values = SIN_POWER[label]
    s = next(s for s in sp.settings() if s.label == setting)
    model, theta = s.truth(2**k)
    for name, v in values.items():
        theta[model.param_names.index(name)] = v
    T = 2**k
    after, before = [], []
    t0 = time.process_time()
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, fitted, freq=s.freq)
        before.append(gof_test(res, sin_frequency=False).p_value)
        after.append(gof_test(res).p_value)
    return {"after": np.array(after), "before": np.array(before),
            "cpu": time.process_time() - t0}


def sin_table(rows: list[tuple[str, int, dict]], R: int) -> list[str]:
    lines = [("| true model | T | SIN frequency off: fits | before: 1 % / 5 % (KS p) | "
              "after: 1 % / 5 % (KS p) | before, off / on: 5 % | after, off / on: 5 % | "
              "frequency held at the truth: 1 % / 5 % (KS p); off / on: 5 % | "
              "test CPU ms before / after |"), "|---|---|---|---|---|---|---|---|---|"]
    for label, k, out in rows:
        off, a, b = out["off"], out["after"], out["before"]

        def split(q: np.ndarray, off: np.ndarray = off) -> str:
            return " / ".join(f"{np.mean(v < .05):.3f}" if v.size else "-"
                              for v in (q[off], q[~off]))
        lines.append(f"| {label} | 2^{k} | {np.mean(off):.3f} | {_size_cell(b, R)} | "
                     f"{_size_cell(a, R)} | {split(b)} | {split(a)} | "
                     f"{_size_cell(out['truth'], R)}; {split(out['truth'])} | "
                     f"{out['ms_before']:.1f} / {out['ms_after']:.1f} |")
    lines += ["", (f"{R} seeded replicates per row (the seeds of the calibration block), default "
              "fit (CI weights); before = `gof_test(res, sin_frequency=False)` (the test at the "
              "fit's own frequency), after = the default `gof_test` (the largest p over the "
              "competing seatings of a sinusoid whose frequency is not identified), on the same "
              "fits; SIN frequency off: fits seating the SIN more than 1.5x from its true "
              "frequency, and the rejections at 5 % among them / among the others; frequency "
              "held at the truth: the test of the model with the SIN frequency known (the fit's "
              "refit there; a diagnostic, not available on data); test CPU: per fit, mean. "
              "Bold: beyond 2 Monte Carlo SE of the level, or KS p < 0.01.")]
    return lines


def sin_main(args: argparse.Namespace, t0: float) -> None:
    import gmwm.gof as gof_module

    if args.write and (args.seed != 2031 or args.sin_compete != gof_module.SIN_COMPETE):
        sys.exit("--write renders the study at its defaults: no --seed or --sin-compete")
    gof_module.SIN_COMPETE = args.sin_compete
    srows, prows = [], []
    for label, ks in SIN_CELLS.items():
        for k in ks:
            srows.append((label, k, sin_cell(label, k, args.R, args.seed)))
            print(label, k, f"{srows[-1][2]['cpu']:.0f} s CPU", flush=True)
    if args.R_power > 0:
        for label in SIN_POWER:
            for k in SIN_CELLS["gyro WN+SIN+RW (selection study)"]:
                prows.append((label, k, sin_power_cell(label, k, args.R_power, args.seed + 1)))
                print(label, k, f"{prows[-1][2]['cpu']:.0f} s CPU", flush=True)
    cpu = sum(out["cpu"] for *_, out in [*srows, *prows])
    lines = ["Sinusoid rows, before and after the frequency correction:", "",
             *sin_table(srows, args.R)]
    if prows:
        lines += ["", "Power beside a weak sinusoid:", "", *plain_power_table(prows, args.R_power)]
    print("\n".join(lines))
    if args.write:
        _write(f"--calibration --sin --R {args.R} --R-power {args.R_power}", lines,
               "bench_gof_sin", t0, f", {cpu:.0f} s CPU, 1 process")


def _size_cell(p: np.ndarray, R: int) -> str:
    """``1 % / 5 % (KS p)``, a share beyond 2 Monte Carlo SEs of its level in bold."""
    p = p[np.isfinite(p)]
    cells = []
    for a in (0.01, 0.05):
        share = float(np.mean(p < a))
        txt = f"{share:.3f}"
        cells.append(f"**{txt}**" if abs(share - a) > 2 * math.sqrt(a * (1 - a) / R) else txt)
    ks = stats.kstest(p, "uniform").pvalue
    ks_txt = f"{ks:.2g}"
    return f"{cells[0]} / {cells[1]} ({f'**{ks_txt}**' if ks < 0.01 else ks_txt})"


def calibration_table(rows: list[tuple[str, int, dict]], R: int) -> list[str]:
    lines = [("| true model | T | fits with a component at 0 | before: 1 % / 5 % (KS p) | "
             "after: 1 % / 5 % (KS p) | after, V at the truth | SIN frequency off: fits; "
             "after 1 % / 5 % there / elsewhere | CPU s |"),
             "|---|---|---|---|---|---|---|---|"]
    for label, k, out in rows:
        off, p = out.get("off"), out["after"]
        if off is None:
            sin = "-"
        else:
            def rates(q: np.ndarray) -> str:
                return f"{np.mean(q < .01):.3f} / {np.mean(q < .05):.3f}" if q.size else "-"
            sin = f"{np.mean(off):.3f}; {rates(p[off])} / {rates(p[~off])}"
        lines.append(f"| {label} | 2^{k} | {np.mean(out['boundary']):.3f} | "
                     f"{_size_cell(out['before'], R)} | {_size_cell(out['after'], R)} | "
                     f"{_size_cell(out['oracle'], R)} | {sin} | {out['cpu']:.0f} |")
    lines += ["", (f"{R} seeded replicates per row, default fit (CI weights); before = the test "
              "with a component at 0 held there (`gof_test(res, hold_boundary=True)`), after = "
              "the default `gof_test`, on the same fits; V at the truth: the same test with "
              "the covariance of the WV estimate at the true parameters (a diagnostic, not "
              "available on data); SIN frequency off: the share of fits whose sinusoid frequency is "
              "more than 1.5x from the truth, and the test's rejections among them / among the "
              "others. Monte Carlo SE of the share: "
              f"{math.sqrt(0.01 * 0.99 / R):.4f} at 1 %, {math.sqrt(0.05 * 0.95 / R):.4f} at 5 %; "
              "bold: beyond 2 SE of the level, or KS p < 0.01.")]
    return lines


def plain_power_table(rows: list[tuple[str, int, dict]], R: int) -> list[str]:
    lines = ["| misspecification | T | before: 5 % / 1 % | after: 5 % / 1 % |", "|---|---|---|---|"]
    for label, k, out in rows:
        b, a = out["before"], out["after"]
        lines.append(f"| {label} | 2^{k} | {np.mean(b < .05):.3f} / {np.mean(b < .01):.3f} | "
                     f"{np.mean(a < .05):.3f} / {np.mean(a < .01):.3f} |")
    lines += ["", (f"Share rejected, {R} seeded replicates per row (default fit of the model "
              "lacking the component).")]
    return lines


def _run_cell(task: tuple[str, str, int, int, int]) -> tuple[str, str, int, dict]:
    kind, label, k, R, seed = task
    fun = calibration_cell if kind == "size" else plain_power_cell
    return kind, label, k, fun(label, k, R, seed)


def calibration_main(args: argparse.Namespace) -> None:
    if args.sin:
        return sin_main(args, time.perf_counter())
    if args.write and (args.models or args.seed != 2031 or args.R_power <= 0):
        sys.exit("--write renders the full study: no --models, --seed or --R-power 0 with it")
    t0 = time.perf_counter()
    labels = args.models or [*CALIBRATION, *SELECTION_CELLS]
    tasks = [("size", lab, k, args.R, args.seed) for lab in labels for k in cal_lengths(lab)]
    if args.R_power > 0:
        tasks += [("power", lab, k, args.R_power, args.seed + 1) for lab in POWER_PLAIN
                  for k in CAL_LENGTHS]
    if args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.workers) as pool:
            done = list(pool.map(_run_cell, tasks))
    else:
        done = []
        for task in tasks:
            done.append(_run_cell(task))
            print(task[:3], f"{done[-1][3]['cpu']:.0f} s CPU", flush=True)
    srows = [(lab, k, out) for kind, lab, k, out in done if kind == "size"]
    prows = [(lab, k, out) for kind, lab, k, out in done if kind == "power"]
    cpu = sum(out["cpu"] for *_, out in done)
    lines = [("Size (true model fitted; share of p-values below 1 % and 5 %, KS test of their "
             "uniformity):"), "", *calibration_table(srows, args.R)]
    if prows:
        lines += ["", "Power (plain misspecifications, fixed strengths):", "",
                  *plain_power_table(prows, args.R_power)]
    print("\n".join(lines))
    if args.write:
        seed = "" if args.seed == 2031 else f" --seed {args.seed}"
        _write(f"--calibration --R {args.R} --R-power {args.R_power}{seed}", lines,
               "bench_gof_calibration", t0,
               f", {cpu:.0f} s CPU in the fits and tests, {args.workers} process(es)")


def satterthwaite(objective: float, lam: np.ndarray) -> float:
    m1, m2 = lam.sum(), (lam**2).sum()
    return float(stats.chi2.sf(objective * m1 / m2, m1**2 / m2))


def size_row(label: str, T: int, R: int, seed: int = 2029) -> dict:
    spec, truth, freq, opts = SIZE[label]
    model = Model(spec, freq)
    theta = model.theta(truth)
    p = {"test": [], "satterthwaite": [], "objective": [], "generalised Wald": []}
    t0 = time.process_time()
    t_gof = 0.0
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, model, freq=freq, **opts)
        t1 = time.process_time()
        g = gof_test(res)
        t_gof += time.process_time() - t1
        p["test"].append(g.p_value)
        U = g.statistic * g.eigenvalues.sum() / g.df
        p["satterthwaite"].append(satterthwaite(U, g.eigenvalues))
        p["objective"].append(objective_test(res)[2])
        p["generalised Wald"].append(generalised_wald(res)[2])
    return {"p": {k: np.array(v) for k, v in p.items()}, "cpu": time.process_time() - t0,
            "gof_ms": 1e3 * t_gof / R}


def power_row(label: str, T: int, z: float, R: int, seed: int = 2030) -> dict:
    """Rejections of the fit without the missing component (ValueError: z not reachable)."""
    from bench_selection import calibrate

    spec, truth, missing, freq = POWER[label]
    model = Model(spec, freq)
    theta = calibrate(model, model.theta(truth), missing, z, T)
    comps = [c.process.name for c in model.components if c.name != missing]
    fitted = "+".join(comps)
    p, q = [], []
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, T, r]))
        res = gmwm.fit(x, fitted, freq=freq)
        p.append(gof_test(res).p_value)
        q.append(objective_test(res)[2])
    return {"p": np.array(p), "objective": np.array(q)}


def size_table(rows: list[tuple[str, int, dict]], R: int) -> list[str]:
    lines = [("| true model | T | test: 1 % / 5 % / 10 % | KS p | Satterthwaite p: 1 % / 5 % | "
              "objective: 5 % (KS p) | generalised Wald: 5 % (KS p) | test ms/fit |"),
             "|---|---|---|---|---|---|---|---|"]

    def rate_ks(x: np.ndarray) -> str:
        x = x[np.isfinite(x)]
        return f"{np.mean(x < .05):.3f} ({stats.kstest(x, 'uniform').pvalue:.2g})"

    for label, T, out in rows:
        p = out["p"]
        t = p["test"]
        ok = np.isfinite(t)
        sat = p["satterthwaite"][ok]
        lines.append(
            f"| {label} | 2^{round(math.log2(T))} | {np.mean(t[ok] < .01):.3f} / "
            f"{np.mean(t[ok] < .05):.3f} / {np.mean(t[ok] < .1):.3f} | "
            f"{stats.kstest(t[ok], 'uniform').pvalue:.2g} | {np.mean(sat < .01):.3f} / "
            f"{np.mean(sat < .05):.3f} | {rate_ks(p['objective'])} | "
            f"{rate_ks(p['generalised Wald'])} | {out['gof_ms']:.1f} |")
    se = math.sqrt(0.05 * 0.95 / R)
    lines += ["", (f"{R} replicates per row: the Monte Carlo SE of a 5 % rejection share is "
              f"{se:.3f}.")]
    return lines


def power_table(rows: list[tuple[str, int, dict[float, dict | str]]], R: int) -> list[str]:
    zs = sorted({z for _, _, out in rows for z in out})
    lines = ["| misspecification | T | " + " | ".join(f"missing at z = {z:g}" for z in zs) + " |",
             "|---|---|" + "---|" * len(zs)]
    for label, T, out in rows:
        cells = []
        for z in zs:
            o = out.get(z)
            cells.append(o if isinstance(o, str) else
                         f"{np.mean(o['p'] < .05):.2f} / {np.mean(o['objective'] < .05):.2f}")
        lines.append(f"| {label} | 2^{round(math.log2(T))} | " + " | ".join(cells) + " |")
    lines += ["", (f"Share rejected at 5 % by the test / by the objective, {R} replicates per "
              "cell; z = the "
              "missing component's expected z-value (estimate / SE) in the generating model at "
              "that length (n/a: not reachable there).")]
    return lines


def _write(command: str, lines: list[str], name: str, t0: float, cost: str = "") -> None:
    """Replace section ``name`` of benchmarks/README.md with ``lines`` under a header giving
    the command (its options ``command``), commit, wall time, ``cost`` and load."""
    from bench_selection import commit, write_section

    head = (f"Generated by `python benchmarks/bench_gof.py {command} --write` (commit {commit()}, "
            f"{time.perf_counter() - t0:.0f} s wall{cost}, 1-minute load "
            f"{os.getloadavg()[0]:.1f} at the end).\n")
    write_section(head + "\n" + "\n".join(lines), name)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=int, default=400)
    ap.add_argument("--R-power", type=int, default=100)
    ap.add_argument("--lengths", type=int, nargs="+", default=[14, 17], metavar="K")
    ap.add_argument("--size", nargs="*", default=list(SIZE))
    ap.add_argument("--power", nargs="*", default=list(POWER))
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--calibration", action="store_true",
                    help="the calibration study (module docstring) instead of size and power")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2031,
                    help="calibration: the size rows' seed (the power rows' is seed + 1)")
    ap.add_argument("--models", nargs="*", choices=[*CALIBRATION, *SELECTION_CELLS], default=None,
                    help="calibration: these true models only (default all)")
    ap.add_argument("--sin", action="store_true",
                    help="calibration: the sinusoid rows before/after the frequency correction")
    ap.add_argument("--sin-compete", type=float, default=6.635,
                    help="--sin: gmwm.gof.SIN_COMPETE for this run (inf: the whole grid)")
    args = ap.parse_args()
    if args.calibration:
        sys.path.insert(0, str(HERE))
        if "--R-power" not in sys.argv:
            args.R_power = 200
        return calibration_main(args)
    t0 = time.perf_counter()
    srows, prows = [], []
    for label in args.size:
        for k in args.lengths:
            out = size_row(label, 2**k, args.R)
            srows.append((label, 2**k, out))
            print("\n".join(size_table([srows[-1]], args.R)[2:3]), f"[{out['cpu']:.0f} s CPU]",
                  flush=True)
    sys.path.insert(0, str(HERE))
    for label in args.power:
        for k in args.lengths:
            cells: dict[float, dict | str] = {}
            for z in POWER_Z:
                try:
                    cells[z] = power_row(label, 2**k, z, args.R_power)
                except ValueError:
                    cells[z] = "n/a"
            prows.append((label, 2**k, cells))
            print("\n".join(power_table([prows[-1]], args.R_power)[2:3]), flush=True)
    lines = ["Size (true model fitted; share of p-values below each level):", "",
             *size_table(srows, args.R), "", ("Power (a component missing from the fitted "
             "model; default fit):"), "", *power_table(prows, args.R_power)]
    print("\n".join(lines))
    if args.write:
        _write(f"--R {args.R} --R-power {args.R_power} --lengths "
               f"{' '.join(map(str, args.lengths))}", lines, "bench_gof", t0)


if __name__ == "__main__":
    sys.exit(main())
