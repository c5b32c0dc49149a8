"""Loosely coupled INS/GNSS error-state EKF, vectorised over a batch of independent runs.

Frames and conventions (all SI: m, m/s, rad, rad/s, s):

* navigation frame: local-level East-North-Up (ENU), flat and non-rotating, constant gravity
  ``g_n = (0, 0, -g)``; adequate for a 235 s, few-km flight emulated and filtered with the same
  assumptions (no model mismatch between the truth generator and the filter);
* body frame: Forward-Left-Up; ``C`` is the body-to-navigation rotation matrix;
* strapdown mechanisation per IMU sample k (rate ``omega_k``, specific force ``f_k``, held over
  the interval): ``C_{k+1} = C_k Exp(omega_k dt)``, ``v_{k+1} = v_k + (C_k Exp(omega_k dt/2) f_k
  + g_n) dt``, ``p_{k+1} = p_k + (v_k + v_{k+1}) dt / 2``;
* errors are truth minus estimate: ``dp = p - p^``, ``dv = v - v^``, attitude ``C = Exp(eps) C^``
  (``eps`` in the navigation frame), gyro error ``db = b - b^``;
* gyroscope error model on the axes ``axes`` (indices into x, y, z): ``b = a + r`` with ``a`` an
  AR1 (phi, innovation variance sigma2) and ``r`` a random walk (innovation variance gamma2), both
  per IMU sample in (rad/s)^2; gyro axes outside ``axes`` are error-free. Accelerometers carry
  white noise of known per-sample SD ``accel_sd`` on every axis (same in truth and filter).

Error state (n = 9 + 2 m): ``[dp(3), dv(3), eps(3), a(m), r(m)]``; GNSS position fixes with
isotropic-per-axis SD ``gnss_sd``. Closed loop: after each update the estimated errors are fed back
into the navigation solution and the error state is reset to zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gmwm.errors import InputError

__all__ = [
    "G0",
    "FilterSetup",
    "exp_so3",
    "log_so3",
    "mechanize",
    "run_filter",
    "skew",
]

G0 = 9.80665  # standard gravity [m/s^2]


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v x]`` of vectors ``v`` (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def exp_so3(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices ``Exp(phi)`` of rotation vectors ``phi`` (..., 3) [rad] (Rodrigues)."""
    phi = np.asarray(phi, dtype=float)
    th2 = np.sum(phi * phi, axis=-1)
    th = np.sqrt(th2)
    small = th2 < 1e-12
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    K = skew(phi)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vectors of rotation matrices ``R`` (..., 3, 3); angles below pi."""
    R = np.asarray(R, dtype=float)
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(cos)
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], -1)
    small = th < 1e-6
    scale = np.where(small, 0.5 + th * th / 12.0, th / (2.0 * np.sin(np.where(small, 1.0, th))))
    return scale[..., None] * w


def mechanize(p0: np.ndarray, v0: np.ndarray, C0: np.ndarray, gyro: np.ndarray,
              accel: np.ndarray, dt: float, g: float = G0) -> tuple[np.ndarray, ...]:
    """Free-inertial integration of one IMU record (no aiding); returns p, v, C at every epoch
    (N + 1 rows for N samples). Used to generate and to check the ideal IMU of a trajectory."""
    n = len(gyro)
    p = np.empty((n + 1, 3))
    v = np.empty((n + 1, 3))
    C = np.empty((n + 1, 3, 3))
    p[0], v[0], C[0] = p0, v0, C0
    gn = np.array([0.0, 0.0, -g])
    dR = exp_so3(gyro * dt)
    dRh = exp_so3(gyro * dt / 2)
    for k in range(n):
        fn = C[k] @ dRh[k] @ accel[k]
        C[k + 1] = C[k] @ dR[k]
        v[k + 1] = v[k] + (fn + gn) * dt
        p[k + 1] = p[k] + (v[k] + v[k + 1]) * dt / 2
    return p, v, C


@dataclass(frozen=True)
class FilterSetup:
    """Fixed settings of the filter and of the emulated sensors (SI units, per IMU sample).

    ``axes``: gyro axes (0 = x forward, 1 = y left, 2 = z up) carrying the AR1 + RW error model.
    ``p0_sd``: initial SDs of (position [m], velocity [m/s], roll/pitch [rad], yaw [rad]).
    """

    dt: float
    axes: tuple[int, ...]
    accel_sd: float
    gnss_sd: tuple[float, float, float]
    p0_sd: tuple[float, float, float, float]
    g: float = G0

    @property
    def m(self) -> int:
        return len(self.axes)

    @property
    def n(self) -> int:
        return 9 + 2 * self.m

    def initial_nav_cov(self) -> np.ndarray:
        """Diagonal of the initial covariance of (dp, dv, eps)."""
        sp, sv, sa, sy = self.p0_sd
        return np.array([sp] * 3 + [sv] * 3 + [sa, sa, sy]) ** 2


def _check_params(params: np.ndarray, batch: int) -> np.ndarray:
    params = np.asarray(params, dtype=float)
    if params.shape != (batch, 3):
        raise InputError(f"filter parameters must have shape ({batch}, 3) (phi, sigma2, gamma2), "
                         f"got {params.shape}")
    phi, s2, g2 = params.T
    if not (np.all(np.abs(phi) < 1) and np.all(s2 >= 0) and np.all(g2 >= 0)):
        raise InputError("filter parameters need |phi| < 1 and non-negative variances")
    return params


def run_filter(
    setup: FilterSetup,
    params: np.ndarray,
    gyro: np.ndarray,
    accel: np.ndarray,
    gnss_steps: np.ndarray,
    gnss_pos: np.ndarray,
    p_init: np.ndarray,
    v_init: np.ndarray,
    C_init: np.ndarray,
    truth_p: np.ndarray,
    truth_C: np.ndarray | None = None,
    record_every: int = 10,
) -> dict[str, np.ndarray]:
    """Run B filters in lockstep over N IMU samples.

    ``params`` (B, 3): each filter's (phi, sigma2, gamma2) of the gyro error model, per sample,
    (rad/s)^2. ``gyro``, ``accel`` (B, N, 3): measurements. ``gnss_steps`` (K,): epoch index (1..N)
    after which a fix is processed; ``gnss_pos`` (B, K, 3) the fixes. ``p_init, v_init`` (B, 3),
    ``C_init`` (B, 3, 3): initial estimates. ``truth_p`` (N + 1, 3) and optionally ``truth_C``
    (N + 1, 3, 3): the true trajectory, for the recorded errors.

    Returns, at epochs ``0, record_every, 2 record_every, ...`` (after any update at that epoch):
    ``step`` (R,), ``pos_err`` (B, R, 3) truth minus estimate, ``pos_cov`` (B, R, 3, 3) the filter's
    covariance of it, and if ``truth_C`` is given ``att_err`` (B, R, 3) and ``att_cov`` (B, R, 3, 3).
    """
    gyro = np.asarray(gyro, dtype=float)
    accel = np.asarray(accel, dtype=float)
    B, N, _ = gyro.shape
    params = _check_params(params, B)
    if accel.shape != gyro.shape:
        raise InputError(f"accel shape {accel.shape} differs from gyro shape {gyro.shape}")
    dt, m, n = setup.dt, setup.m, setup.n
    ax = list(setup.axes)
    phi, s2, g2 = params[:, 0], params[:, 1], params[:, 2]
    ia, ir = slice(9, 9 + m), slice(9 + m, 9 + 2 * m)

    p = np.array(p_init, dtype=float)
    v = np.array(v_init, dtype=float)
    C = np.array(C_init, dtype=float)
    xa = np.zeros((B, m))
    xr = np.zeros((B, m))
    P = np.zeros((B, n, n))
    idx = np.arange(9)
    P[:, idx, idx] = setup.initial_nav_cov()
    ja, jr = np.arange(9, 9 + m), np.arange(9 + m, 9 + 2 * m)
    P[:, ja, ja] = (s2 / (1.0 - phi * phi))[:, None]  # stationary AR1
    P[:, jr, jr] = g2[:, None]  # the RW's first sample

    # Process noise: accelerometer white noise enters dv and dp through C_mid; with the same SD on
    # every axis C_mid diag(sd^2) C_mid^T = sd^2 I, so that block is constant.
    Q = np.zeros((B, n, n))
    sa2 = setup.accel_sd**2
    for i in range(3):
        Q[:, i, i] = sa2 * dt**4 / 4
        Q[:, i, 3 + i] = Q[:, 3 + i, i] = sa2 * dt**3 / 2
        Q[:, 3 + i, 3 + i] = sa2 * dt**2
    Q[:, ja, ja] = s2[:, None]
    Q[:, jr, jr] = g2[:, None]

    Phi = np.zeros((B, n, n))
    Phi[:, np.arange(n), np.arange(n)] = 1.0
    for i in range(3):
        Phi[:, i, 3 + i] = dt
    Phi[:, ja, ja] = phi[:, None]

    R = np.diag(np.asarray(setup.gnss_sd, dtype=float) ** 2)
    gn = np.array([0.0, 0.0, -setup.g])
    fix_at = {int(s): j for j, s in enumerate(np.asarray(gnss_steps))}
    rec_steps = np.arange(0, N + 1, record_every)
    nrec = len(rec_steps)
    out = {"step": rec_steps, "pos_err": np.empty((B, nrec, 3)),
           "pos_cov": np.empty((B, nrec, 3, 3))}
    if truth_C is not None:
        out["att_err"] = np.empty((B, nrec, 3))
        out["att_cov"] = np.empty((B, nrec, 3, 3))

    def record(r: int, k: int) -> None:
        out["pos_err"][:, r] = truth_p[k] - p
        out["pos_cov"][:, r] = P[:, :3, :3]
        if truth_C is not None:
            out["att_err"][:, r] = log_so3(truth_C[k] @ np.swapaxes(C, -1, -2))
            out["att_cov"][:, r] = P[:, 6:9, 6:9]

    record(0, 0)
    r_next = 1
    I_n = np.eye(n)
    for k in range(N):
        bias = np.zeros((B, 3))
        bias[:, ax] = xa + xr
        w = gyro[:, k] - bias
        dR = exp_so3(w * dt)
        Cmid = C @ exp_so3(w * (dt / 2))
        fn = np.einsum("bij,bj->bi", Cmid, accel[:, k])
        C = C @ dR
        # linearised error dynamics of this step (see module docstring)
        Sf = skew(fn)
        Phi[:, 0:3, 6:9] = -(dt * dt / 2) * Sf
        Phi[:, 3:6, 6:9] = -dt * Sf
        Gb = -dt * C[:, :, ax]
        Phi[:, 6:9, ia] = Gb
        Phi[:, 6:9, ir] = Gb
        P = Phi @ P @ np.swapaxes(Phi, -1, -2) + Q
        v_new = v + (fn + gn) * dt
        p = p + (v + v_new) * (dt / 2)
        v = v_new
        xa = phi[:, None] * xa
        j = fix_at.get(k + 1)
        if j is not None:
            y = gnss_pos[:, j] - p
            S = P[:, :3, :3] + R
            K = np.swapaxes(np.linalg.solve(S, P[:, :3, :]), -1, -2)  # P H^T S^-1 (S symmetric)
            dx = np.einsum("bij,bj->bi", K, y)
            p = p + dx[:, 0:3]
            v = v + dx[:, 3:6]
            C = exp_so3(dx[:, 6:9]) @ C
            xa = xa + dx[:, ia]
            xr = xr + dx[:, ir]
            IKH = np.broadcast_to(I_n, P.shape).copy()
            IKH[:, :, :3] -= K
            P = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)  # Joseph
            P = 0.5 * (P + np.swapaxes(P, -1, -2))
        if r_next < nrec and rec_steps[r_next] == k + 1:
            record(r_next, k + 1)
            r_next += 1
    return out
