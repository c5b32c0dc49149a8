"""Selection study: which criterion keeps weak but real components (and what dropping one costs).

    python benchmarks/bench_selection.py [--reps 40] [--lengths 14 17 20] [--write]

Design. IMU-like generating models, each with a random walk (the term whose loss makes a
navigation filter over-confident) and one weak but real component whose strength is set by its
*expected z-value* (scale parameter / its sandwich SE at the truth, computed on the noise-free
WV of length T with the default CI weights and the model-based WV covariance; :func:`calibrate`),
so "a random walk at 3 SE" means the same at every T:

* ``WN+RW``, the random walk at z = 2, 3, 5 (accelerometer: VRW + AccRW);
* ``WN+AR1+RW``, the random walk at z = 2, 3, 5 next to a strong AR1 (phi = 0.995);
* ``WN+GM+RW`` at 100 Hz, a Gauss-Markov (1/beta = 2 s) at z = 3 next to a random walk at z = 4;
* ``WN+SIN+RW``, a slow sinusoid (period 2000 samples) at z = 3 next to a random walk at z = 4;
* null settings, every component strong: ``WN+RW`` (RW z = 8) and ``WN+GM+RW`` (GM z = 8, RW
  z = 5) (the cost side: spurious additions).

A random walk next to a slow AR1/GM is hard to separate: its expected z-value saturates as
gamma2 grows (e.g. at about 2 at T = 2^14 next to the AR1 or GM above), so settings whose
target is not reachable at a length are skipped and listed.

Each replicate is ranked (:func:`gmwm.select.rank_models`, its defaults) over the candidates one
component away from the generating model (one removed or one added, from
:func:`gmwm.select.auto_candidates`), and every criterion of :mod:`gmwm.criteria` is read off the
same fits. Reported per setting and criterion: the share of replicates whose first-ranked model
is the generating one, the share that dropped the weak component, the share that added one,
and the random-walk error of the selected model, ``RMS(K_hat / K - 1)`` with ``K = sqrt(gamma2)``
(the RRW coefficient; 1 when the selected model has no RW). ``--write`` replaces this
benchmark's section of ``benchmarks/README.md`` with the tables.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gmwm.criteria import CRITERIA
from gmwm.inference import Problem, model_wv_cov, weight_matrix
from gmwm.model import Model, parse_model
from gmwm.select import auto_candidates, rank_models, rerank
from gmwm.wv import WaveletVariance, wvar

HERE = Path(__file__).resolve().parent


# -- design ----------------------------------------------------------------------------------------
def expected_se(model: Model, theta: np.ndarray, T: int) -> np.ndarray:
    """Sandwich SEs at the truth on the noise-free WV of a T-sample signal (default levels, CI
    weights, model-based WV covariance)."""
    J = math.floor(math.log2(T)) - 1
    tau = 2.0 ** np.arange(1, J + 1)
    wv = WaveletVariance.from_table(tau, model.wv(theta, tau), n_samples=T, freq=model.freq)
    prob = Problem(model, wv, weight_matrix(wv, "ci"))
    _, se, _ = prob.sandwich(theta, model_wv_cov(model, theta, wv))
    return se


def calibrate(model: Model, theta: np.ndarray, component: str, z: float, T: int) -> np.ndarray:
    """``theta`` with ``component``'s scale parameter set so that its expected z-value (scale /
    expected SE) is ``z`` at length T: doubling or halving from the given value until the target
    is bracketed, then bisection on the log scale. ValueError if the z-value cannot reach the
    target (it saturates when the component's own noise sets its SE)."""
    comp = next(c for c in model.components if c.name == component)
    i = comp.start + comp.process.scale_index
    th = np.array(theta, dtype=float)

    def zval(log_s: float) -> float:
        th[i] = math.exp(log_s)
        return float(th[i] / expected_se(model, th, T)[i])

    a = math.log(theta[i])
    za = zval(a)
    step = math.log(2.0) if za < z else -math.log(2.0)
    for _ in range(40):
        b = a + step
        zb = zval(b)
        if not (np.isfinite(zb) and (zb > za if step > 0 else zb < za)):
            raise ValueError(f"the expected z-value of {component} saturates at {max(za, zb):.3g}"
                             f" < {z:g}")
        if (zb - z) * (za - z) <= 0:
            break
        a, za = b, zb
    else:
        raise ValueError(f"{component}: target z = {z} not bracketed at T = {T}")
    lo, hi = (a, b) if step > 0 else (b, a)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if zval(mid) < z else (lo, mid)
    if abs(zval(0.5 * (lo + hi)) - z) > 0.01 * z:
        raise ValueError(f"{component}: calibration to z = {z} failed at T = {T}")
    return th


@dataclass
class Setting:
    label: str
    spec: str
    base: dict[str, float]
    weak: str                     # component whose strength is the design variable
    z: float
    strong: dict[str, float] = field(default_factory=dict)   # other components' z
    freq: float = 1.0

    def truth(self, T: int) -> tuple[Model, np.ndarray]:
        model = Model(self.spec, self.freq)
        theta = model.theta(self.base)
        for comp, z in self.strong.items():
            theta = calibrate(model, theta, comp, z, T)
        return model, calibrate(model, theta, self.weak, self.z, T)


_WN_RW = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}
_WN_AR1_RW = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995, "AR1[1].sigma2": 2e-3,
              "RW[1].gamma2": 1e-6}
