"""Coverage of parameter intervals: plain Wald against the domain-respecting rule of
:mod:`gmwm.intervals` (and the natural-scale Wald truncated to the domain), by simulation.

    python benchmarks/bench_intervals.py [--R 300] [--write]

For each model, ``R`` seeded signals are simulated and fitted with the defaults (CI weights,
model-based SEs); per parameter the table gives the share of replicates whose 95 % interval
covers the truth (Wilson 95 % interval of the share in brackets) and the number of Wald interval
ends outside the parameter's domain. ``--write`` replaces this benchmark's section of
``benchmarks/README.md`` with the tables.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.special import ndtri
from scipy.stats import binomtest

import gmwm
from gmwm.intervals import fit_intervals, param_domains
from gmwm.model import Model

HERE = Path(__file__).resolve().parent
# label -> (model, base truth, T, freq, {component: expected z-value at T} set by calibration)
CASES: dict[str, tuple[str, dict[str, float], int, float, dict[str, float]]] = {
    "WN+AR1+RW, RW z=2": ("WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99,
                                        "AR1[1].sigma2": 1e-3, "RW[1].gamma2": 1e-6},
                          2**15, 1.0, {"RW[1]": 2.0}),
    "WN+RW, RW z=1": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 2**15, 1.0,
                      {"RW[1]": 1.0}),
    "WN+RW, RW z=1.5": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 2**15, 1.0,
                        {"RW[1]": 1.5}),
    "WN+RW, RW z=2": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 2**15, 1.0,
                      {"RW[1]": 2.0}),
    "WN+RW, RW z=2.5": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 2**15, 1.0,
                        {"RW[1]": 2.5}),
    "WN+RW, RW z=3": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}, 2**15, 1.0,
                      {"RW[1]": 3.0}),
    "QN+WN+RW+DR": ("QN+WN+RW+DR", {"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0,
                                     "RW[1].gamma2": 1e-3, "DR[1].omega": 1e-3}, 2**16, 1.0, {}),
    "WN+AR1+SIN": ("WN+AR1+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975,
                                   "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
                                   "SIN[1].beta": 0.35}, 2**15, 1.0, {}),
    "WN+GM+RW (100 Hz), GM z=3, RW z=3": (
        "WN+GM+RW", {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
                     "RW[1].gamma2": 1e-9}, 2**17, 100.0, {"RW[1]": 3.0, "GM[1]": 3.0}),
    "WN+AR1, phi near 1": ("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9995,
                                      "AR1[1].sigma2": 1e-5}, 2**15, 1.0, {}),
}


def wald(params: np.ndarray, se: np.ndarray, alpha: float = 0.05) -> np.ndarray:
    z = ndtri(1 - alpha / 2)
    return np.column_stack([params - z * se, params + z * se])


def domain(model: Model) -> np.ndarray:
    """(p, 2) closed domain of each parameter (the processes' ``domain``)."""
    return param_domains(model)


def truncated(model: Model, ci: np.ndarray) -> np.ndarray:
    """Natural-scale Wald cut to the domain (NaN stays NaN)."""
    d = domain(model)
    return np.column_stack([np.maximum(ci[:, 0], d[:, 0]), np.minimum(ci[:, 1], d[:, 1])])


def run_case(spec: str, truth: dict[str, float], T: int, freq: float, R: int,
             zs: dict[str, float] | None = None, seed: int = 2027) -> dict:
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    from bench_selection import calibrate

    model = Model(spec, freq)
    theta = model.theta(truth)
    for comp, z in (zs or {}).items():
        theta = calibrate(model, theta, comp, z, T)
    kinds = ("wald", "truncated", "rule")
    ci = {k: np.full((R, model.n_params, 2), np.nan) for k in kinds}
    boundary = np.zeros(R, int)
    t0 = time.process_time()
    for r in range(R):
        x = model.simulate_fast(theta, T, np.random.default_rng([seed, r]))
        res = gmwm.fit(x, model, freq=freq)
        w = wald(res.params, res.se)
        ci["wald"][r] = w
        ci["truncated"][r] = truncated(model, w)
        ci["rule"][r] = fit_intervals(res)
        boundary[r] = len(res.diagnostics["at_boundary"])
    return {"model": model, "theta": theta, "ci": ci, "boundary": boundary,
            "cpu": time.process_time() - t0}


def coverage_cell(ci: np.ndarray, truth: float) -> str:
    ok = np.all(np.isfinite(ci), axis=1)
    hit = (ci[ok, 0] <= truth) & (truth <= ci[ok, 1])
    n, k = int(ok.sum()), int(hit.sum())
    if n == 0:
        return "-"
    w = binomtest(k, n).proportion_ci(0.95, method="wilson")
    return f"{k / n:.3f} [{w.low:.2f}, {w.high:.2f}]" + ("" if n == len(ci) else f" (n={n})")


def table(label: str, out: dict) -> list[str]:
    model, theta, ci = out["model"], out["theta"], out["ci"]
    d = domain(model)
    R = ci["wald"].shape[0]
    lines = [(f"**{label}** ({model.spec}, T = {out['T']}, {R} fits, "
             f"{int(np.sum(out['boundary'] > 0))} with a component at the boundary 0)"), "",
             "| parameter | truth | Wald | Wald cut to domain | rule | Wald ends outside |",
             "|---|---|---|---|---|---|"]
    for i, name in enumerate(model.param_names):
        w = ci["wald"][:, i]
        with np.errstate(invalid="ignore"):
            outside = int(np.sum(w[:, 0] < d[i, 0]) + np.sum(w[:, 1] > d[i, 1]))
        cells = [coverage_cell(ci[k][:, i], theta[i]) for k in ("wald", "truncated", "rule")]
        lines.append(f"| {name} | {theta[i]:.4g} | " + " | ".join(cells) + f" | {outside} |")
    rule = ci["rule"]
    with np.errstate(invalid="ignore"):
        inside = np.isnan(rule) | ((rule >= d[None, :, :1]) & (rule <= d[None, :, 1:]))
    lines += ["", (f"rule: {int(np.sum(~inside))} ends outside the domain; "
              f"{int(np.sum(np.isnan(rule[..., 0])))} parameters without an interval "
              f"(no SE); {out['cpu']:.0f} s CPU"), ""]
    return lines


def write_section(text: str, begin: str = "<!-- bench_intervals:begin -->",
                  end: str = "<!-- bench_intervals:end -->") -> None:
    path = HERE / "README.md"
    src = path.read_text()
    block = f"{begin}\n{text}\n{end}"
    if begin in src and end in src:
        src = src[:src.index(begin)] + block + src[src.index(end) + len(end):]
    else:
        src = src.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(src)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=int, default=300)
    ap.add_argument("--cases", nargs="+", default=list(CASES))
    ap.add_argument("--write", action="store_true",
                    help="replace this benchmark's section of benchmarks/README.md")
    args = ap.parse_args()
    lines: list[str] = []
    for label in args.cases:
        spec, truth, T, freq, zs = CASES[label]
        out = run_case(spec, truth, T, freq, args.R, zs)
        out["T"] = T
        block = table(label, out)
        print("\n".join(block), flush=True)
        lines += block
    if args.write:
        import os

        load = os.getloadavg()[0]
        head = (f"Generated by `python benchmarks/bench_intervals.py --R {args.R} --write` "
                f"(commit {_commit()}, 1-minute load {load:.1f} at the end). Coverage of 95 % "
                "intervals, Wilson 95 % interval of the share in brackets.\n")
        write_section(head + "\n" + "\n".join(lines))


def _commit() -> str:
    import subprocess

    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, text=True,
                              capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


if __name__ == "__main__":
    sys.exit(main())
