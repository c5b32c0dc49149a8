"""The fleet's calibration of one recording (gmwm.fleet.job.report: gmwm.calibrate.calibrate and
gmwm.report.write_calibration called directly) gives what `gmwm report` of the same file gives,
and refuses what it does not calibrate as a recording."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest


def _recording(path: Path, n: int = 20000, freq: float = 100.0, seed: int = 3) -> Path:
    """A two-axis gyroscope CSV [rad/s] with a time column: white noise plus a random walk."""
    rng = np.random.default_rng(seed)
    g = rng.normal(0.0, 1e-3, (n, 2)) + np.cumsum(rng.normal(0.0, 1e-6, (n, 2)), axis=0)
    with open(path, "w") as fh:
        fh.write("time,gx,gy\n")
        np.savetxt(fh, np.column_stack([np.arange(n) / freq, g]), delimiter=",", fmt="%.9g")
    return path


@pytest.mark.slow
def test_fleet_calibration_is_gmwm_report(tmp_path):
    from gmwm.cli import main
    from gmwm.fleet.job import report
    from gmwm.fleet.run import FleetSettings

    rec = _recording(tmp_path / "r.csv")
    s = FleetSettings(model="WN+RW", columns="gx,gy", units=("rad/s",))
    code, obj, err = report(s.report_argv(str(rec), str(tmp_path / "fleet")))
    assert code == 0, err
    assert main(s.report_argv(str(rec), str(tmp_path / "cli"))) == 0
    # the configuration files, byte for byte
    for name in ("imu.yaml", "imu_noise.json"):
        assert (tmp_path / "fleet" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    noise = json.loads((tmp_path / "fleet" / "imu_noise.json").read_text())
    assert noise  # something was written to compare
    # the fits the table reads, as gmwm report --json gives them
    assert obj is not None and set(obj["fits"]) == {"gx", "gy"}
    assert obj["stationarity"]["used"]["how"] == "longest static segment"
    assert "gmwm: verdict:" in err


def test_wv_table_is_refused_in_one_line(tmp_path):
    from gmwm.fleet.job import report
    from gmwm.fleet.run import FleetSettings

    table = tmp_path / "wv.csv"
    table.write_text("scale,variance\n1,1e-6\n2,5e-7\n4,2.5e-7\n")
    code, obj, err = report(FleetSettings().report_argv(str(table), str(tmp_path / "o")))
    assert code == 1 and obj is None
    assert err.strip() == f"gmwm: error: {table} is a WV table, not a recording: the fleet " \
                          "calibrates recordings"


def test_usage_error_of_a_report_argument_is_exit_status_2(tmp_path):
    from gmwm.fleet.job import report
    from gmwm.fleet.run import FleetSettings

    rec = _recording(tmp_path / "r.csv", n=500)
    s = FleetSettings(model="WN", report_args=("--gaps", "nonsense"))
    code, obj, err = report(s.report_argv(str(rec), str(tmp_path / "o")))
    assert code == 2 and obj is None and "--gaps" in err


def test_python_warnings_reach_the_status_after_the_error(tmp_path, monkeypatch):
    import warnings

    import gmwm.calibrate
    from gmwm.errors import InputError
    from gmwm.fleet.job import report
    from gmwm.fleet.run import FleetSettings

    def fake(*_a, **_k):
        warnings.warn("a reader's caveat", UserWarning, stacklevel=1)
        raise InputError("too short")

    monkeypatch.setattr(gmwm.calibrate, "calibrate", fake)
    rec = _recording(tmp_path / "r.csv", n=500)
    code, obj, err = report(FleetSettings(model="WN").report_argv(str(rec), str(tmp_path / "o")))
    assert (code, obj) == (1, None)
    assert err.splitlines() == ["gmwm: error: too short", "gmwm: warning: a reader's caveat"]


def test_fleet_snakemake_command_uses_the_greedy_scheduler(tmp_path):
    # the ILP scheduler doubles Snakemake's own CPU at ~1000 alike jobs; Snakemake's own parser
    # must accept the command as built
    snakemake_cli = pytest.importorskip("snakemake.cli")
    from gmwm.fleet.run import snakemake_argv

    for kw in ({"cores": 2}, {"profile": str(tmp_path)}):
        argv = snakemake_argv(tmp_path / "out", tmp_path / "fleet.yaml", **kw)
        assert argv[argv.index("--scheduler") + 1] == "greedy"
        args = snakemake_cli.get_argument_parser().parse_args(argv[3:])
        assert args.scheduler == "greedy"