_WN_GM_RW = {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
             "RW[1].gamma2": 1e-9}
_WN_SIN_RW = {"WN[1].sigma2": 1.0, "SIN[1].alpha": 0.1, "SIN[1].beta": 2 * math.pi / 2000,
              "RW[1].gamma2": 1e-6}


def settings() -> list[Setting]:
    out = [Setting(f"WN+RW, RW z={z:g}", "WN+RW", _WN_RW, "RW[1]", z) for z in (2, 3, 5)]
    out += [Setting(f"WN+AR1+RW, RW z={z:g}", "WN+AR1+RW", _WN_AR1_RW, "RW[1]", z)
            for z in (2, 3, 5)]
    out.append(Setting("WN+GM+RW, GM z=3", "WN+GM+RW", _WN_GM_RW, "GM[1]", 3,
                       {"RW[1]": 4}, 100.0))
    out.append(Setting("WN+SIN+RW, slow SIN z=3", "WN+SIN+RW", _WN_SIN_RW, "SIN[1]", 3,
                       {"RW[1]": 4}))
    out.append(Setting("null: WN+RW, RW z=8", "WN+RW", _WN_RW, "RW[1]", 8))
    out.append(Setting("null: WN+GM+RW, GM z=8", "WN+GM+RW", _WN_GM_RW, "GM[1]", 8,
                       {"RW[1]": 5}, 100.0))
    return out


# -- one replicate ---------------------------------------------------------------------------------
def distance(a: str, b: str) -> int:
    ca, cb = parse_model(a), parse_model(b)
    return sum(abs(ca.get(k, 0) - cb.get(k, 0)) for k in set(ca) | set(cb))


def candidates(spec: str) -> list[str]:
    return [c for c in auto_candidates(spec) if distance(c, spec) <= 1]


def rw_gamma2(result) -> float:
    """gamma2 of a fit's random walk (0 if it has none)."""
    d = result.as_dict()
    return float(d.get("RW[1].gamma2", 0.0))


def replicate(setting: Setting, T: int, r: int, model: Model, theta: np.ndarray,
              cands: list[str], criteria: tuple[str, ...] = CRITERIA, seed: int = 2028
              ) -> dict[str, tuple[str, float]]:
    """Per criterion: (selected model, its RW gamma2) for replicate r."""
    key = sum(map(ord, setting.label))
    x = model.simulate_fast(theta, T, np.random.default_rng([seed, key, T, r]))
    ranking = rank_models(wvar(x, freq=setting.freq), cands)
    out = {}
    for crit in criteria:
        best = rerank(ranking, crit).best
        out[crit] = (best.model, rw_gamma2(best.result))
    return out


def summarise(setting: Setting, model: Model, theta: np.ndarray,
              picks: list[dict[str, tuple[str, float]]]) -> dict[str, dict[str, float]]:
    weak_type = setting.weak.split("[")[0]
    n_weak = parse_model(model.spec).get(weak_type, 0)
    g0 = float(model.as_dict(theta)["RW[1].gamma2"])
    out = {}
    for crit in picks[0]:
        sel = [p[crit] for p in picks]
        hit = np.mean([m == model.spec for m, _ in sel])
        dropped = np.mean([parse_model(m).get(weak_type, 0) < n_weak for m, _ in sel])
        added = np.mean([sum(parse_model(m).values()) > sum(parse_model(model.spec).values())
                         for m, _ in sel])
        err = np.array([math.sqrt(max(g, 0.0) / g0) - 1 for _, g in sel])
        out[crit] = {"hit": hit, "dropped": dropped, "added": added,
                     "rrw_rms": float(np.sqrt(np.mean(err**2)))}
    return out


