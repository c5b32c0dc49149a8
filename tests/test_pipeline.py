"""End-to-end tests of the Snakemake workflow on the quick profile.

The outputs come from the session's one quick run (`quick_run` in conftest.py: the README's
command in a git copy of the workflow, which must leave `git status` clean). The tests check the
outputs, what dry runs plan after config edits, and that a run killed with SIGKILL resumes with the
same command and ends with the same estimates as the uninterrupted run.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml

from conftest import (
    QUICK_ARGS,
    QUICK_OUT,
    git_status,
    run_snakemake,
    snakemake_cmd,
    workflow_copy,
)
from gmwm_studies.store import read_dataset

pytestmark = pytest.mark.pipeline

T_QUICK = 131072


def planned_jobs(output: str) -> dict[str, int]:
    """Job counts per rule from Snakemake's 'Job stats' table (empty if nothing to do)."""
    if "Nothing to be done" in output:
        return {}
    stats = output.split("Job stats:")[-1]
    rows = re.finditer(r"^(\w+)\s+(\d+)\s*$", stats, re.MULTILINE)
    return {m.group(1): int(m.group(2)) for m in rows if m.group(1) != "total"}


@pytest.fixture(scope="module")
def run(quick_run) -> Path:
    """Output directory of the session's quick run (results/, reports/, logs/ below it)."""
    return quick_run.out


def test_quick_run_leaves_git_status_clean(quick_run):
    assert quick_run.git_before == "" and quick_run.git_after == "", quick_run.git_after


def test_quick_run_completes(quick_run):
    failed = re.findall(r"Error in rule (\w+)", quick_run.output)
    assert quick_run.returncode == 0, f"rules failed: {failed}\n{quick_run.output[-3000:]}"


def test_outputs_exist_and_are_sensible(run):
    for study in ("sim2", "sim3"):
        for name in ("bias_sd_rmse.csv", "bias_sd_rmse.md", "fig_wv.png", "fig_wv.pdf",
                     "fig_boxplot.png", "fig_boxplot.pdf"):
            assert (run / "reports" / study / name).stat().st_size > 0, (study, name)
    index = (run / "reports" / "index.md").read_text()
    assert "sim2" in index and "sim3" in index and "fig_boxplot.png" in index
    # a study fitted with several estimators labels its key rows (sim3: CI and efficient weights)
    sim3_section = index.split("## sim3:")[1].split("\n## ")[0]
    assert "| estimator |" in sim3_section and "| gmwm_eff |" in sim3_section
    assert len(list((run / "reports" / "archive").iterdir())) == 1
    assert list((run / "logs" / "sim3" / "fit").glob("*.log"))

    # 16 replicates: the MC SE of a standardized bias is about 1/sqrt(n_used) <= 0.3, so |.| < 1.2
    # is a 4-SE bound. sim2's slow sinusoid is weakly identified by the current estimator (its
    # SIN parameters are reported in the table but not asserted here; see docs/pipeline.md).
    sim3 = pd.read_csv(run / "reports" / "sim3" / "bias_sd_rmse.csv")
    # both weightings (config studies.sim3.estimators): 6 parameters each
    assert list(sim3.estimator.unique()) == ["gmwm", "gmwm_eff"]
    assert len(sim3) == 2 * 6 and (sim3.n_replicates == 16).all()
    assert (sim3.std_bias.abs() < 1.2).all(), sim3[["parameter", "std_bias"]]
    assert (sim3.share_not_converged <= 0.5).all()
    sim2 = pd.read_csv(run / "reports" / "sim2" / "bias_sd_rmse.csv")
    ar1 = sim2[sim2.parameter.str.startswith("AR1")]
    assert len(ar1) == 2 * 4 and (ar1.std_bias.abs() < 1.2).all(), ar1[["estimator", "parameter",
                                                                         "std_bias"]]
    assert sim2.share_not_converged.between(0, 1).all()


def test_archive_covers_navchip_when_data_is_local(run):
    """The Navchip file is on disk (../shared/data): its reports and job timings are archived
    with the studies', so one archive covers every report of the run."""
    (archive,) = (run / "reports" / "archive").iterdir()
    for name in ("estimates.csv", "gof.csv", "bootstrap_ci.csv", "identifiability.csv"):
        assert (archive / "reports" / "navchip" / name).stat().st_size > 0, name
    timings = pd.read_csv(archive / "timings.csv")
    assert {"navchip_fit", "navchip_report", "uncertainty_table"} <= set(timings.rule)
    assert (timings.study == "navchip").sum() >= 3


