"""gmwm: Generalized Method of Wavelet Moments for inertial-sensor stochastic calibration.

Quick start::

    import gmwm
    model = gmwm.Model("WN+RW+AR1+SIN")
    theta = model.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975,
                         "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35})
    x = model.simulate(theta, 100_000, rng=1)
    res = gmwm.fit(x, model)
    print(res.summary())

The public names below are imported on first use (``import gmwm`` loads neither SciPy nor
Numba), so ``gmwm --help`` starts fast.
"""

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "GMWMError": "errors", "IdentifiabilityError": "errors", "InputError": "errors",
    "ModelError": "errors", "DataUnavailableError": "errors",
    "Model": "model", "fit": "estimator", "GMWMResult": "estimator",
    "FitSettings": "settings", "prepare_wv": "settings",
    "wvar": "wv", "avar": "wv", "WaveletVariance": "wv", "AllanVariance": "wv",
    "fit_avsm": "avsm",
    "svo": "virtual",
    "select_model": "select", "rank_models": "select",
    "choose_model": "automodel", "Choice": "automodel",
}

__all__ = ["AllanVariance", "Choice", "DataUnavailableError", "FitSettings", "GMWMError",
           "GMWMResult", "IdentifiabilityError", "InputError", "Model", "ModelError",
           "WaveletVariance", "avar", "choose_model", "fit", "fit_avsm", "prepare_wv", "rank_models",
           "select_model", "svo", "wvar"]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module 'gmwm' has no attribute {name!r}")
