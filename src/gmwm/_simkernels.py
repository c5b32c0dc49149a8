"""Numba kernels of the fast simulators: each ``add_*`` kernel adds one component's values to a
block of the signal, carrying the component's state from block to block. A block (a few 10^4
samples) stays in cache, so the signal is written once instead of once per component and per
NumPy operation. Imported lazily, like :mod:`gmwm._ar1kernels`.

Two users: :meth:`gmwm.model.Model.simulate_fast` (NumPy's normals and uniforms, one full-length
signal) and the fused simulation + WV pass :func:`simulate_wv` of the Monte Carlo studies (its
own generator, no full-length signal; see the section below).

``z``/``u`` are the block's standard normals / uniforms on [0, 1); ``t0`` is the 1-based time
of the block's first sample.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from gmwm.errors import ModelError


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
# The fused simulation + WV pass (:func:`simulate_wv`): the signal is generated block by block into
# a buffer that stays in cache and each block goes straight through phase 1 of the WV kernel, so
# no full-length signal exists. Its normals and uniforms come from the generator below rather
# than NumPy's (which costs ~10 ns a normal on the dev VM, most of a replicate's time): xoshiro256++
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


_ZIG_K, _ZIG_W, _ZIG_F = _ziggurat_tables()


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


class _Plan:
    """The components of ``model`` at ``theta`` in the primitive form the block kernels take
    (as in :meth:`gmwm.model.Model.simulate_fast`: WN and RW as one walk-plus-noise stream),
    their start states drawn from ``rng`` (one normal per AR1/GM, one uniform per QN and per
    SIN, in component order), then the xoshiro256++ state from ``rng``."""

    def __init__(self, model: Any, theta: np.ndarray, rng: np.random.Generator,
                 boundary_ok: bool = False) -> None:
        theta = np.asarray(theta, dtype=float)
        model.check(theta, boundary_ok=boundary_ok)
        sigma2 = gamma2 = 0.0
        self.omega = 0.0
        self.ar1: list[list[float]] = []  # [phi, innovation sd, state]
        self.qn: list[list[float]] = []  # [q, previous uniform]
        self.sines: list[tuple[float, float, float]] = []  # (alpha, beta, phase)
        for c in model.components:
            kind, *v = c.process.primitive(theta[c.slice], model.freq)
            if kind == "wn":
                sigma2 += v[0]
            elif kind == "rw":
                gamma2 += v[0]
            elif kind == "dr":
                self.omega += v[0]
            elif kind == "ar1":
                phi, _, s2 = v
                s = math.sqrt(s2)
                self.ar1.append([phi, s, s * rng.standard_normal() / math.sqrt(1.0 - phi * phi)])
            elif kind == "qn":
                self.qn.append([math.sqrt(12.0 * v[0]), rng.random()])
            elif kind == "sin":
                self.sines.append((v[0], v[1], rng.uniform(0.0, 2 * np.pi)))
            else:  # a process added to PROCESSES without a kernel here
                raise ModelError(f"the fused simulator has no kernel for process "
                                 f"{c.process.name!r}")
        self.walk = sigma2 > 0 or gamma2 > 0
        self.a_w = self.b_w = self.level = 0.0
        if self.walk:
            # x_t = a z_t + b sum_{k<t} z_k: increments MA(1) with the variance and lag-1
            # covariance of the increments of WN + RW (derivation: Model.simulate_fast)
            c0 = 2 * sigma2 + gamma2
            g = math.sqrt(gamma2 * (4 * sigma2 + gamma2))
            theta_ma = -2 * sigma2 / (c0 + g)
            self.a_w = math.sqrt(c0 / (1 + theta_ma * theta_ma))
            self.b_w = self.a_w * (gamma2 + g) / (c0 + g)
        self.state = seed_state(rng)

    def fill(self, xb: np.ndarray, t0: int, z: np.ndarray, u: np.ndarray) -> None:
        """Samples ``t0 .. t0 + len(xb) - 1`` (0-based) into ``xb``; ``z``/``u``: work rows
        (one per normal stream / QN) at least as long as ``xb``. Stream per block: the normals
        of the walk (if any), then of each AR1/GM, then the uniforms of each QN."""
        m = xb.size
        xb[:] = 0.0
        i = 0
        if self.walk:
            fill_normals(self.state, z[0, :m], _ZIG_K, _ZIG_W, _ZIG_F)
            self.level = add_walk_noise(xb, z[0, :m], self.a_w, self.b_w, self.level)
            i = 1
        for st in self.ar1:
            fill_normals(self.state, z[i, :m], _ZIG_K, _ZIG_W, _ZIG_F)
            st[2] = add_ar1(xb, z[i, :m], st[0], st[1], st[2])
            i += 1
        for st in self.qn:
            fill_uniforms(self.state, u[0, :m])
            st[1] = add_quantization(xb, u[0, :m], st[0], st[1])
        if self.omega:
            add_drift(xb, self.omega, t0 + 1)
        for alpha, beta, phase in self.sines:
            add_sinusoid(xb, alpha, beta, phase, t0 + 1)

    def work(self, m: int) -> tuple[np.ndarray, np.ndarray]:
        return (np.empty((int(self.walk) + len(self.ar1), m)), np.empty((min(1, len(self.qn)), m)))


#: samples generated per block of the fused pass (a multiple of the WV kernel's block is used)
FUSED_BLOCK = 1 << 15


def simulate_signal(model: Any, theta: np.ndarray, n: int, rng: np.random.Generator,
                    boundary_ok: bool = False) -> np.ndarray:
    """The signal :func:`simulate_wv` draws for the same ``rng`` state, materialised (length
    ``n``): for tests, and for a study that needs the signal itself. Equal in distribution to
    :meth:`gmwm.model.Model.simulate_fast`'s (up to an additive constant), other numbers."""
    n = int(n)
    if n < 1:
        raise ModelError(f"number of samples must be positive, got {n}")
    plan = _Plan(model, theta, rng, boundary_ok)
    x = np.empty(n)
    z, u = plan.work(min(FUSED_BLOCK, n))
    for start in range(0, n, FUSED_BLOCK):
        plan.fill(x[start:start + FUSED_BLOCK], start, z, u)
    return x


