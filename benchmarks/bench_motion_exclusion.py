"""Motion exclusion study: does leaving out a flagged knock change the coefficients, and how often
is a static recording cut or refused for nothing?

    python benchmarks/bench_motion_exclusion.py [--reps 200] [--seconds 600] [--write]

Design. ``--reps`` static six-axis recordings at 100 Hz (the four IMU profiles of
``bench_stationarity.PROFILES`` in turn, each axis fitted with its own generating model), and the
same recordings with one 2-s tilt of 20 degrees at a random time (``inject_tilt``: gyro x sees
the rate, accelerometers y and z the rotated gravity). Both go through
:func:`gmwm.calibrate.calibrate` with its defaults (motion up to 5 % of the samples, padded by
1 s, left out and the clean parts pooled). Reported:

* per profile, axis and filter coefficient (the white-noise density N and random walk K the
  configuration file carries, SI), the exclusion's bias: the mean of the values with the knock
  left out against the mean of the same static recordings' values, relative (mean(knocked) /
  mean(static) - 1), with its Monte Carlo SE from the paired differences; beside it the median
  of the per-recording relative changes (their spread: what one recording can move) and the
  static value's own 95 % interval half-width (relative). A bias within 2 MC SE of 0: none seen.
  (The mean of the per-recording ratios is not a bias measure: two noisy values of the same
  mean have a ratio whose mean exceeds 1 by about their relative variance, +5 % at a 30 %
  spread.); and both means against the generating value (a flagged term's upper bound sits
  above it by design): whether leaving the knock out moves the estimate away from the truth or
  only by the information the left-out stretch and the cut take away;
* the share of knocked recordings whose knock was left out (the rest refused: the padded
  flagged range exceeded 5 %);
* false exclusions: the share of the *static* recordings that had a range left out or were
  refused (target <= 1 %).

``--write`` replaces this benchmark's section of ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_selection as sel
import bench_stationarity as bs

FS = 100.0


def _npz(path: Path, x: dict[str, np.ndarray]) -> Path:
    n = x["gx"].size
    np.savez(path, t_s=np.arange(n) / FS, **x)
    return path


TERMS = ("noise_density", "random_walk")


def _run(path: Path, models: dict[str, str]) -> tuple[dict[str, dict[str, tuple]], str]:
    """Per axis and filter term: (value written, 95 % CI) of the configuration; and whether the
    recording was kept whole, had a range excluded, or was refused."""
    from gmwm.calibrate import calibrate
    from gmwm.exports import noise_export

    res = calibrate(str(path), models, columns="all", units=dict(bs.UNITS), workers=1)
    sec = res.only()
    exp = noise_export({c: (a.units, a.result) for c, a in sec.axes.items()})
    out = {c: {t: (ax.term(t).value, ax.term(t).ci95, ax.term(t).flag is not None) for t in TERMS}
           for c, ax in exp.axes.items()}
    v = sec.verdict
    state = ("refused" if not v.written else
             "excluded" if any(c.startswith("motion excluded") for c in v.caveats) else "kept")
    return out, state


def replicate(args: tuple[int, float, int]) -> dict:
    r, seconds, seed = args
    profile = r % len(bs.PROFILES)
    rng = np.random.default_rng([seed, r])
    _, gp, ap = bs.PROFILES[profile]
    static = bs.static_imu(profile, FS, seconds, rng)
    knock = {c: v.copy() for c, v in static.items()}
    t0 = float(rng.uniform(0.1 * seconds, 0.9 * seconds))
    bs.inject_tilt(knock, FS, t0, 2.0, 20.0)
    models = {c: (gp if c[0] == "g" else ap).spec for c in bs.AXES}
    with tempfile.TemporaryDirectory() as d:
        s_fit, s_state = _run(_npz(Path(d) / "s.npz", static), models)
        k_fit, k_state = _run(_npz(Path(d) / "k.npz", knock), models)
    pair, half, flags = {}, {}, {}
    for c in bs.AXES:
        for t in TERMS:
            (vs, ci, fs), (vk, _, fk) = s_fit[c][t], k_fit[c][t]
            flags[(c, t)] = (fs, fk)
            ok = vs is not None and vk is not None and vs > 0
            pair[(c, t)] = (vs, vk) if ok else (np.nan, np.nan)
            half[(c, t)] = (ci[1] - ci[0]) / 2 / vs if ok and ci is not None else np.nan
    return {"profile": profile, "static": s_state, "knock": k_state, "pair": pair, "half": half,
            "flags": flags}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2041)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    t0, cpu0 = time.perf_counter(), time.process_time()
    work = [(r, args.seconds, args.seed) for r in range(args.reps)]
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            reps = list(pool.map(replicate, work))
    else:
        reps = [replicate(w) for w in work]
    lines = [("| profile | axis | term | knock left out | bias of the mean (relative) | MC SE | "
              "median relative change | static 95 % CI half-width (relative) | "
              "static: mean / truth - 1 (MC SE) | knock left out: mean / truth - 1 (MC SE) | "
              "flagged (upper bound written): static / knock left out |"),
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    worst, worst_free = 0.0, 0.0
    for p, (name, gp, ap_) in enumerate(bs.PROFILES):
        mine = [x for x in reps if x["profile"] == p and x["knock"] == "excluded"]
        n_p = sum(x["profile"] == p for x in reps)
        for c in ("gx", "ay"):  # the axes the tilt touches (gyro x, accelerometer y)
            for t in TERMS:
                v = np.array([x["pair"][(c, t)] for x in mine], float).reshape(-1, 2)
                v = v[np.all(np.isfinite(v), axis=1)]
                h = np.array([x["half"][(c, t)] for x in mine], float)
                if len(v) < 2:
                    continue
                base, d = float(np.mean(v[:, 0])), v[:, 1] - v[:, 0]
                m = float(np.mean(d)) / base
                se = float(np.std(d, ddof=1) / math.sqrt(len(d))) / base
                worst = max(worst, abs(m) / se if se > 0 else 0.0)
                if not any(any(x["flags"][(c, t)]) for x in mine):
                    worst_free = max(worst_free, abs(m) / se if se > 0 else 0.0)
                med = float(np.median(v[:, 1] / v[:, 0] - 1.0))
                prof = gp if c[0] == "g" else ap_
                truth = prof.nd if t == "noise_density" else prof.k
                vs_truth = " | ".join(
                    f"{np.mean(col) / truth - 1:+.4f} ({np.std(col, ddof=1) / np.sqrt(len(col)) / truth:.4f})"
                    for col in (v[:, 0], v[:, 1]))
                lines.append(f"| {name} | {c} | {t} | {len(mine)} / {n_p} | {m:+.4f} | "
                             f"{se:.4f} | {med:+.4f} | {float(np.nanmedian(h)):.3f} | {vs_truth} | "
                             f"{sum(x['flags'][(c, t)][0] for x in mine)} / "
                             f"{sum(x['flags'][(c, t)][1] for x in mine)} |")
    false = [x for x in reps if x["static"] != "kept"]
    lines += ["", (f"Largest |bias| / MC SE over the rows: {worst:.2f}; over the rows where no "
              f"value is flagged (estimates, not upper bounds): {worst_free:.2f}. False exclusions: "
              f"{len(false)} of {len(reps)} static recordings cut or refused "
              f"({100 * len(false) / max(len(reps), 1):.2g} %; "
              f"{sum(x['static'] == 'excluded' for x in false)} cut, "
              f"{sum(x['static'] == 'refused' for x in false)} refused). Knocks left out: "
              f"{sum(x['knock'] == 'excluded' for x in reps)} of {len(reps)}; refused: "
              f"{sum(x['knock'] == 'refused' for x in reps)}.")]
    print("\n".join(lines))
    if args.write:
        head = (f"Generated by `python benchmarks/bench_motion_exclusion.py --reps {args.reps} "
                f"--seconds {args.seconds:g} --jobs {args.jobs} --write` (commit {sel.commit()}, "
                f"{time.perf_counter() - t0:.0f} s wall, {time.process_time() - cpu0:.0f} s CPU "
                f"in the main process, 1-minute load {os.getloadavg()[0]:.1f} at the end). Each "
                "row: the knocked recordings whose knock was left out; the change of the value "
                "the configuration carries (its 95 % upper bound for a flagged term) against the "
                "same recording without the knock, beside that value's own precision.\n")
        sel.write_section(head + "\n" + "\n".join(lines), "bench_motion_exclusion")


if __name__ == "__main__":
    sys.exit(main())
