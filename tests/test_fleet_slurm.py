"""The fleet's SLURM path: the Snakemake command `gmwm fleet --profile profiles/slurm` runs
(gmwm.fleet.run.snakemake_argv) checked as a dry run with the SLURM executor plugin: the profile
is read, the recordings' jobs are bundled into one submission (group 'calibrate'), the table is
a local rule, and nothing is run or written."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest

pytest.importorskip("statsmodels")
pytest.importorskip("snakemake")

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "profiles" / "slurm"


def test_slurm_profile_dry_run_plans_one_group_job(tmp_path):
    pytest.importorskip("snakemake_executor_plugin_slurm",
                        reason="the SLURM executor plugin is not installed")
    if not (PROFILE / "config.yaml").is_file():
        pytest.skip(f"no SLURM profile at {PROFILE}")
    from gmwm.fleet.collect import find_recordings
    from gmwm.fleet.run import FleetSettings, prepare, run_workflow, snakemake_argv

    inputs = tmp_path / "in"
    inputs.mkdir()
    for i in range(3):
        (inputs / f"imu{i}_2026-01-0{i + 1}.csv").write_text(f"time,gx\n0,{i}\n0.01,1\n")
    out = tmp_path / "out"
    prep = prepare(find_recordings([str(inputs)]), out, FleetSettings(model="WN"))
    extra = ["--group-components", "calibrate=20"]
    argv = snakemake_argv(out, prep.config, profile=str(PROFILE), dry_run=True, extra=extra)
    assert argv[argv.index("--profile") + 1] == str(PROFILE) and "--cores" not in argv
    assert "-n" in argv
    log = io.StringIO()
    code = run_workflow(out, prep.config, profile=str(PROFILE), dry_run=True, extra=extra,
                        log=log)
    text = log.getvalue()
    assert code == 0, text[-3000:]
    assert "Using profile" in text and "Group job calibrate" in text
    stats = text.split("Job stats:")[-1]
    jobs = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", stats,
                                                              re.MULTILINE)}
    assert jobs == {"calibrate": 3, "fleet_table": 1, "all": 1, "total": 5}
    # a dry run: no calibration folder, no table
    assert not (out / "units").exists() and not (out / "fleet.json").exists()
