"""The fleet's inputs and outputs without running a calibration: unit identity, manifests,
folders, the written tables and page, the missing-extra message."""

from __future__ import annotations

import csv
import datetime as dt
import io
import json

import pytest

pytest.importorskip("statsmodels")

from gmwm.errors import InputError
from gmwm.fleet.collect import estimates_from_folder, find_recordings
from gmwm.fleet.core import Estimate, fleet_table
from gmwm.fleet.output import write_fleet


def _touch(path, text="time,gx\n0,1\n"):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_unit_rule_from_file_names_and_folders(tmp_path):
    _touch(tmp_path / "in" / "imuA_2026-03-01_ground.csv")
    _touch(tmp_path / "in" / "sub" / "imuA_2026-04-01.csv")
    _touch(tmp_path / "in" / "lonely.npy")
    _touch(tmp_path / "in" / "notes.md")
    _touch(tmp_path / "in" / "old" / ".fleet" / "settings.json")  # a fleet's output: skipped
    _touch(tmp_path / "in" / "old" / "fleet.csv", "unit,recording\n")
    recs = find_recordings([str(tmp_path / "in")])
    got = {(r.unit, r.name, r.date) for r in recs}
    assert got == {("imuA", "imuA_2026-03-01_ground", dt.date(2026, 3, 1)),
                   ("imuA", "imuA_2026-04-01", dt.date(2026, 4, 1)),
                   ("lonely", "lonely", None)}


def test_manifest_overrides_and_checks(tmp_path):
    _touch(tmp_path / "a.csv")
    _touch(tmp_path / "b.csv")
    man = _touch(tmp_path / "manifest.csv",
                 "path,unit,date,topic,temperature\na.csv,drone 7,2025-12-01,/imu0,21.5\n"
                 "b.csv,drone 7,2026-01-01,,\n")
    recs = find_recordings([str(man)])
    assert [(r.unit, r.date, r.topic, r.temperature) for r in recs] == [
        ("drone_7", dt.date(2025, 12, 1), "/imu0", 21.5), ("drone_7", dt.date(2026, 1, 1),
                                                          None, None)]
    _touch(tmp_path / "bad.csv", "path,date\na.csv,1st of May\n")
    with pytest.raises(InputError, match="not YYYY-MM-DD"):
        find_recordings([str(tmp_path / "bad.csv")])
    with pytest.raises(InputError, match="matches no file"):
        find_recordings([str(tmp_path / "*.bag")])


def test_failed_and_flagged_terms_from_a_folder(tmp_path):
    from gmwm.fleet.collect import Recording

    rec = Recording(tmp_path / "x.csv", "u1", "x")
    assert estimates_from_folder(tmp_path / "none", rec) == (
        [], "no calibration result (the job did not finish)")
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "status.json").write_text(json.dumps({"ok": False, "reason": "too short"}))
    assert estimates_from_folder(tmp_path / "f", rec) == ([], "too short")
    d = tmp_path / "ok"
    d.mkdir()
    (d / "status.json").write_text(json.dumps({"ok": True, "used_s": 90.0,
                                               "not_identifiable": {"gx": {"WN": True}}}))
    axis = {"sensor": "gyroscope",
            "noise_density": {"estimate": 1e-4, "ci95": [0.9e-4, 1.1e-4], "flag": None},
            "random_walk": {"estimate": 0.0, "ci95": [0.0, 2e-5], "flag": "boundary"}}
    (d / "imu_noise.json").write_text(json.dumps({"axes": {"gx": axis}}))
    fit = {"datasheet": {"ARW": {"value": 1e-4, "parameters": ["WN[1].sigma2"]}},
           "datasheet_verdict": {"rows": [{"term": "ARW", "quantity": "", "datasheet": 0.007,
                                           "unit": "deg/s/sqrt(Hz)", "measured": 0.0057296,
                                           "verdict": "better"}]}}
    (d / "report.json").write_text(json.dumps({"fits": {"gx": fit}}))
    ests, why = estimates_from_folder(d, rec)
    assert why is None
    by = {e.coefficient: e for e in ests}
    # the verdict of the report, the datasheet value in the estimate's unit (rad/s/sqrt(Hz))
    assert by["gx.noise_density"].datasheet == "better"
    assert by["gx.noise_density"].datasheet_value == pytest.approx(1.2217e-4, rel=1e-4)
    assert by["gx.random_walk"].excluded == "at the boundary 0"
    assert by["gx.noise_density"].excluded == "not identifiable at the 90 s used (gmwm plan rule)"
    assert not any(e.usable for e in ests)


