"""The fleet table's statistics by simulation (gmwm.fleet.core), its time at scale, and the scale
benchmark of ``gmwm fleet`` itself.

    python benchmarks/bench_fleet.py [--reps 2000] [--seed 1] [--table-units 10000] [--json F]
    python benchmarks/bench_fleet.py --reps 0 --units 1000 [--sample 20] [--minutes 1.5]
                                     [--long-minutes 4] [--cores 2] [--workdir DIR]

Coverage. Fleets of ``k`` units drawn from the random-effects model on the log scale:
``y_i = mu + u_i + e_i``, ``u_i ~ N(0, tau^2)``, ``e_i ~ N(0, s_i^2)`` with ``s_i`` uniform on
``[s_lo, s_hi]`` (unequal recording lengths), ``mu = log(1e-4)``. Per design, ``R`` seeded fleets;
reported: the share whose Q-profile 95 % interval covers the true tau^2 (exact under the model:
expected 95 %), of the 95 % interval of mu (Paule-Mandel estimate, modified Hartung-Knapp
interval), and of the 95 % prediction interval for one new unit drawn from the same fleet; each with
its Monte Carlo SE ``sqrt(p (1 - p) / R)``. The designs include tau = 0 (every lower end is 0, the
interval covers whenever Q's upper end does). ``--reps 0`` skips it.

Scale (``--units N``, alias ``--overhead N``, off by default). ``examples/make_fleet.py`` writes a
fleet of ``N`` static six-axis units (``--minutes`` each at 100 Hz; 20 % ROS 1 bags, 20 % HDF5,
the rest CSV), ``max(1, min(3, N // 20))`` units out of family, ``aging`` recorded 6 times (its
gyroscope noise density +40 %/year), ``moved`` (static for its first 40 %; both ``--long-minutes``)
and 3 corrupt files. ``gmwm fleet`` (model WN+RW, ``--cores``; run in the temporary folder, so no
workflow profile of the working directory applies) calibrates it once, timed as a whole: wall
and CPU seconds of the whole process tree (wait4's rusage of every reaped descendant), per
recording; each job's own wall (its status.json), the table job's wall
(Snakemake's log); the peak resident memory of the process tree (psutil: the sum over the tree,
sampled every 0.25 s) and of its largest process (GNU time). A seeded sample of ``--sample`` of the
recordings (corrupt ones included) is calibrated by separate ``gmwm report`` runs with the same
options, one at a time: the overhead is the fleet's CPU per recording over the sample's mean CPU
per report (goal <= 1.2x), with a bootstrap 95 % interval over the sample. Checked (the run fails,
and writes no README block, otherwise): the out-of-family units are flagged, ``aging``'s
gyroscope noise-density drift intervals exclude 0, the corrupt files are listed as failed.

Table. :func:`gmwm.fleet.core.fleet_table` for ``--table-units`` units x 1 coefficient (the
whole-fleet band above 500 units, gmwm.fleet.core.LOO_MAX_UNITS) and for 500 units (leave-one-out
band): CPU seconds.

Only ``--readme`` modifies a tracked file: the generated blocks ``bench_fleet`` (coverage, when
``--reps`` > 0) and ``bench_fleet_scale`` (with ``--units``) of benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import time
from pathlib import Path
from typing import Any

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
    zero = hit_pi_zero = 0  # fleets whose tau^2 estimate is 0, and their prediction hits
    for _ in range(reps):
        s = rng.uniform(s_lo, s_hi, k)
        y = mu + rng.normal(0.0, tau, k) + rng.normal(0.0, s)
        lo, hi = q_profile_tau2(y, s ** 2)
        hit_tau += lo <= tau ** 2 <= hi
        re = random_effects(y, s ** 2, "pm")
        hit_mu += re.ci_mu[0] <= mu <= re.ci_mu[1]
        new = mu + rng.normal(0.0, tau)  # a new unit's true log value
        pi = re.pi
        hit = pi[0] <= new <= pi[1]
        hit_pi += hit
        if re.tau2 <= 0.0:
            zero += 1
            hit_pi_zero += hit
    out: dict[str, float] = {"tau2_zero_share": zero / reps,
                             "prediction_given_zero": hit_pi_zero / zero if zero else math.nan,
                             "prediction_given_positive":
                                 (hit_pi - hit_pi_zero) / (reps - zero) if reps > zero
                                 else math.nan}
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


#: the gmwm report options of every recording of the synthetic fleet (six named axes, SI units)
REPORT_OPTS = ["--columns", "all", "--units", "gx,gy,gz=rad/s", "--units", "ax,ay,az=m/s^2"]
MODEL = "WN+RW"


def run_tree(cmd: list[str], env: dict[str, str], cwd: Path | None = None, every: float = 0.25
             ) -> dict[str, Any]:
    """Run ``cmd`` under GNU time (when /usr/bin/time exists) and return its wall seconds, CPU
    seconds (user + system of the whole process tree: wait4's rusage counts every reaped
    descendant), exit status, stderr, and two peaks of resident memory [MB]: ``tree_rss_mb``,
    the largest sum of RSS over the process and all its descendants alive at once (psutil,
    sampled every ``every`` s: a spike shorter than that can be missed), and
    ``largest_rss_mb``, the largest single process's own peak (GNU time's %M)."""
    import os
    import subprocess
    import tempfile
    import threading

    import psutil

    gnu_time = Path("/usr/bin/time")
    with tempfile.TemporaryFile() as fe, tempfile.NamedTemporaryFile(suffix=".rss") as fr:
        full = [str(gnu_time), "-f", "%M", "-o", fr.name, *cmd] if gnu_time.exists() else cmd
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=fe, env=env, cwd=cwd)
        peak = [0]
        done = threading.Event()

        def sample() -> None:
            try:
                root = psutil.Process(proc.pid)
            except psutil.NoSuchProcess:
                return
            while not done.is_set():
                total = 0
                try:
                    procs = [root, *root.children(recursive=True)]
                except psutil.NoSuchProcess:
                    break
                for q in procs:
                    with contextlib.suppress(psutil.NoSuchProcess, psutil.AccessDenied):
                        total += q.memory_info().rss
                peak[0] = max(peak[0], total)
                done.wait(every)

        th = threading.Thread(target=sample, daemon=True)
        th.start()
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        done.set()
        th.join()
        largest = ru.ru_maxrss / 1024
        with contextlib.suppress(ValueError, IndexError, OSError):
            largest = int(Path(fr.name).read_text().split()[-1]) / 1024
        fe.seek(0)
        return {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime,
                "code": os.waitstatus_to_exitcode(status), "tree_rss_mb": peak[0] / 2**20,
                "largest_rss_mb": largest, "err": fe.read().decode(errors="replace")}


def _table_job_seconds(log: Path) -> float | None:
    """Wall seconds of the fleet_table job, from the time stamps Snakemake writes before a job
    starts and after it finishes (1 s resolution); None when the log does not show both."""
    import datetime as dt
    import re

    stamp = re.compile(r"^\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]$")
    last = start = None
    for line in log.read_text(encoding="utf-8", errors="replace").splitlines():
        m = stamp.match(line.strip())
        if m:
            last = dt.datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif line.startswith(("localrule fleet_table:", "rule fleet_table:")):
            start = last
        elif "(Rule: fleet_table)" in line and start is not None and last is not None:
            return (last - start).total_seconds()
    return None


def _fleet_checks(out: Path, truth: list[dict[str, Any]], corrupt: list[str]
                  ) -> list[tuple[str, bool, str]]:
    """What the fleet table must find in the synthetic fleet: (check, passed, detail)."""
    fleet = json.loads((out / "fleet.json").read_text())
    odd = sorted({t["unit"] for t in truth if str(t["unit"]).startswith("odd")})
    flagged = sorted({u["unit"] for u in fleet["units"] if u["status"] == "out of family"})
    gyro = ("gx.noise_density", "gy.noise_density", "gz.noise_density")
    drift = {d["coefficient"]: d["percent_per_year"] for d in fleet["drift"]
             if d["unit"] == "aging"}
    failed = sorted(f["recording"] for f in fleet["failed"])
    moved = next((u for u in fleet["units"] if u["unit"] == "moved"), None)
    chance = [u for u in flagged if u not in odd]
    return [
        ("out-of-family units found", bool(odd) and set(odd) <= set(flagged),
         (f"{', '.join(odd)} among {len(flagged)} flagged ({len(chance)} others by chance: "
         "a 95 % band)")),
        ("degrading unit's gyroscope noise-density drift per year excludes 0",
         all(c in drift and drift[c][1] > 0 for c in gyro),
         "; ".join(f"{c.split('.')[0]} {drift[c][0]:+.0f} % [{drift[c][1]:+.0f}, "
                   f"{drift[c][2]:+.0f}]" if c in drift else f"{c}: no drift row"
                   for c in gyro) + " (true +40 %)"),
        ("corrupt files listed as failed", set(corrupt) <= set(failed),
         f"{len(failed)} failed: " + ", ".join(failed)),
        ("the moved unit calibrated on its static start", moved is not None,
         "in the table" if moved else "missing"),
    ]


def scale(n_units: int, sample: int, minutes: float, long_minutes: float, cores: int,
          seed: int, workdir: str | None = None) -> dict[str, Any]:
    """The fleet of ``n_units`` by ``gmwm fleet`` timed once as a whole, and ``sample`` of its
    recordings (seeded) by separate ``gmwm report`` runs; the checks of its table."""
    import os
    import subprocess
    import sys
    import tempfile

    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root / "src"),
                                                      env.get("PYTHONPATH")]))
    odd = max(1, min(3, n_units // 20))
    make = ["--units", str(n_units), "--minutes", f"{minutes:g}", "--long-minutes",
            f"{long_minutes:g}", "--bags", "0.2", "--h5", "0.2", "--odd", str(odd),
            "--dated", "6", "--corrupt", "3", "--seed", str(seed)]
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        d = Path(tmp)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, str(root / "examples" / "make_fleet.py"), str(d / "in"),
                        *make], check=True, env=env, capture_output=True)
        make_s = time.perf_counter() - t0
        truth = json.loads((d / "in" / "truth.json").read_text())
        files = sorted(p for p in (d / "in").iterdir() if p.name != "truth.json")
        corrupt = [p.stem for p in files if p.name.startswith("corrupt")]
        formats: dict[str, int] = {}
        for p in files:
            formats[p.suffix] = formats.get(p.suffix, 0) + 1
        # run in the temporary folder, as a user runs it from a folder of their own: from the
        # repository's root, Snakemake would pick up the pipeline's workflow profile
        # (profiles/default: greedy scheduler, a job rate limit), which users do not get
        print(f"fleet: {len(files)} recordings ({', '.join(f'{v} {k}' for k, v in formats.items())}"
              f") written in {make_s:.0f} s; gmwm fleet on {cores} cores ...", flush=True)
        fleet = run_tree([sys.executable, "-m", "gmwm", "fleet", str(d / "in"), "-o",
                          str(d / "fleet"), "--model", MODEL, *REPORT_OPTS, "--cores",
                          str(cores), "-q"], env, cwd=d)
        if fleet["code"] != 0:
            raise SystemExit(f"gmwm fleet failed ({fleet['code']}): {fleet['err'][-2000:]}")
        statuses = [json.loads(p.read_text())
                    for p in sorted((d / "fleet" / "units").glob("*/*/status.json"))]
        job_s = np.array([float(s["seconds"]) for s in statuses])
        checks = _fleet_checks(d / "fleet", truth, corrupt)
        table_s = _table_job_seconds(d / "fleet" / ".fleet" / "snakemake.log")
        # the sample: K recordings drawn without replacement from every input (corrupt ones
        # included: the fleet spends time on them too), seeded
        rng = np.random.default_rng([seed, n_units])
        picked = sorted(rng.choice(len(files), size=min(sample, len(files)), replace=False))
        reps = []
        print(f"gmwm fleet done in {fleet['wall']:.0f} s; {len(picked)} gmwm report runs ...",
              flush=True)
        for i in picked:
            f = files[i]
            got = run_tree([sys.executable, "-m", "gmwm", "report", str(f), MODEL,
                            *REPORT_OPTS, "-o", str(d / "rep" / f.stem), "--segment",
                            "longest-static", "--export", "kalibr,json", "-q"], env, cwd=d)
            if got["code"] not in (0, 3) and not f.name.startswith("corrupt"):
                raise SystemExit(f"gmwm report {f.name} failed ({got['code']}): {got['err']}")
            reps.append({"file": f.name, "cpu_s": got["cpu"], "wall_s": got["wall"],
                         "code": got["code"], "largest_rss_mb": got["largest_rss_mb"]})
    n = len(files)
    cpu = np.array([r["cpu_s"] for r in reps])
    wall = np.array([r["wall_s"] for r in reps])
    per_cpu = float(fleet["cpu"]) / n
    # the ratio's spread: the sample mean's, by a seeded bootstrap over the K reports
    boot = rng.choice(cpu, size=(2000, len(cpu)), replace=True).mean(axis=1)
    return {"units": n_units, "recordings": n, "formats": formats, "odd": odd,
            "minutes": minutes, "long_minutes": long_minutes, "cores": cores, "seed": seed,
            "make_s": make_s, "fleet_wall_s": fleet["wall"], "fleet_cpu_s": fleet["cpu"],
            "fleet_tree_rss_mb": fleet["tree_rss_mb"],
            "fleet_largest_rss_mb": fleet["largest_rss_mb"],
            "per_recording_wall_s": fleet["wall"] / n, "per_recording_cpu_s": per_cpu,
            "job_wall_s": {"median": float(np.median(job_s)),
                           "p90": float(np.percentile(job_s, 90)), "max": float(job_s.max())},
            "table_job_wall_s": table_s,
            "sample": reps, "report_cpu_mean_s": float(cpu.mean()),
            "report_cpu_sd_s": float(cpu.std(ddof=1)) if len(cpu) > 1 else 0.0,
            "report_wall_mean_s": float(wall.mean()),
            "report_largest_rss_mb": max(r["largest_rss_mb"] for r in reps),
            "cpu_ratio": per_cpu / float(cpu.mean()),
            "cpu_ratio_ci95": [per_cpu / float(np.percentile(boot, 97.5)),
                               per_cpu / float(np.percentile(boot, 2.5))],
            "checks": [{"check": c, "passed": ok, "detail": det} for c, ok, det in checks]}


def _markdown(a: argparse.Namespace, rows: list[dict[str, float]], t_big: float,
              t_loo: float, load_before: str, cpu: float, where: str) -> str:
    """The generated coverage block (``bench_fleet``) of benchmarks/README.md."""
    from readme_section import load

    out = [f"`python benchmarks/bench_fleet.py --reps {a.reps} --readme`: " + where
           + f"; 1-minute load average {load_before} before, {load()} after; {cpu:.0f} s CPU "
           "in this process.", "",
           (f"Coverage of nominal 95 % intervals, R = {a.reps} simulated fleets per design (MC SE "
           "in brackets; 95 % +- 2 MC SE is the target):"), "",
           ("| units k | tau | unit SE range | tau^2 (Q-profile) | typical value mu "
           "(PM, mod. HK) | new unit (prediction) | tau^2 estimated 0 | prediction given "
           "tau^2 = 0 / > 0 |"), "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['k']} | {r['tau']:g} | {r['s_lo']:g}-{r['s_hi']:g} | "
                   + " | ".join(f"{r[n]:.3f} ({r[n + '_mcse']:.3f})"
                                for n in ("tau2_qprofile", "mu", "prediction"))
                   + f" | {r['tau2_zero_share']:.3f} | {r['prediction_given_zero']:.3f} / "
                   f"{r['prediction_given_positive']:.3f} |")
    out += ["", (f"`fleet_table` CPU: {a.table_units} units x 1 coefficient {t_big:.2f} s "
            f"(whole-fleet band); 500 units {t_loo:.2f} s (leave-one-out band).")]
    return "\n".join(out)


def _scale_lines(s: dict[str, Any]) -> list[str]:
    """The scale run's numbers, one line each (printed, and the README block's list)."""
    rss = (f"peak resident memory: {s['fleet_tree_rss_mb']:.0f} MB for the whole process tree "
           f"at once (psutil, sampled every 0.25 s), {s['fleet_largest_rss_mb']:.0f} MB for its "
           f"largest process (GNU time); one `gmwm report`'s largest process "
           f"{s['report_largest_rss_mb']:.0f} MB")
    tj = s["job_wall_s"]
    table = ("" if s["table_job_wall_s"] is None else
             f"; the table job (fleet.json/csv/md/html with its figures) "
             f"{s['table_job_wall_s']:.0f} s wall")
    return [
        (f"fleet: {s['units']} static units + {s['odd']} out of family + `aging` (6 dated "
         f"recordings) + `moved` + 3 corrupt files = {s['recordings']} recordings ("
         + ", ".join(f"{v} {k}" for k, v in s["formats"].items())
         + f"); {s['minutes']:g} min at 100 Hz each, `aging` and `moved` {s['long_minutes']:g} "
         f"min; written in {s['make_s']:.0f} s (not counted)"),
        (f"`gmwm fleet` on {s['cores']} cores: {s['fleet_wall_s']:.0f} s wall, "
         f"{s['fleet_cpu_s']:.0f} CPU s (whole process tree); per recording "
         f"{s['per_recording_wall_s']:.2f} s wall, {s['per_recording_cpu_s']:.2f} CPU s; "
         f"one job's own wall (status.json) median {tj['median']:.1f} s, 90th percentile "
         f"{tj['p90']:.1f} s, max {tj['max']:.1f} s" + table),
        (f"`gmwm report` on a seeded sample of {len(s['sample'])} recordings ("
         + ", ".join(r["file"] for r in s["sample"]) + f"), one at a time: "
         f"{s['report_cpu_mean_s']:.2f} CPU s mean (SD {s['report_cpu_sd_s']:.2f}), "
         f"{s['report_wall_mean_s']:.2f} s wall mean"),
        (f"overhead: the fleet's CPU per recording / one report's = {s['cpu_ratio']:.2f}x "
         f"(95 % bootstrap interval over the sample {s['cpu_ratio_ci95'][0]:.2f}-"
         f"{s['cpu_ratio_ci95'][1]:.2f}; goal <= 1.2x)"),
        rss,
    ]


def _scale_markdown(a: argparse.Namespace, s: dict[str, Any], t_big: float,
                    load_before: str, where: str) -> str:
    """The generated scale block (``bench_fleet_scale``) of benchmarks/README.md."""
    from readme_section import load

    out = [(f"`python benchmarks/bench_fleet.py --reps 0 --units {a.overhead} --sample "
            f"{a.sample} --minutes {a.minutes:g} --long-minutes {a.long_minutes:g} --cores "
            f"{a.cores} --readme`: {where}; 1-minute load average {load_before} before, "
            f"{load()} after."), ""]
    out += [f"- {line}" for line in _scale_lines(s)]
    out += [(f"- `fleet_table` alone (the statistics, no files): {a.table_units} units x 1 "
            f"coefficient {t_big:.2f} CPU s"), ""]
    out += ["| check of the fleet table | passed | detail |", "|---|---|---|"]
    out += [f"| {c['check']} | {'yes' if c['passed'] else 'NO'} | {c['detail']} |"
            for c in s["checks"]]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=2000,
                    help="simulated fleets per coverage design (0: no coverage study)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--table-units", type=int, default=10000)
    ap.add_argument("--overhead", "--units", type=int, default=0, metavar="N", dest="overhead",
                    help="also time a synthetic fleet of N units by gmwm fleet, against "
                         "--sample of its recordings by gmwm report")
    ap.add_argument("--sample", type=int, default=20, metavar="K",
                    help="recordings timed by separate gmwm report runs (seeded sample)")
    ap.add_argument("--minutes", type=float, default=1.5,
                    help="length of each unit's recording (the fleet's minimum static "
                         "stretch is 60 s)")
    ap.add_argument("--long-minutes", type=float, default=4.0,
                    help="length of the aging and moved units' recordings")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--workdir", default=None,
                    help="where the temporary fleet goes (default: the system's temp folder)")
    ap.add_argument("--json", default=None, help="also write the numbers to this JSON file")
    ap.add_argument("--readme", action="store_true",
                    help="also rewrite the generated bench_fleet block (coverage, when --reps "
                         "> 0) and bench_fleet_scale block (with --units) of benchmarks/README.md")
    a = ap.parse_args()
    from readme_section import load

    load_before, cpu0 = load(), time.process_time()
    rows = []
    if a.reps > 0:
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
          f"500 units {t_loo:.2f} s (leave-one-out band)", flush=True)
    cpu_here = time.process_time() - cpu0
    sc = None
    if a.overhead:
        sc = scale(a.overhead, a.sample, a.minutes, a.long_minutes, a.cores, a.seed, a.workdir)
        for line in _scale_lines(sc):
            print(line.replace("`", ""))
        for c in sc["checks"]:
            print(f"check: {c['check']}: {'PASS' if c['passed'] else 'FAIL'} ({c['detail']})")
    failed = [c["check"] for c in (sc or {}).get("checks", []) if not c["passed"]]
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"reps": a.reps, "seed": a.seed, "coverage": rows,
                       "table_seconds": {str(a.table_units): t_big, "500": t_loo},
                       "scale": sc, "load_before": load_before, "load_after": load()},
                      fh, indent=2)
    if failed:
        raise SystemExit(f"the fleet table missed: {'; '.join(failed)} (README not written)")
    if a.readme:
        from readme_section import machine, update_section

        if rows:
            update_section("bench_fleet", _markdown(a, rows, t_big, t_loo, load_before,
                                                    cpu_here, machine()))
        if sc is not None:
            update_section("bench_fleet_scale",
                           _scale_markdown(a, sc, t_big, load_before, machine()))


if __name__ == "__main__":
    main()
