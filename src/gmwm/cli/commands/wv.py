"""``gmwm wv``: the empirical Haar wavelet variance of one or several channels, with CIs; and the
WV computation it shares with ``gmwm av`` (:func:`channel_wvs`)."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import threading
import time
from typing import TYPE_CHECKING, Any, TextIO

from gmwm.cli.inputs import check_levels, read_signals, stream_wvs
from gmwm.cli.outputs import plot_channels, write_table
from gmwm.cli.parser import EXIT_OK
from gmwm.formatting import WV_HEADERS, json_text, table, wv_channel_table, wv_channel_text, wv_rows

if TYPE_CHECKING:
    from gmwm.calibrate import Prepared

#: samples of the warm-up call that loads the compiled WV kernel (reported as the first-call cost)
WARMUP_SAMPLES = 1024


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    got, wvs, seconds, costs = channel_wvs(args, err)
    if args.plot:
        from gmwm.plots import plot_wv

        plot_channels(wvs, lambda wv, ax, c: plot_wv(wv, ax=ax, units=got.units[c]), args.plot)
    name, wv = next(iter(wvs.items()))
    single = args.columns is None
    headers, rows = (WV_HEADERS, wv_rows(wv)) if single else wv_channel_table(wvs)
    if args.output:
        write_table(args.output, headers, rows)
    if args.json:
        what = ({**wv.to_dict(), "seconds": seconds[name]} if single else
                {"columns": list(wvs), "wv": {c: w.to_dict() for c, w in wvs.items()},
                 "seconds": seconds})
        out.write(json_text({"command": "wv", "input": args.input, **what, **costs}))
    elif single:
        out.write(f"Haar wavelet variance of {args.input}: T = {wv.n_samples} samples, "
                  f"freq = {wv.freq:g} Hz, {100 * (1 - wv.alpha):g}% CI, "
                  f"{seconds[name]:.3f} s\n")
        out.write(table(headers, rows) + "\n")
    else:
        out.write(f"Haar wavelet variance of {args.input}: {len(wvs)} channels, "
                  f"T = {wv.n_samples} samples, freq = {wv.freq:g} Hz, "
                  f"{sum(seconds.values()):.3f} s\n")
        out.write(wv_channel_text(wvs, lambda w: w.variance, "variance") + "\n")
    return EXIT_OK


def channel_wvs(args: argparse.Namespace, err: TextIO
                ) -> tuple[Prepared, dict[str, Any], dict[str, float], dict[str, Any]]:
    """The input, its WV per channel (``--levels``, ``--alpha``, ``--robust``), the seconds of
    each, and the costs reported in ``--json``: ``seconds_read``, ``seconds_first_call``
    (loading the compiled kernel), ``seconds_import_scipy``, ``wv_kernel`` ("c" or "numba") and
    ``streamed``. A streamed input (:func:`gmwm.cli.inputs.stream_wvs`) is read and transformed
    in one pass, whose time is the WV's."""
    got = stream_wvs(args, err)
    if got is not None:
        from gmwm.wv import kernel_name

        return got, got.data, {c: v.seconds for c, v in got.streamed.items()}, {
            "seconds_read": 0.0, "seconds_first_call": 0.0, "seconds_import_scipy": 0.0,
            "wv_kernel": kernel_name(), "streamed": True}
    got = read_signals(args, err)
    robust = {"robust": True, "eff": args.eff} if getattr(args, "robust", False) else {}
    wvs, seconds, costs = _compute_wvs(args, got, **robust)
    return got, wvs, seconds, {"seconds_read": got.seconds, **costs, "streamed": False}


def _compute_wvs(args: argparse.Namespace, got: Prepared, **options: Any
                 ) -> tuple[dict[str, Any], dict[str, float], dict[str, Any]]:
    """WV per signal of ``got``, the seconds of each (the WV and its CI, wall; the first
    signal's includes waiting for the end of scipy.special's import, which runs beside it) and
    the costs: the first call (loading the compiled kernel, measured on a short warm-up call),
    the import of scipy.special and the kernel's name."""
    from gmwm.wv import load_kernel, wvar

    for x in got.data.values():
        check_levels(x.size, args.levels)
    first = next(iter(got.data.values()))
    t0 = time.perf_counter()
    # The CI's chi-square quantiles need scipy.special (~0.2 s to import): import it on a second
    # thread while this one loads the kernel and computes the first WV (the C kernel releases the
    # GIL; so do LLVM's compile and load steps of the Numba fallback). chi2_ci's own import waits
    # for it if it has not finished.
    took: dict[str, float] = {}
    prefetch = threading.Thread(target=_import_quietly, args=("scipy.special", took), daemon=True)
    prefetch.start()
    kernel = load_kernel(min(first.size, WARMUP_SAMPLES))
    first_call = time.perf_counter() - t0
    wvs, seconds = {}, {}
    for name, x in got.data.items():
        args.progress(f"wavelet variance of {name} ({x.size} samples)")
        t0 = time.perf_counter()
        wvs[name] = wvar(x, levels=args.levels, alpha=args.alpha, freq=got.freq, **options)
        seconds[name] = time.perf_counter() - t0
    prefetch.join()
    return wvs, seconds, {"seconds_first_call": first_call,
                          "seconds_import_scipy": took.get("scipy.special", 0.0),
                          "wv_kernel": kernel}


def _import_quietly(name: str, took: dict[str, float]) -> None:
    """Import ``name`` for its side effect (module cache) and record its wall time in
    ``took[name]``; errors surface at the real import."""
    t0 = time.perf_counter()
    with contextlib.suppress(Exception):  # a failing import is reported by the real import
        importlib.import_module(name)
    took[name] = time.perf_counter() - t0
