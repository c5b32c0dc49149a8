"""benchmarks/bench_fleet.py's scale mode and the synthetic fleet it times (examples/make_fleet.py):
the formats and corrupt files written, the checks of the fleet table, the table job's time read
from Snakemake's log; end to end on a small fleet (slow)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import load_benchmark

ROOT = Path(__file__).resolve().parents[1]
HAS_ROSBAGS = importlib.util.find_spec("rosbags") is not None


def _env() -> dict[str, str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"),
                                                      env.get("PYTHONPATH")]))
    return env


def _make_fleet():
    spec = importlib.util.spec_from_file_location("make_fleet", ROOT / "examples" / "make_fleet.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_make_fleet_formats_lengths_and_corrupt_files(tmp_path: Path) -> None:
    from gmwm.readers.recording import read_recording

    bags = "0.34" if HAS_ROSBAGS else "0"
    assert _make_fleet().main([str(tmp_path), "--units", "4", "--minutes", "0.05",
                               "--long-minutes", "0.1", "--bags", bags, "--h5", "0.34",
                               "--dated", "2", "--corrupt", "3"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    truth = json.loads((tmp_path / "truth.json").read_text())
    suffixes = {Path(t["file"]).suffix for t in truth if t["unit"].startswith("unit")}
    assert suffixes == ({".bag", ".h5", ".csv"} if HAS_ROSBAGS else {".h5", ".csv"})
    assert [n for n in names if n.startswith("corrupt")] == [
        "corrupt0_2026-01-05.csv", "corrupt1_2026-01-05.bag", "corrupt2_2026-01-05.h5"]
    secs = {t["unit"]: t["seconds"] for t in truth}
    assert secs["unit0000"] == pytest.approx(3.0) and secs["aging"] == pytest.approx(6.0)
    assert secs["moved"] == pytest.approx(6.0)
    h5 = next(t["file"] for t in truth if t["file"].endswith(".h5"))
    rec = read_recording(tmp_path / h5, columns="all")
    assert rec.freq == pytest.approx(100.0) and len(rec.channels) == 6
    with pytest.raises(SystemExit):  # shares beyond 1 are refused
        _make_fleet().main([str(tmp_path / "x"), "--bags", "0.6", "--h5", "0.6"])


def _fleet_json(path: Path, *, odd_flagged: bool, drift_lo: float, failed: list[str]) -> None:
    units = [{"unit": "odd0", "status": "out of family" if odd_flagged else "in family"},
             {"unit": "unit0003", "status": "out of family"},
             {"unit": "moved", "status": "in family"}]
    drift = [{"unit": "aging", "coefficient": f"{a}.noise_density",
              "percent_per_year": [40.0, drift_lo, 60.0]} for a in ("gx", "gy", "gz")]
    path.mkdir()
    (path / "fleet.json").write_text(json.dumps(
        {"units": units, "drift": drift,
         "failed": [{"unit": r.split("_")[0], "recording": r, "reason": "x"} for r in failed]}))


def test_fleet_checks_pass_and_fail(tmp_path: Path) -> None:
    bench = load_benchmark("bench_fleet")
    truth = [{"unit": "odd0"}, {"unit": "unit0003"}, {"unit": "aging"}]
    corrupt = ["corrupt0_2026-01-05"]
    _fleet_json(tmp_path / "good", odd_flagged=True, drift_lo=20.0, failed=corrupt)
    good = bench._fleet_checks(tmp_path / "good", truth, corrupt)
    assert all(ok for _, ok, _ in good), good
    assert "1 others by chance" in good[0][2]
    _fleet_json(tmp_path / "bad", odd_flagged=False, drift_lo=-5.0, failed=[])
    bad = bench._fleet_checks(tmp_path / "bad", truth, corrupt)
    assert [ok for _, ok, _ in bad] == [False, False, False, True]


def test_table_job_seconds_from_snakemake_log(tmp_path: Path) -> None:
    bench = load_benchmark("bench_fleet")
    log = tmp_path / "snakemake.log"
    log.write_text("[Sat Nov 28 17:15:01 2026]\nrule calibrate:\n    jobid: 2\n"
                   "[Sat Nov 28 17:15:30 2026]\nFinished jobid: 2 (Rule: calibrate)\n"
                   "[Sat Nov 28 17:15:34 2026]\nlocalrule fleet_table:\n    jobid: 1\n"
                   "[Sat Nov 28 17:15:41 2026]\nFinished jobid: 1 (Rule: fleet_table)\n")
    assert bench._table_job_seconds(log) == 7.0
    log.write_text("[Sat Nov 28 17:15:34 2026]\nlocalrule fleet_table:\n")
    assert bench._table_job_seconds(log) is None


@pytest.mark.slow
def test_scale_mode_end_to_end(tmp_path: Path) -> None:
    """A fleet of 5 units (16 recordings) timed against one gmwm report; README untouched."""
    readme = ROOT / "benchmarks" / "README.md"

    def block() -> str:  # the generated block --readme would write (others may edit the rest)
        text = readme.read_text()
        return text[text.find("<!-- BEGIN bench_fleet_scale"):text.find("<!-- END bench_fleet_s")]

    before = block()
    out = tmp_path / "scale.json"
    got = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_fleet.py"),
                          "--reps", "0", "--table-units", "100", "--units", "5", "--sample",
                          "1", "--cores", "2", "--workdir", str(tmp_path), "--json", str(out)],
                         capture_output=True, text=True, env=_env(), cwd=ROOT / "benchmarks",
                         check=False)
    assert got.returncode == 0, got.stderr[-2000:]
    sc = json.loads(out.read_text())["scale"]
    assert sc["recordings"] == 5 + 1 + 6 + 1 + 3
    assert all(c["passed"] for c in sc["checks"]), sc["checks"]
    assert sc["fleet_cpu_s"] > 0 and sc["cpu_ratio"] > 0 and len(sc["sample"]) == 1
    assert sc["fleet_tree_rss_mb"] >= sc["fleet_largest_rss_mb"] * 0.5
    assert block() == before