def simulate_wv(model: Any, theta: np.ndarray, n: int, rng: np.random.Generator,
                levels: int | None = None, boundary_ok: bool = False) -> np.ndarray:
    """Wavelet variances ``nu_1..nu_J`` (Haar, as :func:`gmwm.wv.wvar`'s ``variance``; J =
    ``levels``, default floor(log2 n) - 1) of the signal :func:`simulate_signal` would return,
    computed without it: each block of samples is generated into a buffer (with the
    ``2**L - 1`` samples of halo phase 1 needs) and passed through phase 1 of the WV kernel in
    the kernel's own block order, so the result has the bits of ``wvar(simulate_signal(...))``
    (tests/test_simkernels.py). Memory: the phase-2 store (~8 bytes a sample) when J > L, as in
    ``wvar``. One thread."""
    from gmwm.wv import _kernels, _n_levels, _Workspace  # the kernel gmwm.stream streams through

    n = int(n)
    J = _n_levels(n, levels)
    plan = _Plan(model, theta, rng, boundary_ok)
    ws = _Workspace(n, J)
    kern = _kernels()
    extra = (1,) if kern.__name__ == "gmwm._haar" else ()
    L = ws.n_block
    halo = (1 << L) - 1
    G = min(n, -(-FUSED_BLOCK // ws.block) * ws.block)  # whole kernel blocks: the same sums order
    buf = np.empty(halo + G)
    z, u = plan.work(G)
    store = ws.store()
    sums = np.zeros(J)
    x0 = 0.0
    h = 0  # samples of halo in front of the block
    for start in range(0, n, G):
        m = min(G, n - start)
        plan.fill(buf[h:h + m], start, z, u)
        if start == 0:
            x0 = float(buf[0])
        kern.phase1(buf[:h + m], start - h, start, start + m, x0, L, ws.block, sums, store, 0,
                    ws.rows, ws.panel, *extra)
        keep = min(halo, h + m)
        buf[:keep] = buf[h + m - keep:h + m]
        h = keep
    if ws.phase2:
        kern.phase2(store, ws.rows, ws.n_out, L, ws.panel, 0, ws.n_panels, J - L, sums, *extra)
    if not np.all(np.isfinite(sums)):
        raise ModelError("the simulated signal overflowed float64 (parameters too large)")
    n_j = n - (1 << np.arange(1, J + 1)) + 1
    return 0.25 * sums / n_j
