"""The navigation emulation's outputs in the session's quick run (config/quick.yaml): the main
study and its variants (navigation.variants; quick profile: z_only, 4 iterations)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

pytestmark = pytest.mark.pipeline

MAIN_TABLE = ["window", "n_dropped", "n_iterations", "time_s", "max_ratio", "ci_lo", "ci_hi",
              "boot_max_lo", "boot_max_hi", "mean_err_model1_m", "mean_err_model2_m",
              "share_ratio_ci_above_1"]


def check_variant_outputs(out: Path, variant: str, gyro_axes: str, iterations: int) -> None:
    """The variant's files exist, its table has the main table's columns plus variant and
    gyro_axes, and its series the main series' columns (the same functions write both)."""
    nav = out / "reports" / "navigation"
    table = pd.read_csv(nav / variant / "ratio_max.csv")
    assert list(table.columns) == ["variant", "gyro_axes", *MAIN_TABLE]
    assert list(pd.read_csv(nav / "ratio_max.csv").columns) == MAIN_TABLE
    assert list(table.window) == ["whole flight", "GNSS outage"]
    assert (table.variant == variant).all() and (table.gyro_axes == gyro_axes).all()
    assert (table.n_iterations + table.n_dropped == iterations).all()
    assert (table.ci_lo <= table.max_ratio).all() and (table.max_ratio <= table.ci_hi).all()
    series = pd.read_csv(nav / variant / "ratio_series.csv")
    assert list(series.columns) == list(pd.read_csv(nav / "ratio_series.csv").columns)
    assert len(series) == len(pd.read_csv(nav / "ratio_series.csv"))  # same flight and rate
    for name in ("ratio_max.md", "fig8_ratio.png", "fig8_ratio.pdf"):
        assert (nav / variant / name).stat().st_size > 0, name


def test_navigation_z_only_variant(quick_run):
    check_variant_outputs(quick_run.out, "z_only", "z", iterations=4)
    index = (quick_run.out / "reports" / "index.md").read_text()
    assert "z_only/fig8_ratio.png" in index
