"""Confidence intervals of the Haar wavelet variance (WV) and so of the Allan variance.

Both kinds are chi-square intervals ``[eta nu_hat / q(1 - alpha/2), eta nu_hat / q(alpha/2)]``
(``q`` the quantiles of a chi-square with ``eta`` degrees of freedom), so they stay positive; they
differ in the equivalent degrees of freedom (EDF) ``eta_j = 2 nu_j**2 / Var(nu_hat_j)``.

``"eta3"``: Percival's ``eta_3 = max(M_j / 2**j, 1)`` (Percival & Walden 2000, ch. 8; R ``wv`` and
``simts``). It ignores the noise type. For large M_j the exact EDF of the estimator is
3 M_j / 2**j for white noise, about 1.9 M_j / 2**j for a random walk and 0.7 M_j or more for
quantization noise, so these intervals are conservative.

``"mixture"`` (the default): the EDF of the noise mixture identified around each level.

1. Dictionary. Unit-amplitude Gaussian processes whose Haar coefficients' autocovariance is known
   exactly: the power laws QN (WV slope -2 in log-log), WN (-1), flicker (0), RW (+1), and
   first-order Gauss-Markov (AR1) processes with correlation times ``2**k`` samples, whose WV
   rises like a RW below and falls like a WN above their correlation time (a hump, which no sum
   of power laws has).
2. Local identification. At level ``j`` a non-negative least-squares fit of the dictionary
   (the power laws and the AR1 with correlation time within 3 octaves of ``tau_j``) to the
   estimated WV at the levels within 3 octaves of ``j``, residuals relative to ``nu_hat_i`` and
   weighted by ``eta_3(i)`` (each level's precision, up to a factor that varies little).
3. EDF. With the fitted amplitudes ``a``, the Gaussian variance of the WV estimate
   ``Var(nu_hat_j) = 2/M_j**2 sum_{|h|<M_j} (M_j - |h|) s_j(h)**2`` (``s_j`` = autocovariance of
   the level-j coefficients under the fitted mixture, Percival & Walden 2000, ch. 8, the exact
   finite-M form), i.e. ``eta_j = M_j nu_j**2 / (a' B_j a)`` with
   ``B_j[k, l] = sum_{|h|<M_j} (1 - |h|/M_j) s_jk(h) s_jl(h)`` precomputed per atom pair.

Guard: a QN atom (the steepest decay, ``tau**-2``) has the largest EDF by far (its coefficients
are correlated only at lags 0, tau/2, tau). A WV that falls like ``tau**-2`` beyond a sinusoid's
band, or by chance at the noisy last levels, must not be read as QN (the intervals would be far
too narrow), so the QN amplitude at level ``j`` is capped by the WV at every finer level (a QN
whose WV exceeds the observed WV at a finer level is impossible).

What it cannot see (the WV does not tell), all on the conservative side: a deterministic drift
or sinusoid is treated as noise with the same WV, so levels they dominate get wider intervals
than the (nearly zero) sampling variability of their WV needs; QN's uniform innovations make its
WV estimate less variable than a Gaussian's (fourth cumulant -1.2 Q2**2: the EDF is up to 1.45x
the Gaussian one), so QN-dominated levels over-cover. ``benchmarks/bench_wv_coverage.py``
measures the coverage over a grid of processes and lengths (table in ``benchmarks/README.md``).

Cost: the per-level tables depend only on ``(T, levels)`` and are cached; each WV then costs one
batched NNLS (a 7 x 11 problem per level). The rule uses only the WV itself and T, so it
applies equally to a streamed WV and to a WV read from a table (without coefficients): a table
of the same levels gets exactly the interval its signal would.
"""

from __future__ import annotations

from functools import lru_cache
from itertools import pairwise

import numpy as np

from gmwm.errors import InputError

__all__ = ["CI_KINDS", "DEFAULT_CI", "check_ci_kind", "edof_for", "eta3_edof", "implied_edof",
           "mixture_edof", "power_law_wv_cov"]

CI_KINDS = ("mixture", "eta3")
DEFAULT_CI = "mixture"

_POWER_LAWS = ("QN", "WN", "FN", "RW")
_NP = len(_POWER_LAWS)
_HALF = 3.0          # octaves each side: fit window (levels) and AR1 correlation times
_AR_STEP = 1.0       # octaves between the AR1 atoms' correlation times


