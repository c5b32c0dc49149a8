"""`gmwm fleet` end to end (Snakemake runs: marked `pipeline`): a small fleet of CSV recordings
and a ROS 1 bag with one corrupt file, the incremental rerun, kill and resume, the SLURM profile's plan, and the
static-stretch rule of one recording (gmwm.fleet.run.calibrate_recording)."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("statsmodels")
pytest.importorskip("snakemake")

pytestmark = pytest.mark.pipeline

ROOT = Path(__file__).resolve().parents[1]
OPTS = ["--model", "WN+RW", "--columns", "gx,gy", "--units", "rad/s", "--cores", "1"]


def write_recording(path: Path, sigma: float, seed: int, n: int = 20000, freq: float = 100.0,
                    moving_from: int | None = None) -> Path:
    """A two-axis gyroscope CSV (rad/s, time column): white noise of density ``sigma``
    [rad/s/sqrt(Hz)], a large oscillation from sample ``moving_from`` on."""
    rng = np.random.default_rng(seed)
    g = rng.normal(0.0, sigma * np.sqrt(freq), (n, 2))
    if moving_from is not None:
        g[moving_from:] += 0.5 * np.sin(np.arange(n - moving_from) / 5.0)[:, None]
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as fh:
        fh.write("time,gx,gy\n")
        np.savetxt(fh, np.column_stack([np.arange(n) / freq, g]), delimiter=",", fmt="%.9g")
    return path


def _example():
    spec = importlib.util.spec_from_file_location("make_fleet", ROOT / "examples" / "make_fleet.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    env["MPLBACKEND"] = "Agg"
    return env


def gmwm_fleet(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gmwm", "fleet", *args], capture_output=True,
                          text=True, env=_env(), check=False)


def planned(output: str) -> dict[str, int]:
    if "Nothing to be done" in output:
        return {}
    stats = output.split("Job stats:")[-1]
    return {m.group(1): int(m.group(2))
            for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", stats, re.MULTILINE)
            if m.group(1) != "total"}


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    base = tmp_path_factory.mktemp("fleet")
    inputs = base / "in"
    for i, s in enumerate((1.0e-4, 1.05e-4)):
        write_recording(inputs / f"imu{i}_2026-0{i + 1}-01.csv", s, seed=i)
    # the third unit as a ROS 1 bag, written by rosbags' writer (examples/make_fleet.py)
    example = _example()
    if importlib.util.find_spec("rosbags") is not None:
        data = example.signals(20000, 100.0, 0.95e-4, 1e-3, np.random.default_rng(2))
        example.write_bag(inputs / "imu2_2026-03-01.bag", data, 100.0)
    else:
        write_recording(inputs / "imu2_2026-03-01.csv", 0.95e-4, seed=2)
    (inputs / "broken_2026-01-01.csv").write_text("time,gx,gy\n0,1\n1,2\n")
    before = _snapshot(inputs)
    proc = gmwm_fleet(str(inputs), "-o", str(base / "out"), *OPTS)
    assert proc.returncode == 0, proc.stderr
    return base, inputs, base / "out", proc, before


def test_table_written_and_corrupt_file_listed(fleet):
    import json

    _, inputs, out, proc, before = fleet
    table = json.loads((out / "fleet.json").read_text())
    assert [f["unit"] for f in table["failed"]] == ["broken"]
    assert "broken/broken_2026-01-01:" in proc.stderr
    assert {u["unit"] for u in table["units"]} == {"imu0", "imu1", "imu2"}
    assert {u["status"] for u in table["units"] if u["unit"] == "imu2"} >= {"in family"}
    nd = table["coefficients"]["gx.noise_density"]
    assert nd["n_units"] == 3 and 0.8e-4 < nd["typical"] < 1.2e-4
    for name in ("fleet.html", "fleet.md", "fleet.csv", "fleet_summary.csv"):
        assert (out / name).stat().st_size > 0
    assert (out / "units" / "imu0" / "imu0_2026-01-01" / "imu.yaml").is_file()
    assert _snapshot(inputs) == before  # the inputs are never written
    assert "fleet of 4 units" in proc.stdout


def test_a_units_configuration_is_that_of_gmwm_report(fleet, tmp_path):
    from gmwm.cli import main
    from gmwm.fleet.run import FleetSettings

    _, inputs, out, _, _ = fleet
    rec = inputs / "imu0_2026-01-01.csv"
    s = FleetSettings(model="WN+RW", columns="gx,gy", units=("rad/s",))  # OPTS
    assert main(s.report_argv(str(rec), str(tmp_path / "cli"))) == 0
    unit = out / "units" / "imu0" / "imu0_2026-01-01"
    for name in ("imu.yaml", "imu_noise.json"):
        assert (unit / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


def test_adding_one_recording_reruns_one_job_and_the_table(fleet):
    base, inputs, out, _, _ = fleet
    proc = gmwm_fleet(str(inputs), "-o", str(out), *OPTS, "-n")
    assert proc.returncode == 0 and planned(proc.stdout) == {}, proc.stdout[-2000:]
    extra = base / "more"
    write_recording(extra / "imu3_2026-04-01.csv", 1.0e-4, seed=3)
    proc = gmwm_fleet(str(inputs), str(extra), "-o", str(out), *OPTS, "-n")
    assert planned(proc.stdout) == {"calibrate": 1, "fleet_table": 1, "all": 1}


def test_changed_content_reruns_that_recording_only(fleet):
    base, inputs, out, _, _ = fleet
    copy = base / "in_copy"
    shutil.copytree(inputs, copy)
    os.utime(copy / "imu1_2026-02-01.csv")  # touched, same content: not rerun
    write_recording(copy / "imu0_2026-01-01.csv", 1.3e-4, seed=10)
    proc = gmwm_fleet(str(copy), "-o", str(out), *OPTS, "-n")
    assert planned(proc.stdout) == {"calibrate": 1, "fleet_table": 1, "all": 1}


def test_changed_setting_reruns_everything(fleet):
    _, inputs, out, _, _ = fleet
    proc = gmwm_fleet(str(inputs), "-o", str(out), *OPTS, "--min-static", "30", "-n")
    assert planned(proc.stdout)["calibrate"] == 4


def test_archive_and_compare_with_it(fleet):
    _, inputs, out, _, _ = fleet
    archives = sorted((out / "archive").iterdir())
    assert {p.name for p in archives[-1].iterdir()} == {"fleet.json", "settings.json",
                                                         "inputs.json", "versions.json"}
    proc = gmwm_fleet(str(inputs), "-o", str(out), *OPTS, "--compare", str(archives[-1]))
    assert proc.returncode == 0, proc.stderr
    assert "moved since" in proc.stdout and ": none (" in proc.stdout  # same recordings
    assert (out / "compare.md").is_file()


def test_kill_then_same_command_resumes(tmp_path):
    import json

    inputs = tmp_path / "in"
    for i in range(4):
        write_recording(inputs / f"u{i}_2026-01-01.csv", 1e-4 * (1 + 0.05 * i), seed=20 + i)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "gmwm", "fleet", str(inputs), "-o", str(out), *OPTS]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=_env(), start_new_session=True)
    log = out / ".fleet" / "snakemake.log"
    while proc.poll() is None:  # kill once Snakemake has recorded the first recording done
        if log.is_file() and "Finished jobid" in log.read_text():
            break
        time.sleep(0.2)
    assert proc.poll() is None, "the run ended before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "fleet.json").exists()
    assert list((out / ".snakemake" / "locks").iterdir()), "a killed run leaves its locks"
    done = len(list(out.glob("units/*/*/status.json")))
    again = gmwm_fleet(str(inputs), "-o", str(out), *OPTS)
    assert again.returncode == 0, again.stderr
    table = json.loads((out / "fleet.json").read_text())
    assert len({u["unit"] for u in table["units"]}) == 4 and not table["failed"]
    from gmwm.fleet.run import RUN_MARK

    text = log.read_text().split(RUN_MARK)[-1]  # the second run's part of the log
    assert text.count("rule calibrate:") == 4 - done


def test_slurm_profile_plans_grouped_jobs(fleet):
    pytest.importorskip("snakemake_executor_plugin_slurm")
    base, inputs, out, _, _ = fleet
    copy = base / "slurm_in"
    write_recording(copy / "imu9_2026-01-01.csv", 1e-4, seed=9)
    proc = gmwm_fleet(str(inputs), str(copy), "-o", str(out), *OPTS[:-2], "--profile",
                      str(ROOT / "profiles" / "slurm"), "-n")
    assert proc.returncode == 0, proc.stderr + proc.stdout[-2000:]
    assert "Using profile" in proc.stdout and "Group job calibrate" in proc.stdout
    assert planned(proc.stdout) == {"calibrate": 1, "fleet_table": 1, "all": 1}


def test_static_stretch_of_a_log_that_moved(tmp_path):
    from gmwm.fleet.job import report
    from gmwm.fleet.run import FleetSettings, calibrate_recording

    s = FleetSettings(model="WN+RW", columns="gx,gy", units=("rad/s",))
    moved = write_recording(tmp_path / "m.csv", 1e-4, seed=7, moving_from=12000)
    st = calibrate_recording(moved, tmp_path / "m", s, report=report)
    assert st["ok"] and st["used"] == "longest static segment"
    assert 100 < st["used_s"] < 120  # the static start, not the 200 s recording
    # 2 minutes of white noise cannot identify a random walk: said per axis
    assert st["not_identifiable"]["gx"] == {"WN": False, "RW": True}
    short = write_recording(tmp_path / "s.csv", 1e-4, seed=8, moving_from=4000)
    st = calibrate_recording(short, tmp_path / "s", s, report=report)
    assert not st["ok"]
    # refused by the report itself (fewer samples than a configuration needs) or by the
    # fleet's own minimum, whichever is stricter: either way a one-line reason, no numbers
    assert re.fullmatch(r"the longest static stretch lasts \d+\.\d s, shorter than the "
                        r"fleet's minimum of 60 s", st["reason"]) or (
        "fewer than the 4096 a configuration needs" in st["reason"])