def test_sim1_and_uncertainty_outputs(run):
    sim1 = run / "reports" / "sim1"
    for name in ("comparison.csv", "rmse_bias_time.csv", "fig1_rmse.png", "fig2_runtime.png",
                 "fig9_boxplot.png"):
        assert (sim1 / name).stat().st_size > 0, name
    comp = pd.read_csv(sim1 / "comparison.csv")
    # one row per T and MLE variant (config sim1.mle.variants), headline variant first, then the
    # statsmodels baseline on its smaller subset (config sim1.statsmodels.replicates)
    assert list(comp.variant[:4]) == ["mle", "mle_sm", "mle_gmwm", "statsmodels"]
    kalman = comp[comp.variant != "statsmodels"]
    # mle_sm on its own cap (config/quick.yaml mle.variant_replicates: 3), the others on the MLE's
    assert list(kalman.n_mle) == [6, 3, 6, 4, 3, 4]
    assert list(comp[comp.variant == "statsmodels"].n_mle) == [2, 1]
    assert (comp.not_converged + comp.wrong_optimum <= comp.n_mle).all()
    assert (comp.speedup_mean > 0).all() and (comp.speedup_median > 0).all()
    # both clocks: point estimate, and with standard errors (never shorter)
    assert (comp.mle_se_mean_s >= comp.mle_mean_s).all()
    assert (comp.gmwm_se_mean_s >= comp.gmwm_mean_s).all()
    assert (comp.speedup_cpu_mean > 0).all()

    cov = pd.read_csv(run / "reports" / "sim3_coverage" / "coverage.csv")
    assert len(cov) == 18 and cov.coverage.between(0, 1).all()
    boot = pd.read_csv(run / "reports" / "uncertainty" / "bootstrap_ci.csv")
    assert len(boot) == 6 and ((boot.n_used + boot.n_failed) == 20).all()
    assert (boot.pct_low <= boot.pct_high).all() and (boot.basic_low <= boot.basic_high).all()
    ident = (run / "reports" / "uncertainty" / "identifiability.md").read_text()
    assert "pass" in ident or "warn" in ident
    assert (run / "reports" / "uncertainty" / "corner_sim3.png").stat().st_size > 0


def test_estimates_are_labelled(run):
    ds = read_dataset(run / "results" / "sim3" / "estimates" / f"gmwm_T{T_QUICK}.nc")
    assert ds.sizes["replicate"] == 16 and list(ds["replicate"].values) == list(range(16))
    assert ds.attrs["study"] == "sim3" and ds.attrs["n_samples"] == T_QUICK
    assert float(ds["truth"].sel(parameter="WN[1].sigma2")) == 8e-4


def test_nothing_to_do_when_nothing_changed(quick_run):
    if quick_run.returncode != 0:
        pytest.skip("the quick run failed (see test_quick_run_completes)")
    assert planned_jobs(run_snakemake(quick_run.work, *QUICK_ARGS, "-n")) == {}


def _overlay(tmp_path: Path, content: dict) -> list[str]:
    path = tmp_path / "overlay.yaml"  # outside the copy: its git status stays clean
    path.write_text(yaml.safe_dump(content))
    return ["-j2", "--configfile", "config/quick.yaml", str(path), "-n"]


def test_estimator_change_reuses_wv_cache(quick_run, tmp_path):
    args = _overlay(tmp_path, {"estimators": {"gmwm": {"n_starts": 3}}})
    jobs = planned_jobs(run_snakemake(quick_run.work, *args))
    assert "simulate_wv" not in jobs
    assert jobs["fit"] == 3  # sim2: 1 chunk, sim3: 2 chunks
    assert jobs["table"] == 2 and jobs["figure_boxplot"] == 2  # one per study
    assert "figure_wv" not in jobs  # the WV figure only depends on the cache


def test_study_change_reruns_only_that_study(quick_run, tmp_path):
    args = _overlay(tmp_path, {"studies": {"sim3": {"truth": {"WN[1].sigma2": 9e-4}}}})
    out = run_snakemake(quick_run.work, *args)
    jobs = planned_jobs(out)
    # sim3: 2 chunks; fits per chunk and estimator (gmwm, gmwm_eff)
    assert jobs["simulate_wv"] == 2 and jobs["fit"] == 2 * 2
    outputs = [ln for ln in out.splitlines() if ln.strip().startswith("output:")]
    assert outputs and not [ln for ln in outputs if "sim2" in ln]


# --- kill and resume -----------------------------------------------------------------------------

def _group(pgid: int) -> list[int]:
    """Live processes of process group ``pgid`` other than its leader (the running jobs)."""
    members = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # exited meanwhile
        pid = int(stat.parent.name)
        if int(fields[2]) == pgid and pid != pgid and fields[0] != "Z":
            members.append(pid)
    return members


