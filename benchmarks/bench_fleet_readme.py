"""Run the README's fleet example and render its output into README.md's fleet section.

    python benchmarks/bench_fleet_readme.py            # run, print the block, write nothing
    python benchmarks/bench_fleet_readme.py --write    # ... and replace it in README.md

A small synthetic fleet written by ``examples/make_fleet.py`` (8 static units drawn around a
typical value, ``odd0`` out of family, ``aging`` recorded 4 times 60 days apart with its gyroscope
noise density growing by 40 % per year, ``moved`` static for its first 40 % only, one corrupt
file; 3 minutes at 100 Hz each) is calibrated by ``gmwm fleet`` in a fresh temporary folder
(deleted afterwards). Rendered between ``<!-- BEGIN readme_fleet ... -->`` and ``<!-- END
readme_fleet -->``: the commands, what ``gmwm fleet`` printed, the fleet's noise densities
(typical value, between-unit spread, prediction band), the out-of-family units and the drifting
coefficients beside the generator's truth (``truth.json``), the failed recording, the files, and
the wall and CPU time with the machine and load. About a minute of CPU on 2 cores. Only
``--write`` modifies a tracked file, and only README.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

from readme_section import load, machine, run_measured, update_section

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
NAME = "readme_fleet"
MAKE = ["examples/make_fleet.py", "fleet_in", "--units", "8", "--minutes", "3"]
FLEET = ["fleet", "fleet_in", "--model", "WN+RW", "--columns", "all", "--units",
         "gx,gy,gz=rad/s", "--units", "ax,ay,az=m/s^2", "-o", "fleet"]


def _g(x: Any, digits: int = 3) -> str:
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) \
        else f"{x:.{digits}g}"


def _ci(lo: Any, hi: Any) -> str:
    return f"[{_g(lo)}, {_g(hi)}]" if lo is not None and hi is not None else ""


def _table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def _truth(truth: list[dict[str, Any]], recording: str, coefficient: str) -> str:
    """The generator's true value of a noise density, else ''."""
    rec = next((t for t in truth if Path(t["file"]).stem == recording), None)
    if rec is None or not coefficient.endswith("noise_density"):
        return ""
    return _g(rec["gyro_noise_density" if coefficient.startswith("g")
                  else "accel_noise_density"])


