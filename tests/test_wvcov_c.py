"""The C twin of gmwm.wvcov's Numba kernels (gmwm._wvcov) gives the same bits."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from conftest import needs_c_kernel
from gmwm import wvcov

# (model, theta, T, levels): AR1 with phi near 1 and with negative phi (on the unit lattice and
# split by parity), two AR1, QN, RW, WN, DR, very long recordings
CASES = [
    ("WN+RW", [1.0, 1e-4], 4096, 10),
    ("WN+AR1", [0.5, 0.999995, 1e-3], 100_000, 15),
    ("WN+AR1", [0.5, -0.5, 0.2], 50_000, 12),
    ("WN+AR1", [0.5, -0.995, 0.2], 50_000, 12),        # transient longer than 64 lags: by parity
    ("AR1+AR1", [0.9, 0.1, -0.3, 0.05], 20_000, 12),
    ("QN+WN+RW", [0.1, 1.0, 1e-5], 60_000, 14),
    ("WN+RW+AR1+DR", [1.0, 1e-4, 0.975, 0.03, 1e-4], 1_000_000, 18),
    ("WN+GM", [2e-5, 0.0132, 1e-9], 10**9, 26),         # the plan's model kind at ~4 months
    ("WN+RW+AR1", [1.0, 1e-6, 0.99999, 1e-4], 10**9 + 7, 28),
    ("WN", [1.0], 2, 1),
    ("WN+AR1", [1.0, -0.9, 0.5], 10**7, 22),            # phi ** m_j by pow() past m_j = 2**16
]


def _kernel_args(model: str, theta: list[float], T: int, levels: int) -> tuple:
    """The arguments gmwm.wvcov passes its kernel for this case (captured, not rebuilt)."""
    seen: list[tuple] = []
    real = wvcov._all_pairs

    def capture(*args):
        seen.append(args)
        return real(*args)

    wvcov._all_pairs = capture
    try:
        wvcov._wv_covariance(wvcov.as_model(model), np.asarray(theta, float),
                             2 ** np.arange(1, levels + 1), T, {"SIN"}, True)
    finally:
        wvcov._all_pairs = real
    return seen[0]


def _c(args: tuple) -> tuple[np.ndarray, np.ndarray]:
    from gmwm import _wvcov

    J = args[1].shape[0]
    S1, S2 = np.full((J, J), np.nan), np.full((J, J), np.nan)
    _wvcov.all_pairs(*args[:10], *args[10:], S1, S2)
    return S1, S2


@needs_c_kernel
@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]}-T{c[2]}" for c in CASES])
def test_c_kernel_matches_numba_bit_for_bit(case) -> None:
    from gmwm import _wvcovkernels

    args = _kernel_args(*case)
    ref = _wvcovkernels.all_pairs(*args)
    got = _c(args)
    for r, g in zip(ref, got, strict=True):
        assert np.all(np.isfinite(r))
        # bit for bit: the same operations in the same order (gmwm/_wvcov.c)
        assert r.tobytes() == g.tobytes(), np.max(np.abs(g - r) / np.abs(r))


@needs_c_kernel
def test_the_installation_uses_the_c_kernel_the_same_from_several_threads() -> None:
    from gmwm import _wvcov

    assert wvcov.kernels() is _wvcov
    args = _kernel_args(*CASES[6])
    ref = _c(args)
    out: list = [None] * 3

    def run(i: int) -> None:
        out[i] = _c(args)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for o in out:  # the same bits from each thread: no shared state in the kernel
        assert o[0].tobytes() == ref[0].tobytes() and o[1].tobytes() == ref[1].tobytes()


@needs_c_kernel
def test_c_kernel_rejects_arrays_that_do_not_fit() -> None:
    from gmwm import _wvcov

    args = _kernel_args(*CASES[1])
    J = args[1].shape[0]
    with pytest.raises(ValueError, match="J x J"):
        _wvcov.all_pairs(*args, np.empty((J, J - 1)), np.empty((J, J)))
    bad = list(args)
    bad[6] = np.array([1.0, 2.0])  # ar_p longer than ar_a
    with pytest.raises(ValueError, match="one length"):
        _wvcov.all_pairs(*bad, np.empty((J, J)), np.empty((J, J)))


def test_wv_covariance_is_the_same_through_either_kernel(monkeypatch) -> None:
    """gmwm.wvcov falls back to the Numba twin when the C kernel is not built: the same V."""
    from gmwm import _wvcovkernels

    model, theta, T, levels = CASES[2]
    scales = 2 ** np.arange(1, levels + 1)
    wvcov._MEMO.clear()
    first = wvcov.wv_covariance(model, theta, scales, T)
    wvcov._MEMO.clear()
    monkeypatch.setattr(wvcov, "kernels", lambda: _wvcovkernels)
    again = wvcov.wv_covariance(model, theta, scales, T)
    wvcov._MEMO.clear()
    assert first.tobytes() == again.tobytes()
