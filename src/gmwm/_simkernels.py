"""Numba kernels of :meth:`gmwm.model.Model.simulate_fast`: each adds one component's values to a
block of the signal, carrying the component's state from block to block. A block (a few 10^4
samples) stays in cache, so the signal is written once instead of once per component and per
NumPy operation. Imported lazily, like :mod:`gmwm._ar1kernels`.

``z``/``u`` are the block's standard normals / uniforms on [0, 1); ``t0`` is the 1-based time
of the block's first sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def add_walk_noise(x: np.ndarray, z: np.ndarray, a: float, b: float, level: float) -> float:
    """x_t += a z_t + b sum_{k<t} z_k (the running sum carried in ``level``); returns the new level.

    With b = 0 this is white noise, with a = b a random walk, and in general white noise plus a
    random walk driven by the same normals (see ``Model.simulate_fast``).
    """
    for t in range(x.size):
        x[t] += a * z[t] + level
        level += b * z[t]
    return level


@njit(cache=True)
def add_ar1(x: np.ndarray, z: np.ndarray, phi: float, s: float, state: float) -> float:
    """x_t += y_t, y_t = phi y_{t-1} + s z_t (``state`` = y before the block); returns the last y."""
    for t in range(x.size):
        state = phi * state + s * z[t]
        x[t] += state
    return state


@njit(cache=True)
def add_quantization(x: np.ndarray, u: np.ndarray, q: float, v: float) -> float:
    """x_t += q (u_t - v_{t-1}) with v_{t-1} the previous uniform (``v`` before the block)."""
    for t in range(x.size):
        x[t] += q * (u[t] - v)
        v = u[t]
    return v


@njit(cache=True)
def add_drift(x: np.ndarray, omega: float, t0: int) -> None:
    """x_t += omega t, t = t0, t0 + 1, ..."""
    for t in range(x.size):
        x[t] += omega * (t0 + t)


@njit(cache=True)
def add_sinusoid(x: np.ndarray, alpha: float, beta: float, phase: float, t0: int) -> None:
    """x_t += alpha sin(beta t + phase), t = t0, t0 + 1, ...: sin and cos evaluated at the block's
    first sample and rotated by beta from there (relative error ~ block length x 1e-16)."""
    s = math.sin(beta * t0 + phase)
    c = math.cos(beta * t0 + phase)
    sb = math.sin(beta)
    cb = math.cos(beta)
    for t in range(x.size):
        x[t] += alpha * s
        s, c = s * cb + c * sb, c * cb - s * sb