def test_written_tables_and_page(tmp_path):
    ests = []
    for i, v in enumerate([1.0e-4, 1.05e-4, 0.97e-4, 1.02e-4, 0.99e-4, 4e-4]):
        for k, day in enumerate((0, 200)):
            vv = v * (2.0 if (i == 0 and k == 1) else 1.0)
            ests.append(Estimate(f"u{i}", f"u{i}_{k}", "gx.noise_density", vv,
                                 (vv / 1.03, vv * 1.03), "rad/s/sqrt(Hz)", "gyroscope",
                                 dt.date(2026, 1, 1) + dt.timedelta(days=day)))
    fleet = fleet_table(ests, failed=[("u9", "u9_0", "unreadable: bad header")])
    files = write_fleet(tmp_path, fleet)
    assert {p.name for p in files} == {"fleet.csv", "fleet_summary.csv", "fleet.md",
                                       "fleet.html", "fleet.json"}
    md = (tmp_path / "fleet.md").read_text()
    assert "u9 | u9_0 | unreadable: bad header" in md
    assert "above the fleet's 95 % prediction interval" in md
    page = (tmp_path / "fleet.html").read_text()
    assert page.count("data:image/png;base64,") == 2  # the coefficient and u0's drift
    obj = json.loads((tmp_path / "fleet.json").read_text())
    assert [d["unit"] for d in obj["drift"] if d["flagged"]] == ["u0"]
    assert {u["unit"] for u in obj["units"] if u["status"] == "out of family"} == {"u5"}


def test_missing_extra_is_one_line(monkeypatch, tmp_path):
    import importlib.util

    from gmwm.cli import main

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "snakemake" else real(name, *a))
    err = io.StringIO()
    monkeypatch.setattr("sys.stderr", err)
    assert main(["fleet", str(tmp_path), "-o", str(tmp_path / "out")]) == 1
    assert err.getvalue() == ("gmwm: error: gmwm fleet needs snakemake: install the pipeline "
                              "extra (pip install 'gmwm[pipeline]')\n")


def test_manifest_temperature_is_carried_beside_each_value(tmp_path):
    from gmwm.fleet.collect import Recording
    from gmwm.fleet.output import TEMPERATURE_NOTE

    ests = [Estimate(f"u{i}", f"u{i}_0", "gx.noise_density", v, (v / 1.03, v * 1.03),
                     "rad/s/sqrt(Hz)", "gyroscope", None)
            for i, v in enumerate([1.0e-4, 1.05e-4, 0.97e-4])]
    recs = [Recording(tmp_path / "a.csv", "u0", "u0_0", None, None, None, 21.5),
            Recording(tmp_path / "b.csv", "u1", "u1_0", None, None, None, None)]
    write_fleet(tmp_path, fleet_table(ests), recordings=recs)
    obj = json.loads((tmp_path / "fleet.json").read_text())
    assert {u["unit"]: u["temperature_c"] for u in obj["units"]} == {"u0": 21.5, "u1": None,
                                                                     "u2": None}
    assert TEMPERATURE_NOTE in obj["notes"]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "fleet.csv").read_text())))
    assert [r["temperature_c"] for r in rows] == ["21.5", "", ""]
