"""gmwm: Generalized Method of Wavelet Moments for inertial-sensor stochastic calibration."""

__version__ = "0.1.0"
