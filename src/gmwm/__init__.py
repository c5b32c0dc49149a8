"""gmwm: Generalized Method of Wavelet Moments for inertial-sensor stochastic calibration.

Quick start::

    import gmwm
    model = gmwm.Model("WN+RW+AR1+SIN")
    x = model.simulate(model.theta({...}), 100_000, rng=1)
    res = gmwm.fit(x, model)
    print(res.summary())
"""

from .errors import GMWMError, IdentifiabilityError, InputError, ModelError
from .fit import GMWMResult, fit
from .model import Model
from .wv import AllanVariance, WaveletVariance, avar, wvar

__version__ = "0.1.0"

__all__ = ["AllanVariance", "GMWMError", "GMWMResult", "IdentifiabilityError", "InputError",
           "Model", "ModelError", "WaveletVariance", "avar", "fit", "wvar"]
