"""Numba kernels of the fast simulators: each ``add_*`` kernel adds one component's values to a
block of the signal, carrying the component's state from block to block. A block (a few 10^4
samples) stays in cache, so the signal is written once instead of once per component and per
NumPy operation. Imported lazily, like :mod:`gmwm._ar1kernels`.

Two users: :meth:`gmwm.model.Model.simulate_fast` (NumPy's normals and uniforms, one full-length
signal) and the fused simulation + WV pass of :mod:`gmwm.fused` (its own generator, below; no
full-length signal).

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


# --------------------------------------------------------------------------------------------------
# The generator of the fused simulation + WV pass (:mod:`gmwm.fused`): its normals and uniforms
# come from here rather than from NumPy's (which costs ~10 ns a normal on the dev VM, most of a replicate's time): xoshiro256++
# (Blackman and Vigna) for the bits, a 256-layer ziggurat (Marsaglia and Tsang) for the normals,
# both inlined in one Numba loop.

_U11 = np.uint64(11)
_U12 = np.uint64(12)
_U17 = np.uint64(17)
_U23 = np.uint64(23)
_U41 = np.uint64(41)
_U45 = np.uint64(45)
_U19 = np.uint64(19)
_U8 = np.uint64(8)
_U1 = np.uint64(1)
_U255 = np.uint64(255)
_TWO_M53 = 2.0 ** -53
_ZIG_R = 3.6541528853610088  # right edge of the base layer of the 256-layer ziggurat
_ZIG_V = 0.00492867323399  # area of each layer


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(k, w, f)`` of the 256-layer ziggurat for |Z|: layer ``i`` spans ``[x_{i+1}, x_i)``
    (``x_0 = V / f(R)``, the base layer's equivalent width, ``x_1 = R``, ``x_256 = 0``,
    ``f(x) = exp(-x^2 / 2)``). A 52-bit integer ``j`` with ``j < k_i`` gives ``|Z| = j w_i``
    directly (``w_i = x_i 2^-52``); otherwise the wedge (or, in layer 0, the tail) decides."""
    x = np.empty(257)
    x[0] = _ZIG_V / math.exp(-0.5 * _ZIG_R * _ZIG_R)
    x[1] = _ZIG_R
    for i in range(1, 255):
        x[i + 1] = math.sqrt(-2.0 * math.log(_ZIG_V / x[i] + math.exp(-0.5 * x[i] * x[i])))
    x[256] = 0.0
    k = np.floor(x[1:] / x[:-1] * 2.0 ** 52).astype(np.int64)
    w = x[:-1] * 2.0 ** -52
    f = np.exp(-0.5 * x * x)
    return k, w, f


ZIG_K, ZIG_W, ZIG_F = _ziggurat_tables()


@njit(cache=True, inline="always")
def _rotl(v: np.uint64, k: np.uint64) -> np.uint64:
    return (v << k) | (v >> (np.uint64(64) - k))


@njit(cache=True, inline="always")
def _next(s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64
          ) -> tuple[np.uint64, np.uint64, np.uint64, np.uint64, np.uint64]:
    """One xoshiro256++ step: (64 random bits, new state)."""
    out = _rotl(s0 + s3, _U23) + s0
    t = s1 << _U17
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, _U45)
    return out, s0, s1, s2, s3


@njit(cache=True)
def fill_normals(state: np.ndarray, z: np.ndarray, zk: np.ndarray, zw: np.ndarray,
                 zf: np.ndarray) -> None:
    """``z[:] =`` standard normals from the xoshiro256++ ``state`` (uint64[4], advanced in place;
    ``zk, zw, zf``: :func:`_ziggurat_tables`). One 64-bit draw per normal in ~99 % of the cases:
    bits 0-7 pick the layer, bit 8 the sign, bits 12-63 the position in the layer."""
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for t in range(z.size):
        while True:
            b, s0, s1, s2, s3 = _next(s0, s1, s2, s3)
            i = np.intp(b & _U255)
            j = np.int64(b >> _U12)  # 52 bits: a signed integer converts to float in one step
            v = j * zw[i]
            neg = (b >> _U8) & _U1
            if j < zk[i]:
                break
            if i == 0:  # the tail beyond R (Marsaglia's exponential rejection)
                while True:
                    b, s0, s1, s2, s3 = _next(s0, s1, s2, s3)
                    a = -math.log(1.0 - np.int64(b >> _U11) * _TWO_M53) / _ZIG_R
                    b, s0, s1, s2, s3 = _next(s0, s1, s2, s3)
                    e = -math.log(1.0 - np.int64(b >> _U11) * _TWO_M53)
                    if e + e > a * a:
                        break
                v = _ZIG_R + a
                break
            b, s0, s1, s2, s3 = _next(s0, s1, s2, s3)
            u = np.int64(b >> _U11) * _TWO_M53
            if zf[i] + u * (zf[i + 1] - zf[i]) < math.exp(-0.5 * v * v):
                break
        z[t] = -v if neg else v
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3


@njit(cache=True)
def fill_uniforms(state: np.ndarray, u: np.ndarray) -> None:
    """``u[:] =`` uniforms on [0, 1) (53 bits) from the xoshiro256++ ``state`` (advanced)."""
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for t in range(u.size):
        b, s0, s1, s2, s3 = _next(s0, s1, s2, s3)
        u[t] = np.int64(b >> _U11) * _TWO_M53
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3


def seed_state(rng: np.random.Generator) -> np.ndarray:
    """A xoshiro256++ state (uint64[4], never all zero) drawn from ``rng``."""
    s = rng.integers(0, 2**64, size=4, dtype=np.uint64, endpoint=False)
    if not s.any():
        s[0] = 1
    return s
