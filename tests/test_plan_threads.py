"""``gmwm plan`` computes its WV covariances in threads while the predictions run (that the plan
is bit-identical to the one-thread plan: tests/test_plan_fast.py): a covariance asked for by two
threads at once is computed once (the second waits) or, if that computation fails, by the
waiter itself."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from gmwm import wvcov
from gmwm.errors import ModelError


def test_a_covariance_asked_twice_at_once_is_computed_once(monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    wvcov._MEMO.clear()
    started, release = threading.Event(), threading.Event()
    calls = []
    real = wvcov._wv_covariance

    def slow(*a, **k):
        calls.append(a[3])
        started.set()
        release.wait(10)
        return real(*a, **k)

    monkeypatch.setattr(wvcov, "_wv_covariance", slow)
    theta, scales = np.array([1.0, 1e-4]), 2.0 ** np.arange(1, 6)
    out = {}

    def ask(name: str) -> None:
        out[name] = wvcov.wv_covariance("WN+RW", theta, scales, 4096)

    first = threading.Thread(target=ask, args=("first",))
    first.start()
    assert started.wait(10)
    second = threading.Thread(target=ask, args=("second",))
    second.start()
    second.join(0.2)
    assert second.is_alive()  # waiting for the first, not computing it again
    release.set()
    first.join(10)
    second.join(10)
    assert calls == [4096]
    np.testing.assert_array_equal(out["first"], out["second"])
    assert not wvcov._MEMO.computing


def test_a_waiter_computes_it_itself_when_the_first_computation_fails(
        monkeypatch: pytest.MonkeyPatch) -> None:
    wvcov._MEMO.clear()
    started, release = threading.Event(), threading.Event()
    real = wvcov._wv_covariance
    calls = []

    def flaky(*a, **k):
        calls.append(threading.current_thread().name)
        if len(calls) == 1:
            started.set()
            release.wait(10)
            raise ModelError("first computation fails")
        return real(*a, **k)

    monkeypatch.setattr(wvcov, "_wv_covariance", flaky)
    theta, scales = np.array([1.0, 1e-4]), 2.0 ** np.arange(1, 6)
    errors, out = [], {}

    def first() -> None:
        try:
            wvcov.wv_covariance("WN+RW", theta, scales, 4096)
        except ModelError as e:
            errors.append(str(e))

    t1 = threading.Thread(target=first, name="t1")
    t1.start()
    assert started.wait(10)
    t2 = threading.Thread(target=lambda: out.update(
        v=wvcov.wv_covariance("WN+RW", theta, scales, 4096)), name="t2")
    t2.start()
    release.set()
    t1.join(10)
    t2.join(10)
    assert errors == ["first computation fails"]
    assert calls == ["t1", "t2"]
    np.testing.assert_array_equal(out["v"], real(*_args(theta, scales)))
    assert not wvcov._MEMO.computing


def _args(theta: np.ndarray, scales: np.ndarray) -> tuple:
    from gmwm.model import as_model

    tau, T = wvcov._check_scales(scales, 4096)
    return (as_model("WN+RW"), theta, tau, T, {"SIN"}, True)


def test_the_plan_cache_predicts_a_length_once_for_two_threads() -> None:
    from gmwm.plan import _Cache

    started, release = threading.Event(), threading.Event()
    calls = []

    def fn(n: int) -> object:
        calls.append(n)
        started.set()
        release.wait(10)
        return object()

    cache = _Cache(fn)
    got = []
    threads = [threading.Thread(target=lambda: got.append(cache(7))) for _ in range(2)]
    threads[0].start()
    assert started.wait(10)
    threads[1].start()
    threads[1].join(0.2)
    assert threads[1].is_alive()  # waiting for the first thread's prediction
    release.set()
    for t in threads:
        t.join(10)
    assert calls == [7] and len(got) == 2 and got[0] is got[1]


def test_the_python_sinh_minus_has_the_compiled_bits() -> None:
    # the same source compiled by Numba (as it was before it became plain Python)
    from numba import njit

    compiled = njit(wvcov._sinh_minus)
    xs = 10.0 ** np.random.default_rng(3).uniform(-12, 2.8, 2000)
    for x in [*xs, 0.0, 0.5, np.nextafter(0.5, 0), 700.0]:
        assert wvcov._sinh_minus(x) == compiled(x), x
