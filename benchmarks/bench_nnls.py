"""What the search's shortcut to SciPy's private NNLS kernel saves (gmwm.search._nnls).

The variable-projection search solves thousands of small NNLS problems per fit. SciPy's public
``scipy.optimize.nnls`` wraps the Lawson-Hanson kernel in input checks; ``gmwm.search`` calls the
kernel directly when this SciPy has it (checked at import), else the public function. This script
measures, in CPU time (minimum of several repeats, so that other load inflates it least):

* one call on a search-sized system (J = 20 scales, 5 components), public vs kernel;
* the default fits of the simulated and stored-bootstrap hard cases (benchmarks/hard_cases.py),
  all with the kernel, then all with the public function, repeated alternately; the estimates
  must be identical.

    python benchmarks/bench_nnls.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import hard_cases
import numpy as np
from scipy.optimize import nnls

import gmwm
from gmwm import search


def per_call(fn, A: np.ndarray, b: np.ndarray, n: int, repeats: int) -> float:
    """Minimum CPU seconds per call of ``fn(A, b, maxiter=...)`` over ``repeats`` runs of n."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(n):
            fn(A, b, maxiter=250)
        best = min(best, time.process_time() - t0)
    return best / n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    kernel = search._nnls_core()
    if kernel is None:
        print("this SciPy has no usable private NNLS kernel: the search uses the public one")
        return 0
    rng = np.random.default_rng(0)
    A, b = np.ascontiguousarray(rng.random((20, 5))), rng.random(20)
    t_pub = per_call(nnls, A, b, 20000, args.repeats)
    t_ker = per_call(lambda A, b, maxiter: kernel(A, b, maxiter), A, b, 20000, args.repeats)
    print(f"one call (20 x 5): public {t_pub * 1e6:.1f} us, kernel {t_ker * 1e6:.1f} us")

    cases = hard_cases.cases(navchip=False)
    calls = {"n": 0}
    plain = search._nnls

    def counted(A, b, maxiter):
        calls["n"] += 1
        return plain(A, b, maxiter)

    search._nnls = counted
    gmwm.fit(cases[0][1], cases[0][2])  # imports and compiled kernels, outside the clock
    cpu = {"kernel": [], "public": []}
    ref = None
    for _ in range(args.repeats):
        for name, k in (("kernel", kernel), ("public", None)):
            search._NNLS = k
            calls["n"] = 0
            t0 = time.process_time()
            est = [gmwm.fit(wv, spec, se_cov="gaussian").params.tobytes()
                   for _, wv, spec in cases]
            cpu[name].append(time.process_time() - t0)
            ref = est if ref is None else ref
            if est != ref:
                raise SystemExit("the kernel and the public function gave different estimates")
    search._NNLS, search._nnls = kernel, plain
    k, p = min(cpu["kernel"]), min(cpu["public"])
    print(f"{len(cases)} hard-case fits, {calls['n']} NNLS calls: CPU {k:.2f} s with the kernel, "
          f"{p:.2f} s with the public function ({(p - k) / p:.0%} saved); identical estimates")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