# The killed run is the quick command restricted to three studies (36 jobs instead of 92) to keep
# the suite short; the resume machinery does not depend on which studies run. The Allan chapter
# (13 s of CPU, no estimate compared below) is left out too.
KILL_OVERLAY = {
    "studies": {name: {"enabled": False}
                for name in ("sim2", "stim300_accel", "sim3_coverage", "misspec")},
    **{section: {"enabled": False}
       for section in ("navchip", "uncertainty", "navigation", "svo", "allan")},
}


def _start(work: Path, args: list[str], log: Path) -> subprocess.Popen:
    """snakemake ``args`` in its own process group, output to ``log``."""
    with open(log, "wb") as fh:
        return subprocess.Popen(snakemake_cmd(*args), cwd=work, stdout=fh,
                                stderr=subprocess.STDOUT, start_new_session=True)


def _wait_mid_run(proc: subprocess.Popen, log: Path, n_finished: int) -> None:
    """Return once ``n_finished`` jobs have finished and another job is running."""
    while proc.poll() is None:
        if log.read_text().count("Finished jobid") >= n_finished and _group(proc.pid):
            return
        time.sleep(0.2)
    pytest.fail(f"the run ended before it could be killed:\n{log.read_text()[-3000:]}")


def _estimates(out: Path) -> dict[str, np.ndarray]:
    """Every estimate array of a quick run: Monte Carlo studies, Simulation 1, STIM-300."""
    found = {}
    for path in sorted((out / "results").glob("*/estimates/*.nc")) + sorted(
            (out / "results").glob("*/gmwm_mle/all_T*.nc")):
        with xr.open_dataset(path) as ds:
            found[str(path.relative_to(out))] = ds["estimate"].values
    for path in sorted((out / "results").glob("*/allan/*.nc")):
        for group in ("gmwm_cf", "armav", "avsm"):
            with xr.open_dataset(path, group=group) as ds:
                found[f"{path.relative_to(out)}:{group}"] = ds["estimate"].values
    return found


def test_sigkill_then_same_command_resumes(quick_run, tmp_path_factory):
    """SIGKILL the main process only (its running job is orphaned and finishes later), then the
    whole process group of the next run; the same command then completes, and every estimate
    equals the uninterrupted run's."""
    work = workflow_copy(tmp_path_factory.mktemp("killed"))
    out = work / QUICK_OUT
    overlay = work.parent / "kill_overlay.yaml"  # outside the copy: git status stays clean
    overlay.write_text(yaml.safe_dump(KILL_OVERLAY))
    args = [*QUICK_ARGS, str(overlay)]

    first = _start(work, args, work.parent / "first.log")
    _wait_mid_run(first, work.parent / "first.log", n_finished=2)
    os.kill(first.pid, signal.SIGKILL)
    first.wait()
    assert list((out / ".snakemake" / "locks").iterdir()), "a killed run leaves Snakemake locks"

    second = _start(work, args, work.parent / "second.log")  # the first's orphans may still run
    _wait_mid_run(second, work.parent / "second.log", n_finished=2)
    os.killpg(second.pid, signal.SIGKILL)
    second.wait()
    assert "removed stale Snakemake locks" in (work.parent / "second.log").read_text()

    third = run_snakemake(work, *args)
    assert "removed stale Snakemake locks" in third
    while _group(first.pid):  # the first run's orphaned jobs finish on their own
        time.sleep(0.5)

    ref = _estimates(quick_run.out)
    got = _estimates(out)
    # sim3 (1 size x 2 estimators), sim1 (2 sizes), stim300_gyro (2 sizes x 3 estimators)
    assert len(got) == 10 and got.keys() <= ref.keys(), sorted(got)
    for name, values in got.items():
        np.testing.assert_array_equal(values, ref[name], err_msg=name)
    for table in ("sim3/bias_sd_rmse.csv", "sim1/rmse_bias_time.csv"):
        ref_t = pd.read_csv(quick_run.out / "reports" / table)
        got_t = pd.read_csv(out / "reports" / table)
        cols = [c for c in ref_t.columns if "time" not in c and "seconds" not in c]
        pd.testing.assert_frame_equal(got_t[cols], ref_t[cols])
    assert git_status(work) == ""


def test_workflow_imports_this_checkouts_library(tmp_path):
    # another copy of the packages first on the path (a stale editable install elsewhere, an
    # older checkout): the workflow must still plan with this checkout's code, whose commit the
    # archive names
    for name in ("gmwm", "gmwm_studies"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("raise ImportError('the wrong copy')\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    proc = subprocess.run(snakemake_cmd("-n", *QUICK_ARGS), cwd=root, env=env,
                          capture_output=True, text=True, check=False)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "the wrong copy" not in out