def run(setting: Setting, T: int, reps: int) -> tuple[dict, float, int]:
    """Summary, CPU seconds per replicate and number of candidates (ValueError: the setting's
    z-values are not reachable at length T)."""
    model, theta = setting.truth(T)
    cands = candidates(model.spec)
    t0 = time.process_time()
    picks = [replicate(setting, T, r, model, theta, cands) for r in range(reps)]
    cpu = (time.process_time() - t0) / reps
    return summarise(setting, model, theta, picks), cpu, len(cands)


def table(rows: list[tuple[Setting, int, dict, float, int]], reps: int) -> list[str]:
    head = ("| setting | T | " + " | ".join(f"{c} hit" for c in CRITERIA) + " | "
            + " | ".join(f"{c} dropped / added" for c in CRITERIA) + " | "
            + " | ".join(f"{c} RRW rms err" for c in CRITERIA) + " | s/rep |")
    lines = [head, "|" + "---|" * (3 + 3 * len(CRITERIA))]
    for s, T, summ, cpu, _ in rows:
        cells = [f"{summ[c]['hit']:.2f}" for c in CRITERIA]
        cells += [f"{summ[c]['dropped']:.2f} / {summ[c]['added']:.2f}" for c in CRITERIA]
        cells += [f"{summ[c]['rrw_rms']:.2f}" for c in CRITERIA]
        lines.append(f"| {s.label} | 2^{round(math.log2(T))} | " + " | ".join(cells)
                     + f" | {cpu:.2f} |")
    weak = [row for row in rows if not row[0].label.startswith("null")]
    null = [row for row in rows if row[0].label.startswith("null")]

    def mean_hit(group: list, what: str = "hit") -> str:
        return ", ".join(f"{c} {np.mean([r[2][c][what] for r in group]):.2f}"
                         for c in CRITERIA) if group else "-"

    lines += ["", (f"Mean hit rate over all rows: {mean_hit(rows)}; weak-component rows: "
              f"{mean_hit(weak)}; null rows: {mean_hit(null)}. Mean RRW rms error over all "
              f"rows: {mean_hit(rows, 'rrw_rms')} ({reps} replicates per row).")]
    return lines


def write_section(text: str, name: str = "bench_selection") -> None:
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    path = HERE / "README.md"
    src = path.read_text()
    block = f"{begin}\n{text}\n{end}"
    if begin in src and end in src:
        src = src[:src.index(begin)] + block + src[src.index(end) + len(end):]
    else:
        src = src.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(src)


def commit() -> str:
    import subprocess

    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, text=True,
                              capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=40)
    ap.add_argument("--lengths", type=int, nargs="+", default=[14, 17, 20], metavar="K")
    ap.add_argument("--settings", nargs="+", default=None, help="labels (default: all)")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    chosen = [s for s in settings() if args.settings is None or s.label in args.settings]
    rows = []
    skipped = []
    t0 = time.perf_counter()
    for s in chosen:
        for k in args.lengths:
            try:
                summ, cpu, nc = run(s, 2**k, args.reps)
            except ValueError as err:
                skipped.append(f"{s.label} at T = 2^{k}: {err}")
                print(f"{s.label:<28} T=2^{k}: skipped: {err}", flush=True)
                continue
            rows.append((s, 2**k, summ, cpu, nc))
            print(f"{s.label:<28} T=2^{k}: " + "  ".join(
                f"{c} {summ[c]['hit']:.2f} (drop {summ[c]['dropped']:.2f}, add "
                f"{summ[c]['added']:.2f}, RRW {summ[c]['rrw_rms']:.2f})" for c in CRITERIA)
                + f"  [{cpu:.2f} s CPU/rep]", flush=True)
    lines = table(rows, args.reps)
    if skipped:
        lines += ["", "Not reachable (skipped): " + "; ".join(skipped) + "."]
    print("\n".join(lines))
    if args.write:
        head = (f"Generated by `python benchmarks/bench_selection.py --reps {args.reps} "
                f"--lengths {' '.join(map(str, args.lengths))} --write` (commit {commit()}, "
                f"{time.perf_counter() - t0:.0f} s wall, 1-minute load "
                f"{os.getloadavg()[0]:.1f} at the end). hit = share of replicates ranking the "
                "generating model first; dropped / added = share whose pick lacks the weak "
                "component / has an extra one; RRW rms err = RMS(K_hat / K - 1) of the "
                "pick's random walk (1 when it has none).\n")
        write_section(head + "\n" + "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
