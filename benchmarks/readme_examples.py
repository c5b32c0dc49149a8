"""Run the README's example commands and render their outputs and times into README.md.

Each example below is a list of shell steps run with ``bash`` in one fresh temporary directory
(deleted afterwards; ``$repo`` is the repository root, ``gmwm`` the command of this interpreter).
The rendered Markdown (the commands, their stdout/stderr, the files they wrote, wall and CPU
times with the machine, load average and commit) goes between ``<!-- BEGIN readme_NAME ... -->``
and ``<!-- END readme_NAME -->`` in README.md (``readme_section.update_section``)::

    python benchmarks/readme_examples.py                 # run, print the blocks, write nothing
    python benchmarks/readme_examples.py --write         # ... and replace them in README.md
    python benchmarks/readme_examples.py --check         # which README blocks differ from a rerun
    python benchmarks/readme_examples.py --only plan --write

``--check`` compares with the timing lines and the printed durations masked, so it flags changed
results, not a slower machine; it exits 1 when a block differs. Only ``--write`` modifies a
tracked file, and only README.md.
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from readme_section import load, run_measured, update_section

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PREFIX = "readme_"  # marker names: <!-- BEGIN readme_quickstart (generated ...) -->
COMPILING = "compiling numerical kernels"  # gmwm's note when Numba's cache is cold


@dataclass
class Step:
    """One shell step: ``cmd`` is shown in the example's bash block (``show``) and run (``run``);
    ``output`` chooses what of it is rendered: 'both' (stdout, then stderr), 'stdout', 'files'
    (the command's stdout as a list of file names) or None; ``timed`` adds its wall and CPU time
    to the example's timing line under ``label``."""

    cmd: str
    show: bool = True
    run: bool = True
    output: str | None = "both"
    caption: str = ""
    lang: str = ""
    details: str = ""  # a summary: render the output inside a collapsed <details> element
    timed: bool = False
    label: str = ""


@dataclass
class Example:
    name: str
    steps: list[Step]
    requires: str = ""  # a flag of `gmwm report --help`; without it the example is skipped
    markdown: Callable[[], str] | None = None  # a block rendered from the library, no commands
    results: list[dict] = field(default_factory=list)


SIX_AXIS_CSV = """python - <<'PY'
import numpy as np, gmwm
from gmwm import units as u
fs, n = 200.0, 2**19                     # 200 Hz, 44 min
gyro = gmwm.Model("WN+GM+RW", freq=fs)   # signal in deg/s
accel = gmwm.Model("WN+RW", freq=fs)     # signal in m/s^2
tg = gyro.theta({"WN[1].sigma2": u.wn_from_arw_per_sqrt_hour(0.15, fs),   # ARW 0.15 deg/sqrt(h)
                 "GM[1].beta": 0.1, "GM[1].sigma2": (7.2 / 3600) ** 2,    # 10 s, 7.2 deg/h
                 "RW[1].gamma2": u.rw_from_per_hour_sqrt_hour(10, fs)})   # RRW 10 deg/h/sqrt(h)
ta = accel.theta({"WN[1].sigma2": u.wn_from_arw_per_sqrt_hour(0.05, fs),  # VRW 0.05 m/s/sqrt(h)
                  "RW[1].gamma2": u.rw_from_per_hour_sqrt_hour(10, fs)})  # AccRW 10 m/s/h/sqrt(h)
rng = np.random.default_rng(2026)
cols = {"time": np.arange(n) / fs}
cols |= {c: gyro.simulate(tg, n, rng) for c in ("gx", "gy", "gz")}
cols |= {c: accel.simulate(ta, n, rng) for c in ("ax", "ay", "az")}
np.savetxt("imu.csv", np.column_stack(list(cols.values())), delimiter=",", fmt="%.9g",
           header=",".join(cols), comments="")
PY"""

SCRATCH = Step('repo=$PWD; cd "$(mktemp -d)"       # a scratch directory: nothing lands in the '
               'checkout', run=False, output=None)
MAKE_BAG = Step('python "$repo/examples/make_imu_bag.py" imu.bag   # 1 h of a static IMU at '
                '200 Hz, known noise', timed=True, label="make_imu_bag.py")
YAML_VALUES = Step("grep -v '^#' calib/imu.yaml | grep .", show=False, lang="yaml",
                   output="stdout", caption="The values of `calib/imu.yaml` (SI units, "
                   "continuous time), without its comment lines:")

EXAMPLES = [
    Example("quickstart", [
        SCRATCH, MAKE_BAG,
        Step("gmwm report imu.bag -o calib/", timed=True, label="gmwm report"),
        Step("ls calib/", show=False, output="files", caption="Files written to `calib/`:"),
        YAML_VALUES,
        Step("cat calib/imu.yaml", show=False, output="stdout", lang="yaml",
             details="The whole <code>calib/imu.yaml</code>: where each value comes from, its "
                     "interval, every axis, the warnings"),
    ]),
    Example("exports", [
        SCRATCH, MAKE_BAG,
        Step("gmwm report imu.bag -o calib/ --export openvins,vins-fusion", timed=True,
             label="gmwm report --export", output="stdout"),
        Step("ls calib/", show=False, output="files", caption="Files written to `calib/`:"),
        Step("grep -v '^#' calib/vins_fusion_imu.yaml | grep .", show=False, lang="yaml",
             output="stdout", caption="The values of `calib/vins_fusion_imu.yaml`, without its "
             "comment lines:"),
    ], requires="--export"),
    Example("targets", [], markdown=lambda: targets_table()),
    Example("plan", [
        Step("gmwm plan --datasheet mti-1 --sensor gyroscope --freq 100 --target BI=10%",
             timed=True, label="gmwm plan"),
    ]),
    Example("worked", [
        Step('gmwm simulate "WN+RW+AR1+SIN" -p "WN[1].sigma2=1" -p "RW[1].gamma2=4e-4" \\\n'
             '     -p "AR1[1].phi=0.975" -p "AR1[1].sigma2=0.03" -p "SIN[1].alpha=0.85" '
             '-p "SIN[1].beta=0.35" \\\n     -n 1000000 --seed 1 -o x.npy', timed=True,
             label="gmwm simulate"),
        Step('gmwm fit x.npy "WN+RW+AR1+SIN" --plot example_fit.png', timed=True,
             label="gmwm fit (plot included)"),
    ]),
    Example("six_axis", [
        Step(SIX_AXIS_CSV, output=None),
        Step('gmwm fit imu.csv "gx=WN+GM+RW,ax=WN+RW" --columns gx,ax --units gx=deg/s '
             '--units ax=m/s^2', timed=True, label="gmwm fit"),
        Step("gmwm av imu.csv --columns gx,gy,gz --units deg/s --adev --plot adev.png "
             "| tail -11", timed=True, label="gmwm av"),
        Step('gmwm report imu.csv "gx=WN+GM+RW,gy=WN+GM+RW,gz=WN+GM+RW,WN+RW" --columns all '
             '\\\n     --units gx,gy,gz=deg/s --units ax,ay,az=m/s^2 -o imu_report',
             timed=True, label="gmwm report", output="stdout"),
    ]),
]

def targets_table() -> str:
    """The export targets of ``gmwm.exports.TARGETS`` as a Markdown table."""
    from gmwm.exports import TARGETS

    rows = [f"| `{t.name}` | `{t.filename}` | {t.description} |" for t in TARGETS.values()]
    return "\n".join(["| target | file | what |", "|---|---|---|", *rows])


# masked by --check: the timing line and the durations a command prints
_TIMING_LINE = re.compile(r"^\*Measured .*$", re.MULTILINE)
_DURATION = re.compile(r"\b(WV|fit) \d+(\.\d+)? s\b|(\[)\d+(\.\d+)? s\]")


def normalise(markdown: str) -> str:
    """``markdown`` without what depends on the machine's speed or the run's date."""
    masked = _TIMING_LINE.sub("*Measured ...*", markdown)
    return _DURATION.sub(lambda m: f"{m.group(1)} <t> s" if m.group(1) else "[<t> s]",
                         masked).strip()


def commit() -> str:
    """The short commit, with '-dirty' when a tracked file other than README.md is modified."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                                cwd=ROOT, check=True, capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    dirty = [ln for ln in status.splitlines() if ln[3:].strip() != README.name]
    return head + ("-dirty" if dirty else "")


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine()


def supports(flag: str) -> bool:
    """True if ``gmwm report --help`` lists ``flag``."""
    out = subprocess.run([sys.executable, "-m", "gmwm", "report", "--help"],
                         capture_output=True, text=True, env=_env(), check=False).stdout
    return flag in out


def _env() -> dict[str, str]:
    env = dict(os.environ, repo=str(ROOT), MPLBACKEND="Agg")
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env.pop("COLUMNS", None)
    return env


def run_example(ex: Example, workdir: Path, repeat: int = 1) -> None:
    """Run the steps of ``ex`` in ``workdir``; their results go to ``ex.results``. A step whose
    stderr says the numerical kernels were compiled (cold Numba cache) is run again and the
    second run kept: the README shows the times of an installed package. A timed step is run
    ``repeat`` times and its fastest run kept."""
    ex.results = []
    for step in ex.steps:
        if not step.run:
            ex.results.append({})
            continue
        cmd = ["bash", "-o", "pipefail", "-c", step.cmd]
        res = run_measured(cmd, env=_env(), cwd=str(workdir))
        if COMPILING in res["err"]:
            res = run_measured(cmd, env=_env(), cwd=str(workdir))
        for _ in range(repeat - 1 if step.timed else 0):  # keep the fastest run
            again = run_measured(cmd, env=_env(), cwd=str(workdir))
            res = again if again["code"] == 0 and again["wall"] < res["wall"] else res
        if res["code"] != 0:
            sys.exit(f"readme_examples.py: {ex.name}: exit {res['code']} from\n{step.cmd}\n"
                     f"{res['err'][-2000:]}")
        ex.results.append(res)


def _fence(text: str, lang: str = "") -> str:
    return f"```{lang}\n{text.rstrip()}\n```"


def render(ex: Example, load_before: str, repeat: int = 1) -> str:
    """The Markdown block of ``ex`` from its results."""
    shown = [s.cmd for s in ex.steps if s.show]
    parts = [_fence("\n".join(shown), "bash")] if shown else []
    timings = []
    for step, res in zip(ex.steps, ex.results):
        if not res:
            continue
        if step.timed:
            timings.append(f"`{step.label}` {res['wall']:.1f} s wall, {res['cpu']:.1f} s CPU, "
                           f"peak {res['rss_mb']:.0f} MB")
        if step.output is None:
            continue
        if step.output == "files":
            names = res["out"].split()
            parts.append(f"{step.caption} " + ", ".join(f"`{n}`" for n in names) + ".")
            continue
        text = res["out"].rstrip("\n")
        if step.output == "both" and res["err"].strip():
            text = (text + "\n" if text else "") + res["err"].rstrip("\n")
        first = step.cmd.splitlines()[0]
        if step.details:
            parts.append(f"<details><summary>{step.details}</summary>\n\n"
                         f"{_fence(text, step.lang)}\n\n</details>")
            continue
        what = " (stdout, then stderr):" if step.output == "both" else ":"
        alone = sum(1 for s in ex.steps if s.show and s.output) == 1
        short = first.split("  #")[0].rstrip(" \\")
        if "\n" in step.cmd.strip():
            short = " ".join(short.split()[:2]) + " ..."
        caption = step.caption or ("Output" + what if alone else f"`{short}` prints" + what)
        parts.append(f"{caption}\n\n{_fence(text, step.lang)}")
    if not timings:
        return "\n\n".join(parts)
    best = f", fastest of {repeat}" if repeat > 1 else ""
    parts.append(f"*Measured by `python benchmarks/readme_examples.py --write`{best}: "
                 + "; ".join(timings) + f". {cpu_name()}, {os.cpu_count()} cores, Python "
                 f"{sys.version.split()[0]}, commit {commit()}, "
                 f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
                 f"; load average {load_before} before, {load()} after.*")
    return "\n\n".join(parts)


def readme_blocks(text: str) -> dict[str, str]:
    """Generated blocks of a README text: name -> content between its markers."""
    pat = re.compile(r"<!-- BEGIN (\S+) \(generated by the benchmark, do not edit\) -->\n"
                     r"(.*?)\n<!-- END \1 -->", re.DOTALL)
    return {m.group(1): m.group(2) for m in pat.finditer(text)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--write", action="store_true", help="replace the blocks in README.md")
    mode.add_argument("--check", action="store_true",
                      help="report the README blocks that differ from a rerun (exit 1 if any)")
    p.add_argument("--only", action="append", choices=[e.name for e in EXAMPLES],
                   help="run only this example (repeatable)")
    p.add_argument("--repeat", type=int, default=1,
                   help="run each timed command this many times, keep the fastest (default: 1)")
    p.add_argument("--readme", type=Path, default=README, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    examples = [e for e in EXAMPLES if not args.only or e.name in args.only]
    current = readme_blocks(args.readme.read_text())
    differ = []
    for ex in examples:
        if ex.requires and not supports(ex.requires):
            print(f"[{ex.name}] skipped: `gmwm report` has no {ex.requires}", file=sys.stderr)
            continue
        if ex.markdown is not None:
            block = ex.markdown()
        else:
            before = load()
            with tempfile.TemporaryDirectory(prefix=f"gmwm_readme_{ex.name}_") as d:
                run_example(ex, Path(d), args.repeat)
            block = render(ex, before, args.repeat)
        name = PREFIX + ex.name
        if args.check:
            old = current.get(name)
            if old is None or normalise(old) != normalise(block):
                differ.append(name)
                print(f"[{name}] differs from README.md" if old is not None
                      else f"[{name}] is not in README.md")
                if old is not None:
                    sys.stdout.writelines(difflib.unified_diff(
                        normalise(old).splitlines(True), normalise(block).splitlines(True),
                        "README.md", "rerun", n=1))
            else:
                print(f"[{name}] same as README.md (timings aside)")
        else:
            print(f"<!-- {name} -->\n{block}\n")
            if args.write:
                update_section(name, block, readme=args.readme)
                print(f"[{name}] written to {args.readme}", file=sys.stderr)
    return 1 if differ else 0


if __name__ == "__main__":
    shutil.which("bash") or sys.exit("readme_examples.py needs bash")
    sys.exit(main())