def _generator() -> Any:
    """examples/make_fleet.py as a module (its typical values and between-unit spread)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_fleet", ROOT / MAKE[0])
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


def render(tmp: Path, made: dict[str, Any], ran: dict[str, Any]) -> str:
    """The README block from the fleet's files in ``tmp``."""
    fleet = json.loads((tmp / "fleet" / "fleet.json").read_text())
    truth = json.loads((tmp / "fleet_in" / "truth.json").read_text())
    printed = (ran["out"] + ran["err"]).replace(str(tmp) + os.sep, "").replace(str(tmp), ".")
    parts = ["```bash",
             "python " + " ".join(MAKE) + "   # 8 units + odd0, aging (4 dates), moved, corrupt0",
             "gmwm " + " ".join(FLEET), "```", "```text", printed.strip(), "```", ""]
    # the fleet, per coefficient: the ones it could estimate
    coefs = list(fleet["coefficients"].values())
    est = [c for c in coefs if c.get("typical") is not None]
    rows = [[f"`{c['coefficient']}`", c.get("value_unit", ""), str(c["n_units"]),
             f"{_g(c['typical'])} {_ci(*(c.get('typical_ci95') or (None, None)))}",
             f"{_g(c.get('tau_log'))} {_ci(*(c.get('tau_log_ci95') or (None, None)))}",
             _g(c.get("spread_factor")), _ci(*(c.get("prediction95") or (None, None)))]
            for c in est]
    parts += [("**The fleet, per coefficient** (`fleet/fleet.md`, `fleet_summary.csv`): the typical "
              "value with its 95 % interval, tau the between-unit standard deviation of "
              "log(value) with its Q-profile interval (units typically differ by the factor "
              "exp(tau)), and the 95 % prediction interval of a new unit."), "",
              _table(["coefficient", "unit", "units", "typical [95 %]", "tau [95 %]",
                      "factor", "new unit, 95 %"], rows), ""]
    gen = _generator()
    parts += [(f"The generator draws the static units' densities with tau = {gen.SPREAD:g} "
               f"around {gen.GYRO_ND:g} rad/s/sqrt(Hz) and {gen.ACCEL_ND:g} m/s^2/sqrt(Hz); the "
               "fleet's estimate includes every unit, `odd0` and `aging` too (the gyroscope's "
               "tau), while each unit's out-of-family test leaves that unit out."), ""]
    left = [c["coefficient"] for c in coefs if c.get("typical") is None]
    if left:
        parts += [f"Not estimated for the fleet ({len(left)} coefficients: "
                  + ", ".join(f"`{c}`" for c in left[:4]) + (", ..." if len(left) > 4 else "")
                  + "): too few units with a usable estimate; `fleet/fleet.md` gives each "
                  "excluded unit's reason.", ""]
    out = [u for u in fleet["units"] if u["status"] == "out of family"]
    rows = [[u["unit"], f"`{u['coefficient']}`", u["reason"].split(": ", 1)[-1],
             _truth(truth, u["recording"], u["coefficient"])] for u in out]
    parts += [("**Out of family** (the unit's 95 % interval outside the fleet's prediction "
              "interval computed without it), beside the generator's true value:"), "",
              _table(["unit", "coefficient", "why", "true value"], rows), ""]
    for unit in sorted({u["unit"] for u in out if not u["unit"].startswith("odd")}):
        t = next(t for t in truth if t["unit"] == unit)
        z = [math.log(t[k] / ref) / gen.SPREAD for k, ref in
             (("gyro_noise_density", gen.GYRO_ND), ("accel_noise_density", gen.ACCEL_ND))]
        parts += [(f"`{unit}` is not one of the generator's odd units: its true densities lie "
                   f"{z[0]:+.1f} (gyroscope) and {z[1]:+.1f} (accelerometer) between-unit "
                   "standard deviations from the typical values (a tail draw of the "
                   "generator)."), ""]
    moved = [json.loads(p.read_text()) for p in (tmp / "fleet" / "units" / "moved").glob(
        "*/status.json")]
    for st in moved:
        parts += [(f"`moved` (a log that turns after its first 40 %) was calibrated on its "
                   f"{st['used']}: {st['used_s']:.0f} s of {made['minutes'] * 60:.0f} s."), ""]
    drift = [d for d in fleet["drift"] if d["flagged"]]
    rows = [[d["unit"], f"`{d['coefficient']}`", str(d["n"]), f"{d['first']} to {d['last']}",
             (f"{d['percent_per_year'][0]:+.1f} % [{d['percent_per_year'][1]:+.1f}, "
             f"{d['percent_per_year'][2]:+.1f}]")] for d in drift]
    parts += [("**Drift per year** (units recorded on several dates; flagged when the interval "
              "excludes 0; the generator's `aging` unit grows by +40 % per year):"), "",
              _table(["unit", "coefficient", "recordings", "dates", "per year [95 %]"], rows), ""]
    parts += ["**Failed** (listed, never stopping the fleet): "
              + "; ".join(f"`{f['unit']}`: {f['reason'].replace(str(tmp) + os.sep, '')}"
                          for f in fleet["failed"]) + ".", ""]
    parts += [("The page with the plots: `fleet/fleet.html` (each coefficient across units with "
              "intervals, the fleet distribution, the drift lines); each recording's own report "
              "and configuration files: `fleet/units/<unit>/<recording>/`."), ""]
    parts += [(f"*{made['n']} files; `gmwm fleet`: {ran['wall']:.0f} s wall, {ran['cpu']:.0f} s "
              f"CPU (all processes, {os.cpu_count()} cores), load average {ran['load']} before "
              f"the run. {machine()}.*")]
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="replace the block in README.md")
    a = ap.parse_args(argv)
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    with tempfile.TemporaryDirectory(prefix="gmwm-fleet-readme-") as d:
        tmp = Path(d)
        made = run_measured([sys.executable, str(ROOT / MAKE[0]), *MAKE[1:]], env=env, cwd=d)
        if made["code"] != 0:
            sys.exit(f"make_fleet.py failed: {made['err']}")
        made["minutes"] = float(MAKE[MAKE.index("--minutes") + 1])
        made["n"] = sum(1 for p in (tmp / "fleet_in").iterdir() if p.name != "truth.json")
        before = load()
        ran = run_measured([sys.executable, "-m", "gmwm", *FLEET], env=env, cwd=d)
        ran["load"] = before
        if ran["code"] != 0:
            sys.exit(f"gmwm fleet failed ({ran['code']}): {ran['err']}")
        block = render(tmp, made, ran)
    print(block)
    if a.write:
        update_section(NAME, block, README)
        print(f"\nwritten to {README}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
