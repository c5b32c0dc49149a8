"""The plain-Python AR1 WV (gmwm.processes._ar1_a_py) gives the Numba kernel's bits, so which of
the two answers a call never changes a result; and the lazy imports keep Numba and
scipy.optimize out of processes that do not fit."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from gmwm import processes


def _kernel(a: float, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from gmwm import _ar1kernels

    nu, dnu = np.empty(tau.size), np.empty(tau.size)
    _ar1kernels.ar1_a(a, tau, nu, dnu)
    return nu, dnu


def test_python_twin_is_bit_identical_to_the_kernel():
    rng = np.random.default_rng(7)
    dyadic = 2.0 ** np.arange(1, 31)
    a_values = np.concatenate([10 ** rng.uniform(-12, 2.5, 1500), [1e-300, 5e-3, 1e-2, 700.0]])
    for i, a in enumerate(a_values):
        tau = dyadic if i % 2 else 10 ** rng.uniform(0.3, 9, 25)
        nu, dnu = processes._ar1_a_py(float(a), tau)
        knu, kdnu = _kernel(float(a), tau)
        assert np.array_equal(nu, knu) and np.array_equal(dnu, kdnu), a


def test_dispatch_falls_back_to_the_kernel_where_python_raises():
    # a < 0 (phi > 1, outside the domain) overflows math.exp: the kernel's inf/nan, no exception
    tau = 2.0 ** np.arange(1, 12)
    nu, dnu = processes.ar1_wv_a(-800.0, tau)
    knu, kdnu = _kernel(-800.0, tau)
    assert np.array_equal(nu, knu, equal_nan=True) and np.array_equal(dnu, kdnu, equal_nan=True)


def test_drawing_a_model_wv_loads_neither_numba_nor_scipy_optimize():
    code = ("import sys, numpy as np, pickle\n"
            "from gmwm.model import Model\n"
            "import gmwm.estimator, gmwm.automodel, gmwm.gof\n"
            "m = Model('WN+GM+RW', freq=100.0)\n"
            "nu = m.wv(np.array([1e-4, 0.01, 1e-6, 1e-9]), 2.0 ** np.arange(1, 20))\n"
            "assert np.all(nu > 0)\n"
            "print('numba' in sys.modules, 'scipy.optimize' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
