"""Default standard errors are calibrated: empirical SD of the estimates / mean reported SE lies in
[0.75, 1.33] for every parameter (benchmarks/bench_se_calibration.py runs the larger study).

R = 60 replicates give the ratio a Monte Carlo SD of about 1/sqrt(2R) = 0.09, so the band is
about 3 MC SDs wide on either side of 1; the old Gaussian diagonal V fails it (0.34 for SIN beta).
"""


import numpy as np
import pytest

from conftest import load_benchmark

_bench = load_benchmark("bench_se_calibration")
CASES, calibration, ratio = _bench.CASES, _bench.calibration, _bench.ratio


@pytest.mark.slow
@pytest.mark.parametrize("spec", sorted(CASES))
def test_standard_errors_are_calibrated(spec):
    out = calibration(spec, CASES[spec], T=2**15, R=60, seed=11)
    assert out["ok"].sum() >= 55
    r = ratio(out)
    assert np.all((r > 0.75) & (r < 1.33)), dict(zip(out["names"], np.round(r, 2), strict=True))