def check_ci_kind(ci: str) -> str:
    """``ci`` if it names an interval kind (:data:`CI_KINDS`), else an InputError."""
    if not isinstance(ci, str) or ci not in CI_KINDS:
        raise InputError(f"unknown ci {ci!r}; use one of {', '.join(CI_KINDS)}")
    return ci


def eta3_edof(n: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Percival's ``eta_3 = max(M_j / tau_j, 1)``."""
    return np.maximum(np.asarray(n) / np.asarray(scales, dtype=np.float64), 1.0)


# --------------------------------------------------------------------------------------------------
# autocovariances of the level-j Haar coefficients of the dictionary's processes
#
# W_{j,t} = (S_t - 2 S_{t-m} + S_{t-2m}) / tau (S = partial sums of X, m = tau / 2), so
# s_j(h) = sum_{a,b} alpha_a alpha_b K(h - a + b) / tau**2 with alpha = (1, -2, 1) at (0, m, 2m) and
# K the generalised covariance of S: QN delta(n), WN -|n|/2, RW (|n|^3 - |n|)/12, flicker n^2 ln|n|
# (the H -> 1 limit of fractional noise, the sampled continuous process), AR1 (unit variance,
# phi = exp(-a)) -P (phi^|n| + sinh(a) |n|), P = phi (1 - phi^2) / ((1 - phi)^3 (1 + phi)).

_C5 = ((0, 6.0), (-1, -4.0), (1, -4.0), (-2, 1.0), (2, 1.0))   # (shift in m, weight)


def _e3(x: np.ndarray) -> np.ndarray:
    """``exp(-x) - 1 + x - x**2/2`` for x >= 0 without cancellation (series below 0.5)."""
    out = np.expm1(-x) + x - 0.5 * x * x
    small = x < 0.5
    if np.any(small):
        xs = x[small]
        term = -xs**3 / 6.0
        s = term.copy()
        for k in range(4, 18):
            term = term * (-xs / k)
            s += term
        out[small] = s
    return out


def _k_power(kind: str, n: np.ndarray) -> np.ndarray:
    a = np.abs(n)
    if kind == "QN":
        return (a == 0).astype(np.float64)
    if kind == "WN":
        return -0.5 * a
    if kind == "RW":
        return (a**3 - a) / 12.0
    return a * a * np.log(np.where(a > 0, a, 1.0))      # FN


def _acvs_power(kind: str, m: int, h: np.ndarray) -> np.ndarray:
    """Autocovariance at lags ``h >= 0`` of the level (half length m) coefficients of a power law."""
    s = sum(c * _k_power(kind, h + d * m) for d, c in _C5)
    if kind == "FN":
        # far from the filter the fourth difference of n^2 ln n cancels: use its expansion
        far = h > 64.0 * m
        if np.any(far):
            hf = h[far]
            s[far] = -2.0 * m**4 / hf**2 - 2.0 * m**6 / hf**4
    else:
        s = np.where(h > 2 * m, 0.0, s)    # finite filters: exactly zero beyond the overlap
    return s / (2.0 * m) ** 2


def _acvs_ar1(a: np.ndarray, m: int, h: np.ndarray) -> np.ndarray:
    """Same for unit-variance AR1 atoms with ``phi = exp(-a)``: shape ``(a.size, h.size)``, in
    forms free of cancellation (the e3 form while ``2 a m <= 2``, the phi^n form beyond)."""
    a = np.asarray(a, dtype=np.float64)[:, None]
    h = np.asarray(h, dtype=np.float64)[None, :]
    phi = np.exp(-a)
    p = phi * -np.expm1(-2.0 * a) / ((-np.expm1(-a)) ** 3 * (1.0 + phi))
    near = h < 2 * m
    # outside the overlap: -P phi^(h - 2m) (phi^(-m/2) - phi^(m/2))^4
    x = 0.5 * a * m
    log2sinh = x + np.log(-np.expm1(-2.0 * x))
    out = -p * np.exp(np.where(near, 0.0, -a * h + 4.0 * log2sinh))
    if np.any(near):
        small = (2.0 * a * m <= 2.0)[:, 0]
        hn = h[:, near[0]]
        acc = np.zeros((a.shape[0], hn.shape[1]))
        sm = np.sinh(a[small]) - a[small]
        psh = p[~small] * np.sinh(a[~small])
        for d, c in _C5:
            n = np.abs(hn + d * m)
            if np.any(small):
                acc[small] += c * -p[small] * (_e3(a[small] * n) + sm * n)
            if not np.all(small):
                acc[~small] += c * (-p[~small] * np.exp(-a[~small] * n) - psh * n)
        out[:, near[0]] = acc
    return out / (2.0 * m) ** 2


def _lattice(breaks: list[int], dense: int = 16, ratio: float = 1.08
             ) -> tuple[np.ndarray, np.ndarray]:
    """Integer points of ``[breaks[0], breaks[-1]]`` for a lattice sum ``sum_h f(h)`` of a
    function smooth between the ``breaks``: every point within ``dense`` of a break, geometrically
    spaced points in between, with trapezoid weights (each sampled point stands for itself and
    half the unsampled points on either side)."""
    ends = sorted(set(breaks))
    pts = [np.array(ends[:1])]
    span = max(ends[-1] - ends[0], 2)
    n_geo = int(np.ceil(np.log(max(span / dense, 1.0 + 1e-9)) / np.log(ratio))) + 2
    geo = np.unique(np.round(dense * ratio ** np.arange(max(n_geo, 1)))).astype(np.int64)
    for a, b in pairwise(ends):
        if b - a <= 4 * dense:
            pts.append(np.arange(a, b + 1))
            continue
        mid = (a + b) // 2
        near = np.arange(dense + 1)
        g = geo[geo < mid - a]
        pts += [a + near, b - near, a + g, b - g]
    h = np.unique(np.concatenate(pts))
    h = h[(h >= ends[0]) & (h <= ends[-1])]
    w = np.ones(h.size)
    if h.size > 1:
        gaps = np.diff(h) - 1.0
        w[1:] += 0.5 * gaps
        w[:-1] += 0.5 * gaps
    return h.astype(np.float64), w


def _lag_grid(m: int, M: int) -> tuple[np.ndarray, np.ndarray]:
    """Lags ``0..M-1`` of one level's coefficients (kinks of their autocovariance at 0, m, 2m)."""
    return _lattice([0, *[k for k in (m, 2 * m) if k < M - 1], M - 1])


def _ar_times(levels: tuple[int, ...]) -> np.ndarray:
    """log2 correlation times of the AR1 atoms (samples), covering every level's window."""
    lo, hi = min(levels) - _HALF, max(levels) + _HALF
    return np.arange(np.floor(lo / _AR_STEP), np.ceil(hi / _AR_STEP) + 1) * _AR_STEP


#: correlation-time exponents of the AR1 atoms whose WV at each level is tabulated once
_LT_TABLE = np.arange(-16.0, 65.0)


@lru_cache(maxsize=128)
def _level_wv(j: int) -> np.ndarray:
    """WV at level ``j`` of the power laws and of the AR1 atoms ``_LT_TABLE`` (read-only)."""
    m = 1 << (j - 1)
    zero = np.zeros(1)
    with np.errstate(all="ignore"):
        out = np.concatenate([[_acvs_power(k, m, zero)[0] for k in _POWER_LAWS],
                              _acvs_ar1(2.0**-_LT_TABLE, m, zero)[:, 0]])
    out.flags.writeable = False
    return out


@lru_cache(maxsize=128)
def _level_near(j: int, lt_sel: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Lattice points of level ``j`` up to the overlap ``2m`` (the same in every lag grid
    reaching beyond ``2m``: :func:`_lag_grid`) and the autocovariances there of the power laws
    and of the AR1 atoms ``lt_sel``, where the e3 series make them costly. Read-only."""
    m = 1 << (j - 1)
    h = _lattice([0, m, 2 * m])[0]
    S = _atom_acvs(m, np.asarray(lt_sel, dtype=np.float64), h)
    h.flags.writeable = S.flags.writeable = False
    return h, S


#: the geometric steps of :func:`_lattice` (dense 16, ratio 1.08), far enough for any length
_GEO = np.unique(np.round(16 * 1.08 ** np.arange(420))).astype(np.int64)


def _far_grid(m: int, M: int, h_near: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_lag_grid` (same points, same weights) from its part up to ``2m``, ``h_near``,
    when the last lag ``M - 1`` lies beyond ``2m + 64``: only the part beyond is built."""
    a, b = 2 * m, M - 1
    g = _GEO[_GEO < (a + b) // 2 - a]
    near = np.arange(17)
    far = np.unique(np.concatenate([a + near, b - near, a + g, b - g]))
    h = np.concatenate([h_near[:-1], far.astype(np.float64)])
    w = np.ones(h.size)
    gaps = np.diff(h) - 1.0
    w[1:] += 0.5 * gaps
    w[:-1] += 0.5 * gaps
    return h, w


def _far_acvs(m: int, lt_sel: np.ndarray, h: np.ndarray) -> np.ndarray:
    """:func:`_atom_acvs` at lags ``h > 2m``, where the finite power-law filters no longer
    overlap (QN, WN and RW exactly 0) and the AR1 atoms are in their product form."""
    out = np.zeros((_NP + lt_sel.size, h.size))
    out[_POWER_LAWS.index("FN")] = _acvs_power("FN", m, h)
    out[_NP:] = _acvs_ar1(2.0**-lt_sel, m, h)
    return out


def _atom_acvs(m: int, lt_sel: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Autocovariances at lags ``h`` of the power laws and the AR1 atoms ``lt_sel`` (rows)."""
    return np.vstack([np.array([_acvs_power(k, m, h) for k in _POWER_LAWS]),
                      _acvs_ar1(2.0**-lt_sel, m, h)])


@lru_cache(maxsize=32)
def _tables(n_samples: int, levels: tuple[int, ...]
            ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Per level: the WV of every atom (``nu[j, k]``), the atoms used at level j (``sel[j]``) and
    ``B[j]`` (their lag sums, finite-M weights); the correlation-time exponents of the AR1 atoms.
    The length-free parts are tabulated once (:func:`_level_wv`, :func:`_level_near`): a plan
    evaluates many lengths."""
    lt = _ar_times(levels)
    n_atoms = _NP + lt.size
    nu = np.empty((len(levels), n_atoms))
    sels, bs = [], []
    with np.errstate(over="ignore", under="ignore"):
        for i, j in enumerate(levels):
            m = 1 << (j - 1)
            M = n_samples - 2 * m + 1
            lo = int(lt[0] - _LT_TABLE[0])
            if lo >= 0 and lt[-1] <= _LT_TABLE[-1]:
                nu[i] = _level_wv(j)[np.r_[:_NP, _NP + lo:_NP + lo + lt.size]]
            else:
                nu[i, :_NP] = _level_wv(j)[:_NP]
                nu[i, _NP:] = _acvs_ar1(2.0**-lt, m, np.zeros(1))[:, 0]
            sel = np.concatenate([np.arange(_NP), _NP + np.flatnonzero(np.abs(lt - j) <= _HALF)])
            lt_sel = lt[sel[_NP:] - _NP]
            h_near, S_near = _level_near(j, tuple(lt_sel.tolist()))
            if M - 1 > 2 * m + 64:
                h, w = _far_grid(m, M, h_near)
                S = np.hstack([S_near, _far_acvs(m, lt_sel, h[h_near.size:])])
            else:  # the lattice ends at or soon after the overlap
                h, w = _lag_grid(m, M)
                S = _atom_acvs(m, lt_sel, h)
            S = S * np.sign(S[:, :1])        # FN's K has the opposite sign convention
            wt = w * (1.0 - h / M)
            wt[1:] *= 2.0                    # lags +h and -h
            sels.append(sel)
            bs.append((S * wt) @ S.T)
    nu[:, :_NP] = np.abs(nu[:, :_NP])
    return nu, sels, bs, lt


def _nnls(G: np.ndarray, c: np.ndarray, max_iter: int = 200) -> np.ndarray:
    """Batched non-negative least squares: for each problem ``b``, the ``x >= 0`` minimising
    ``|A x - y|`` given its normal equations ``G[b] = A'A``, ``c[b] = A'y`` (Lawson & Hanson's
    active set, all problems stepped together). Written here: the problems are tiny, and
    importing SciPy's optimize costs ~1 s of a CLI call."""
    nb, n = c.shape
    eye = np.eye(n, dtype=bool)
    x = np.zeros((nb, n))
    passive = np.zeros((nb, n), dtype=bool)
    inner = np.zeros(nb, dtype=bool)        # inside the inner loop (a solve is pending)
    done = np.zeros(nb, dtype=bool)
    tol = 1e-12 * np.maximum(np.abs(c).max(axis=1), 1e-300)
    rows = np.arange(nb)
    for _ in range(max_iter):
        outer = ~done & ~inner
        if np.any(outer):
            w = c - np.einsum("bij,bj->bi", G, x)
            w[passive] = -np.inf
            k = np.argmax(w, axis=1)
            add = outer & (w[rows, k] > tol)
            done |= outer & ~add
            passive[rows[add], k[add]] = True
            inner |= add
        if not np.any(inner):
            break
        both = passive[:, :, None] & passive[:, None, :]
        Gm = np.where(both | (~passive[:, :, None] & eye), np.where(both, G, 1.0), 0.0)
        z = np.linalg.solve(Gm[inner], np.where(passive, c, 0.0)[inner][..., None])[..., 0]
        zi = np.zeros((nb, n))
        zi[inner] = z
        bad = inner & np.any(passive & (zi <= 0), axis=1)
        good = inner & ~bad
        x[good] = zi[good]
        inner &= ~good
        if np.any(bad):
            xb, zb, pb = x[bad], zi[bad], passive[bad]
            neg = pb & (zb <= 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(neg, xb / (xb - zb), np.inf)
            t = np.min(ratio, axis=1)[:, None]
            xb = xb + t * (zb - xb)
            pb &= xb > 1e-14 * np.maximum(xb.max(axis=1, keepdims=True), 1e-300)
            xb[~pb] = 0.0
            x[bad], passive[bad] = xb, pb
    return x


def mixture_edof(variance: np.ndarray, scales: np.ndarray, n_samples: int) -> np.ndarray:
    """EDF of each level's WV estimate under the noise mixture fitted around it (module
    docstring). ``scales`` are filter lengths ``tau_j = 2**j`` samples (any increasing subset of
    levels), ``n_samples`` = T of the signal; levels whose WV is not positive get ``eta_3``."""
    var = np.asarray(variance, dtype=np.float64)
    sc = np.asarray(scales, dtype=np.float64)
    T = int(n_samples)
    levels = tuple(int(v) for v in np.round(np.log2(sc)))
    n = T - sc + 1
    out = eta3_edof(n, sc)
    ok = np.isfinite(var) & (var > 0)
    if not np.any(ok):
        return out
    nu, sels, bs, _ = _tables(T, levels)
    lev = np.asarray(levels, dtype=np.float64)
    prec = np.sqrt(eta3_edof(n, sc))
    # QN cap: its WV (~tau^-2) may not exceed the estimated WV at any finer level
    qcap = np.minimum.accumulate(np.where(ok, var / nu[:, 0], np.inf))
    idx = np.flatnonzero(ok)
    sel = np.array([sels[i] for i in idx])                      # (B, K): same K at every level
    win = ok[None, :] & (np.abs(lev[None, :] - lev[idx, None]) <= _HALF)   # (B, L) window rows
    rel = np.where(win, prec / np.where(ok, var, 1.0), 0.0)     # row weights sqrt(eta3) / nu_hat
    A = nu.T[sel] * rel[:, None, :]                             # (B, K, L) = A'
    norm = np.sqrt(np.einsum("bkl,bkl->bk", A, A))
    A /= norm[..., None]
    y = np.where(win, prec, 0.0)
    G = np.einsum("bkl,bml->bkm", A, A)
    c = np.einsum("bkl,bl->bk", A, y)
    x = _nnls(G, c)
    capped = x[:, 0] > qcap[idx] * norm[:, 0]
    if np.any(capped):
        x0 = qcap[idx][capped] * norm[capped, 0]
        rest = _nnls(G[capped][:, 1:, 1:], c[capped][:, 1:] - G[capped][:, 1:, 0] * x0[:, None])
        x[capped] = np.concatenate([x0[:, None], rest], axis=1)
    x /= norm
    nu_fit = np.einsum("bk,bk->b", nu[idx[:, None], sel], x)
    quad = np.einsum("bk,bkm,bm->b", x, np.array([bs[i] for i in idx]), x)
    good = (nu_fit > 0) & (quad > 0)
    out[idx[good]] = np.maximum(n[idx[good]] * nu_fit[good] ** 2 / quad[good], 1.0)
    return out


def power_law_wv_cov(kind: str, levels: np.ndarray, n_samples: int) -> np.ndarray:
    """Gaussian covariance ``Cov(nu_hat_j, nu_hat_k)`` of the WV estimates at ``levels`` for a
    unit-amplitude power law ``kind`` ("QN", "WN", "FN" flicker, "RW") and T = ``n_samples``:
    ``2 / (M_j M_k) sum_h N_jk(h) g_jk(h)**2`` with the exact lag counts ``N_jk`` and the
    cross-covariance ``g_jk(h) = Cov(W_{j,t}, W_{k,t-h})`` of the coefficients (the form of
    Percival & Walden 2000, ch. 8; ``gmwm.wvcov`` has it for every model, this one needs only
    NumPy). Used for the correlation between the levels of an Allan-deviation slope line."""
    if kind not in _POWER_LAWS:
        raise InputError(f"unknown power law {kind!r}; use one of {', '.join(_POWER_LAWS)}")
    lev = np.asarray(levels, dtype=np.int64).reshape(-1)
    T = int(n_samples)
    tau = (1 << lev).astype(np.float64)
    out = np.empty((lev.size, lev.size))
    if len(_PAIRS) > 4096:
        _PAIRS.clear()
    for i, tj in enumerate(tau):
        for k in range(i, lev.size):
            key = (kind, T, int(lev[i]), int(lev[k]))
            if key in _PAIRS:
                out[i, k] = out[k, i] = _PAIRS[key]
                continue
            tk = tau[k]
            offs_j = (0.0, tj / 2, tj)
            offs_k = (0.0, tk / 2, tk)
            lo, hi = int(tj - T), int(T - tk)                # lags with pairs (t, t - h)
            if kind != "FN":                                  # filters overlap only there
                lo, hi = max(lo, int(-tk - 1)), min(hi, int(tj + 1))
            kinks = [int(a - b) for a in offs_j for b in offs_k]
            h, w = _lattice([lo, hi, *[q for q in kinks if lo < q < hi]])
            g = np.zeros_like(h)
            for a, ca in zip(offs_j, (1.0, -2.0, 1.0), strict=True):
                for b, cb in zip(offs_k, (1.0, -2.0, 1.0), strict=True):
                    g += ca * cb * _k_power(kind, h - a + b)
            g /= tj * tk
            count = np.minimum(T, T + h) - np.maximum(tj, tk + h) + 1.0
            val = 2.0 * float(np.sum(w * np.clip(count, 0.0, None) * g * g)) / (
                (T - tj + 1.0) * (T - tk + 1.0))
            out[i, k] = out[k, i] = _PAIRS[key] = val
    return out


#: entries of :func:`power_law_wv_cov` already computed in this process, by (kind, T, level j,
#: level k): each depends on nothing else, and the Allan readings of a recording's axes ask for
#: overlapping runs of the same levels at the same length
_PAIRS: dict[tuple[str, int, int, int], float] = {}


def edof_for(ci: str, variance: np.ndarray, scales: np.ndarray, n: np.ndarray, n_samples: int,
             efficiency: float = 1.0) -> np.ndarray:
    """EDF of the interval kind ``ci`` (times the estimator's Gaussian efficiency, 1 for the
    classical WV; a robust WV's variance ratio to the classical one is at most 1/efficiency)."""
    check_ci_kind(ci)
    if ci == "eta3":
        return efficiency * eta3_edof(n, scales)
    return efficiency * mixture_edof(variance, scales, n_samples)


def implied_edof(low: np.ndarray, high: np.ndarray, alpha: float) -> np.ndarray:
    """The EDF of the chi-square interval at level ``1 - alpha`` with the ratio ``high / low`` of
    given bounds (for bounds read from a table; ``inf`` when ``high == low``)."""
    from scipy.special import chdtri

    low = np.asarray(low, dtype=np.float64)
    high = np.asarray(high, dtype=np.float64)
    target = np.log(high / low)
    lo_e = np.full(target.shape, 1e-3)
    hi_e = np.full(target.shape, 1e12)
    for _ in range(80):       # bisection in log(eta): log q(1-a/2) - log q(a/2) decreases in eta
        mid = np.sqrt(lo_e * hi_e)
        r = np.log(chdtri(mid, alpha / 2.0)) - np.log(chdtri(mid, 1.0 - alpha / 2.0))
        big = r > target
        lo_e = np.where(big, mid, lo_e)
        hi_e = np.where(big, hi_e, mid)
    out = np.sqrt(lo_e * hi_e)
    return np.where(target > 0, out, np.inf)
