"""benchmarks/search_class.py: a replicate's best known objective never exceeds its default's."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("search_class")


def test_replicate_best_not_above_default(bench) -> None:
    # Simulation 2's design at a tiny length with a 2x budget and a short SIN profile: the row's
    # best known objective comes from a search that starts at the default's estimate
    design = bench.designs()["sim2"]
    theta = design.theta()
    row = bench.replicate(design, theta, 0, T=2**12, factor=2, n_profile=3)
    assert row["model"] == "sim2" and row["T"] == 2**12 and row["base_seed"] == bench.BASE_SEED
    assert np.isfinite(row["default"]) and row["default"] > 0
    assert row["best"] <= row["default"]
    assert row["excess"] == pytest.approx(row["default"] / row["best"] - 1, abs=1e-15)
    assert row["reaches"] == (row["excess"] <= bench.TOL)
    assert len(row["variance"]) == 11  # J = floor(log2 T) - 1
    assert row["cpu_default"] > 0 and row["cpu_search"] > 0


def test_wilson_interval(bench) -> None:
    lo, hi = bench.wilson(200, 200)
    assert hi == pytest.approx(1.0) and 0.98 < lo < 0.985  # 1 - 3.84 / 203.84 = 0.9812
    lo, hi = bench.wilson(50, 100)
    assert lo < 0.5 < hi and hi - 0.5 == pytest.approx(0.5 - lo)
