"""Compile the Numba kernels into Numba's on-disk cache at install time, and say so on stderr
when a command has to compile anyway.

Why a cache built at install time (and not C ports or Numba's AOT compiler): the classical WV
kernel and the WV estimate's covariance (what ``gmwm plan`` needs, so that it never loads Numba)
are C (``_haar.c``, ``_wvcov.c``, with their Numba twins as the fallback), but some thirty further kernels (AR1 and covariance formulas of the
fit, the simulators, the robust WV, SVO) would need a second,
separately maintained implementation each; ``numba.pycc`` is deprecated and compiles for a generic
CPU. Numba's own cache (``cache=True`` on every kernel) keys an entry on the source file's
content hash, the Numba version and the CPU, so the entries compiled by ``setup.py`` (its
``build_ext`` step runs ``python -m gmwm._precompile`` next to the freshly built package, into
``gmwm/__pycache__``) are the ones the installed package loads: the first command after
``pip install`` runs as fast as the second. When they do not apply (another Numba version or CPU,
a read-only installation, ``GMWM_NO_PRECOMPILE=1`` at install), a command that compiles prints one
line on stderr (:func:`announce_compiles`).

The warm-up runs the command-line tool itself on small files (simulate, fit with every
component kind and option that reaches a kernel, select, the robust WV, SVO), so the kernels are
compiled for exactly the argument types those paths pass. It runs each command as ``python -m
gmwm`` in a child process: the command-line package imports this module (for the note), so this
module must not import it back (no import cycle; tests/test_layout.py). The paper studies'
kernels (``gmwm_studies``, e.g. the MLE's Kalman filter) are not part of the library and compile
on their first use.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from typing import Any, TextIO

#: every kind of component, so that the simulators and all model WV kernels are compiled
_FULL_MODEL = "WN+QN+RW+DR+AR1+GM+SIN"
_FULL_PARAMS = ("WN[1].sigma2=1", "QN[1].Q2=0.1", "RW[1].gamma2=1e-4", "DR[1].omega=1e-4",
                "AR1[1].phi=0.99", "AR1[1].sigma2=0.01", "GM[1].beta=0.5", "GM[1].sigma2=0.02",
                "SIN[1].alpha=0.5", "SIN[1].beta=0.3")

#: command lines run by the warm-up ({x}: a one-channel signal, {X}: a three-channel one)
_COMMANDS: tuple[tuple[str, ...], ...] = (
    ("fit", "{x}", "WN+RW+AR1+DR"),
    ("fit", "{x}", "WN+AR1+RW", "--weights", "efficient"),
    ("fit", "{x}", "WN+GM+SIN+QN", "--method", "armav", "--reweight", "1", "--freq", "100"),
    ("fit", "{x}", "WN+RW", "--robust"),
    ("fit", "{x}", "WN+RW", "--method", "avsm"),
    ("select", "{x}", "WN+AR1+RW", "--auto"),
    ("wv", "{x}", "--robust"),
    ("model-wv", "WN+AR1", "-p", "WN[1].sigma2=1", "-p", "AR1[1].phi=0.9", "-p",
     "AR1[1].sigma2=0.1", "--levels", "8"),
    ("svo", "{X}", "--columns", "all", "--n-boot", "4"),
)


def _run(argv: list[str]) -> int:
    """Run ``gmwm argv`` in a child process (same interpreter and environment); its exit status."""
    return subprocess.run([sys.executable, "-m", "gmwm", *argv], capture_output=True,
                          check=False).returncode


def warm(log: TextIO = sys.stderr) -> float:
    """Run the warm-up workload (compiling and caching every kernel it reaches); returns its
    wall seconds."""
    import numpy as np

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="gmwm-precompile-") as tmp:
        x = os.path.join(tmp, "x.npy")
        params = [a for p in _FULL_PARAMS for a in ("-p", p)]
        code = _run(["simulate", _FULL_MODEL, *params, "-n", "16384", "--seed", "1", "-o", x])
        if code != 0:
            raise RuntimeError(f"warm-up simulate failed (exit status {code})")
        X = os.path.join(tmp, "X.npy")
        rng = np.random.default_rng(2)
        common = np.cumsum(rng.standard_normal(8192))
        np.save(X, common[:, None] + rng.standard_normal((8192, 3)))
        for cmd in _COMMANDS:
            argv = [a.format(x=x, X=X) for a in cmd]
            code = _run(argv)
            log.write(f"  gmwm {' '.join(cmd[:1] + cmd[2:])}: exit status {code}\n")
    return time.perf_counter() - t0


class _NoteState:
    err: TextIO | None = None
    announced = False
    registered = False


def _register() -> None:
    from numba.core import event

    class _Note(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            err = _NoteState.err
            if _NoteState.announced or err is None:
                return
            if getattr(err, "closed", False):
                # the command that asked for the note has finished (its stream is gone):
                # a library call compiling later must not fail on the note
                _NoteState.err = None
                return
            _NoteState.announced = True
            try:
                err.write("gmwm: note: compiling numerical kernels for this machine "
                          "(once: later runs load them from Numba's cache; an install "
                          "normally does this)\n")
                err.flush()
            except (OSError, ValueError):
                pass

        def on_end(self, ev: event.Event) -> None:
            pass

    event.register("numba:compile", _Note())
    _NoteState.registered = True


class _AfterImport(importlib.abc.MetaPathFinder):
    """Registers the compile note right after Numba is first imported, so that commands which
    never run a Numba kernel do not pay for importing it."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "numba":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.loader is not None:
            spec.loader = _NotingLoader(spec.loader)
        return spec


class _NotingLoader(importlib.abc.Loader):
    """Numba's own loader, plus the registration once the package has been executed."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def create_module(self, spec: Any) -> Any:
        return self._inner.create_module(spec)

    def exec_module(self, module: Any) -> None:
        self._inner.exec_module(module)
        if not _NoteState.registered:
            _register()

    def __getattr__(self, name: str) -> Any:  # resource readers etc.: the real loader's
        return getattr(self._inner, name)


def announce_compiles(err: TextIO) -> None:
    """From now on, the first time Numba compiles a kernel in this process (no valid cached
    version), write one note to ``err`` (the latest stream given). Does not import Numba: the
    note is set up when something else does."""
    _NoteState.err = err
    if _NoteState.registered:
        return
    if "numba" in sys.modules:
        _register()
    elif not any(isinstance(f, _AfterImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport())


def main() -> int:
    """``python -m gmwm._precompile``: compile the kernels into Numba's cache, report the time."""
    from gmwm.wv import kernel_name
    from gmwm.wvcov import kernels as wvcov_kernels

    sys.stderr.write("gmwm: compiling the Numba kernels into their cache\n")
    seconds = warm()
    cov = "c" if wvcov_kernels().__name__ == "gmwm._wvcov" else "numba"
    sys.stderr.write(f"gmwm: kernels compiled in {seconds:.1f} s (classical WV kernel: "
                     f"{kernel_name()}, WV covariance kernel: {cov})\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
