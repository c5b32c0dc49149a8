"""The fleet table's statistics by simulation (gmwm.fleet.core), and its time at scale.

    python benchmarks/bench_fleet.py [--reps 2000] [--seed 1] [--table-units 10000] [--json F]
    python benchmarks/bench_fleet.py --units 1000 [--minutes 5] [--cores 2]   # + the overhead

Coverage. Fleets of ``k`` units drawn from the random-effects model on the log scale:
``y_i = mu + u_i + e_i``, ``u_i ~ N(0, tau^2)``, ``e_i ~ N(0, s_i^2)`` with ``s_i`` uniform on
``[s_lo, s_hi]`` (unequal recording lengths), ``mu = log(1e-4)``. Per design, ``R`` seeded fleets;
reported: the share whose Q-profile 95 % interval covers the true tau^2 (exact under the model:
expected 95 %), of the 95 % interval of mu (Paule-Mandel estimate, modified Hartung-Knapp
interval), and of the 95 % prediction interval for one new unit drawn from the same fleet; each with
its Monte Carlo SE ``sqrt(p (1 - p) / R)``. The designs include tau = 0 (every lower end is 0, the
interval covers whenever Q's upper end does).

Overhead (``--units N``, alias ``--overhead N``, off by default): a synthetic fleet of ``N`` static units written by
``examples/make_fleet.py`` (``--minutes`` each, CSV, six axes), calibrated once by ``gmwm fleet``
(model WN+RW, ``--cores``) and once by ``N`` separate ``gmwm report`` runs with the same options;
reported: CPU seconds (user + system of every child process) and wall time of each, and their
ratio per recording (the fleet's includes Snakemake and the table job), and the peak resident
memory of the largest single process of each (GNU time, when /usr/bin/time exists).

Scale. :func:`gmwm.fleet.core.fleet_table` for ``--table-units`` units x 1 coefficient (the
whole-fleet band above 500 units, gmwm.fleet.core.LOO_MAX_UNITS) and for 500 units (leave-one-out
band): CPU seconds.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from gmwm.fleet.core import Estimate, fleet_table, q_profile_tau2, random_effects

DESIGNS = [  # (k units, tau, s_lo, s_hi)
    (5, 0.3, 0.02, 0.2),
    (10, 0.3, 0.02, 0.2),
    (30, 0.3, 0.02, 0.2),
    (10, 0.05, 0.02, 0.2),
    (10, 0.0, 0.02, 0.2),
    (100, 0.2, 0.01, 0.1),
]


def coverage(k: int, tau: float, s_lo: float, s_hi: float, reps: int, seed: int
             ) -> dict[str, float]:
    rng = np.random.default_rng([seed, k, int(tau * 1000)])
    mu = math.log(1e-4)
    hit_tau = hit_mu = hit_pi = 0
    for _ in range(reps):
        s = rng.uniform(s_lo, s_hi, k)
        y = mu + rng.normal(0.0, tau, k) + rng.normal(0.0, s)
        lo, hi = q_profile_tau2(y, s ** 2)
        hit_tau += lo <= tau ** 2 <= hi
        re = random_effects(y, s ** 2, "pm")
        hit_mu += re.ci_mu[0] <= mu <= re.ci_mu[1]
        new = mu + rng.normal(0.0, tau)  # a new unit's true log value
        pi = re.pi
        hit_pi += pi[0] <= new <= pi[1]
    out = {}
    for name, h in (("tau2_qprofile", hit_tau), ("mu", hit_mu), ("prediction", hit_pi)):
        p = h / reps
        out[name] = p
        out[name + "_mcse"] = math.sqrt(p * (1 - p) / reps)
    return out


def table_time(n_units: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    vals = 1e-4 * np.exp(rng.normal(0, 0.2, n_units))
    ests = [Estimate(f"u{i}", "r", "gx.noise_density", float(v), (v / 1.1, v * 1.1))
            for i, v in enumerate(vals)]
    t0 = time.process_time()
    fleet_table(ests)
    return time.process_time() - t0


def overhead(n_units: int, minutes: float, cores: int) -> dict[str, float]:
    import os
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from readme_section import run_measured

    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join([str(root / "src"), env.get("PYTHONPATH", "")])
    opts = ["WN+RW", "--columns", "all", "--units", "gx,gy,gz=rad/s", "--units",
            "ax,ay,az=m/s^2"]

    def run(cmd: list[str]) -> dict[str, object]:
        got = run_measured(cmd, env=env)
        if got["code"] != 0:
            raise SystemExit(f"{' '.join(cmd[:4])} ... failed ({got['code']}): {got['err']}")
        return got

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        subprocess.run([sys.executable, str(root / "examples" / "make_fleet.py"), str(d / "in"),
                        "--units", str(n_units), "--minutes", str(minutes), "--odd", "0",
                        "--dated", "0", "--corrupt", "0"], check=True, env=env,
                       capture_output=True)
        (d / "in" / "moved_2026-01-05.csv").unlink()
        files = sorted((d / "in").glob("*.csv"))
        # CPU of the whole process tree; peak RSS: the largest single process of it
        fleet = run([sys.executable, "-m", "gmwm", "fleet", str(d / "in"), "-o",
                     str(d / "fleet"), "--model", *opts, "--cores", str(cores), "-q"])
        rep_cpu = rep_wall = rep_rss = 0.0
        for f in files:
            got = run([sys.executable, "-m", "gmwm", "report", str(f), *opts, "-o",
                       str(d / "rep" / f.stem), "--segment", "longest-static",
                       "--export", "kalibr,json", "-q"])
            rep_cpu += float(got["cpu"])  # type: ignore[arg-type]
            rep_wall += float(got["wall"])  # type: ignore[arg-type]
            rep_rss = max(rep_rss, float(got["rss_mb"]))  # type: ignore[arg-type]
    n = len(files)
    fleet_cpu = float(fleet["cpu"])  # type: ignore[arg-type]
    return {"recordings": n, "fleet_cpu_s": fleet_cpu,
            "fleet_wall_s": float(fleet["wall"]),  # type: ignore[arg-type]
            "fleet_peak_rss_mb": float(fleet["rss_mb"]),  # type: ignore[arg-type]
            "reports_cpu_s": rep_cpu, "reports_wall_s": rep_wall,
            "reports_peak_rss_mb": rep_rss, "cpu_ratio": fleet_cpu / rep_cpu}


def _markdown(a: argparse.Namespace, rows: list[dict[str, float]], t_big: float,
              t_loo: float, over: dict[str, float] | None, load_before: str, cpu: float,
              where: str) -> str:
    """The generated block of benchmarks/README.md."""
    from readme_section import load

    out = [f"`python benchmarks/bench_fleet.py --reps {a.reps}"
           + (f" --units {a.overhead} --minutes {a.minutes:g} --cores {a.cores}"
              if a.overhead else "") + " --readme`: " + where + f"; 1-minute load average "
           f"{load_before} before, {load()} after; {cpu:.0f} s CPU in this process"
           + (" (plus the fleet's and the reports' child processes)" if a.overhead else "")
           + ".", "",
           (f"Coverage of nominal 95 % intervals, R = {a.reps} simulated fleets per design (MC SE "
           "in brackets; 95 % +- 2 MC SE is the target):"), "",
           ("| units k | tau | unit SE range | tau^2 (Q-profile) | typical value mu "
           "(PM, mod. HK) | new unit (prediction) |"), "|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['k']} | {r['tau']:g} | {r['s_lo']:g}-{r['s_hi']:g} | "
                   + " | ".join(f"{r[n]:.3f} ({r[n + '_mcse']:.3f})"
                                for n in ("tau2_qprofile", "mu", "prediction")) + " |")
    out += ["", (f"`fleet_table` CPU: {a.table_units} units x 1 coefficient {t_big:.2f} s "
            f"(whole-fleet band); 500 units {t_loo:.2f} s (leave-one-out band).")]
    if over:
        out += ["", (f"Overhead: {over['recordings']:.0f} recordings; `gmwm fleet` "
                f"{over['fleet_cpu_s']:.1f} CPU s ({over['fleet_wall_s']:.1f} s wall, "
                f"{a.cores} cores) against {over['recordings']:.0f} `gmwm report` runs "
                f"{over['reports_cpu_s']:.1f} CPU s ({over['reports_wall_s']:.1f} s wall, "
                f"serial): {over['cpu_ratio']:.2f}x the CPU per recording. Peak resident "
                f"memory of the largest process: {over['fleet_peak_rss_mb']:.0f} MB in the "
                f"fleet, {over['reports_peak_rss_mb']:.0f} MB in a report.")]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--table-units", type=int, default=10000)
    ap.add_argument("--overhead", "--units", type=int, default=0, metavar="N", dest="overhead",
                    help="also time a fleet of N units against N gmwm report runs")
    ap.add_argument("--minutes", type=float, default=5.0)
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--json", default=None, help="also write the numbers to this JSON file")
    ap.add_argument("--readme", action="store_true",
                    help="also rewrite the generated bench_fleet block of benchmarks/README.md")
    a = ap.parse_args()
    from readme_section import load

    load_before, cpu0 = load(), time.process_time()
    rows = []
    print(f"coverage of nominal 95 % intervals, R = {a.reps} fleets per design (MC SE)")
    print(f"{'k':>4} {'tau':>5} {'s range':>12} {'tau2 Q-prof':>14} {'mu (mod. HK)':>14} "
          f"{'prediction':>14}")
    for k, tau, lo, hi in DESIGNS:
        c = coverage(k, tau, lo, hi, a.reps, a.seed)
        rows.append({"k": k, "tau": tau, "s_lo": lo, "s_hi": hi, **c})
        print(f"{k:4d} {tau:5.2f} {lo:5.2f}-{hi:<5.2f} "
              + " ".join(f"{c[n]:7.3f} ({c[n + '_mcse']:.3f})"
                         for n in ("tau2_qprofile", "mu", "prediction")))
    t_big = table_time(a.table_units, a.seed)
    t_loo = table_time(500, a.seed)
    print(f"fleet_table CPU: {a.table_units} units {t_big:.2f} s (whole-fleet band); "
          f"500 units {t_loo:.2f} s (leave-one-out band)")
    over = None
    if a.overhead:
        over = overhead(a.overhead, a.minutes, a.cores)
        print(f"overhead: {over['recordings']} recordings, gmwm fleet {over['fleet_cpu_s']:.1f} "
              f"CPU s ({over['fleet_wall_s']:.1f} s wall, {a.cores} cores) vs gmwm report "
              f"{over['reports_cpu_s']:.1f} CPU s ({over['reports_wall_s']:.1f} s wall, serial):"
              f" {over['cpu_ratio']:.2f}x CPU per recording; peak RSS "
              f"{over['fleet_peak_rss_mb']:.0f} MB (fleet) vs {over['reports_peak_rss_mb']:.0f} "
              "MB (report)")
    if a.readme:
        from readme_section import machine, update_section

        update_section("bench_fleet", _markdown(a, rows, t_big, t_loo, over, load_before,
                                                time.process_time() - cpu0, machine()))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"reps": a.reps, "seed": a.seed, "coverage": rows,
                       "table_seconds": {str(a.table_units): t_big, "500": t_loo},
                       "overhead": over}, fh, indent=2)


if __name__ == "__main__":
    main()
