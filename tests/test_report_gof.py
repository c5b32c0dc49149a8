"""The calibration report (gmwm.report.write_report) shows each axis's goodness-of-fit line and
never says "No warnings" over a rejected model, even when the caller's warning list lacks it."""

from __future__ import annotations

import numpy as np

import gmwm
from gmwm.datasheet import datasheet
from gmwm.report import write_report


def test_report_shows_the_gof_line_and_the_rejected_model(tmp_path, one_process):
    model = gmwm.Model("WN+AR1", freq=100.0)
    x = model.simulate(model.theta({"WN[1].sigma2": 1e-4, "AR1[1].phi": 0.995,
                                    "AR1[1].sigma2": 1e-7}), 2**13, np.random.default_rng(5))
    wrong = gmwm.fit(x, "WN", freq=100.0)
    right = gmwm.fit(x, model, freq=100.0)
    assert wrong.gof.rejected() and not right.gof.rejected()
    axes = {"gx": {"result": wrong, "units": "rad/s", "warnings": [],
                   "datasheet": datasheet(wrong, "rad/s")},
            "gy": {"result": right, "units": "rad/s", "warnings": [],
                   "datasheet": datasheet(right, "rad/s")}}
    write_report(tmp_path, axes, source="sim.csv", title="IMU")
    md = (tmp_path / "report.md").read_text()
    page = (tmp_path / "report.html").read_text()
    gx, gy = md.split("## gx", 1)[1].split("## gy", 1)
    assert "Goodness of fit: statistic" in gx and "(REJECTED)" in gx
    assert wrong.gof.warning() in gx and "No warnings" not in gx
    assert "Goodness of fit: statistic" in gy and "REJECTED" not in gy
    assert right.gof.line()[1:] in gy
    assert "the model is rejected" in page
