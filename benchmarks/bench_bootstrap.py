"""Cost of the parametric bootstrap (gmwm.bootstrap) on long signals.

Model: the Navchip gyroscope X model QN+WN+2*GM+RW+DR at 250 Hz with theta from a GMWM fit to
the Navchip WV table; lengths T = 1e6 and the Navchip length T = 3,105,250. For each T it times
``--draws`` draws (default 5) of (a) simulation + WV only (``wv_bootstrap``, enough for the WV
covariance / efficient GMWM) and (b) simulation + WV + refit (``parametric_bootstrap``), and
extrapolates linearly to B = 100 (draws are independent and equally expensive). ``--draws 100``
measures B = 100 directly. Single process; draws split over processes/jobs with ``draws=``.

    python benchmarks/bench_bootstrap.py [--draws 5] [--wv PATH]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

import gmwm
from gmwm import bootstrap as bs
from gmwm.estimator import weight_matrix
from gmwm.model import Model
from gmwm_studies.data import load_navchip_wv

SPEC = "QN+WN+2*GM+RW+DR"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--draws", type=int, default=5)
    ap.add_argument("--B", type=int, default=100)
    ap.add_argument("--wv", default="/work/shared/data/wv/navchip_wv.csv")
    args = ap.parse_args()

    wv = load_navchip_wv(args.wv, "gyroscope", "X")
    model = Model(SPEC, freq=wv.freq)
    t0 = time.perf_counter()
    est = gmwm.fit(wv, model)
    print(f"Navchip gyro X: T = {wv.n_samples}, J = {wv.n_levels}, fit {time.perf_counter() - t0:.2f} s, "
          f"converged {est.converged}")
    for name, value in est.as_dict().items():
        print(f"  {name:<14} {value: .6g}")
    # warm up numba / imports outside the timings
    bs.wv_bootstrap(model, est.params, 2**12, 1, seed=99)

    print(f"\n{'T':>10} {'J':>3} {'sim+WV s/draw':>14} {'+refit s/draw':>14} "
          f"{'B=' + str(args.B) + ' WV only':>14} {'B=' + str(args.B) + ' refit':>12}  failed")
    for T in (10**6, int(wv.n_samples)):
        J = int(np.floor(np.log2(T))) - 1
        # the same theta at every T; the WV object only carries T and J for the refits
        res_T = _with_length(est, T, J)
        t0 = time.perf_counter()
        bs.wv_bootstrap(model, est.params, T, args.draws, levels=J, seed=1)
        per_wv = (time.perf_counter() - t0) / args.draws
        t0 = time.perf_counter()
        boot = bs.parametric_bootstrap(res_T, args.draws, seed=1)
        per_fit = (time.perf_counter() - t0) / args.draws
        print(f"{T:>10} {J:>3} {per_wv:>14.3f} {per_fit:>14.3f} {per_wv * args.B:>14.1f} "
              f"{per_fit * args.B:>12.1f}  {boot.n_failed}/{boot.n_draws}")
    print(f"\n(timed {args.draws} draws per row, extrapolated linearly to B = {args.B}; "
          "one process)")


def _with_length(res: gmwm.GMWMResult, T: int, J: int) -> gmwm.GMWMResult:
    """The estimate as if fitted to a WV of length T with J levels (theoretical WV as values)."""
    scales = 2.0 ** np.arange(1, J + 1)
    nu = res.model.wv(res.params, scales)
    wv = gmwm.WaveletVariance.from_table(scales, nu, n_samples=T, freq=res.wv.freq)
    return dataclasses.replace(res, wv=wv, weights=weight_matrix(wv, "ci"))


if __name__ == "__main__":
    main()
