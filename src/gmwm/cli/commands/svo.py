"""``gmwm svo``: the virtual gyroscope of redundant signals of one axis (Scale-wise Variance
Optimisation, :func:`gmwm.virtual.svo`; or the comparison methods RDVG and equal weights)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from gmwm.cli.inputs import read_signals
from gmwm.cli.outputs import save_plot, write_table
from gmwm.cli.parser import EXIT_OK
from gmwm.errors import InputError
from gmwm.formatting import WV_HEADERS, json_text, wv_rows


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Coefficients with CIs, the virtual WV table (-o), a WV figure (--plot)."""
    from gmwm.readers.tables import read_weights
    from gmwm.virtual import equal, rdvg, svo

    got = read_signals(args, err)
    signals = got.data
    if len(signals) < 2:
        raise InputError(f"--columns selected {len(signals)} signal; at least 2 are needed")
    lengths = {len(x) for x in signals.values()}
    if len(lengths) != 1:
        raise InputError(f"the selected signals have different lengths: {sorted(lengths)}")
    names = [str(c) for c in signals]
    X = np.column_stack([np.asarray(x, dtype=np.float64) for x in signals.values()])
    weights: Any = args.weights
    if args.method == "svo" and weights.strip().lower() not in ("short", "long", "equal"):
        if not Path(weights).is_file():
            raise InputError(f"--weights {weights}: not 'short', 'long', 'equal' nor an existing "
                             "file")
        weights = read_weights(weights)
    t0 = time.perf_counter()
    args.progress(f"SVO ({args.method}) on {X.shape[1]} signals of {X.shape[0]} samples")
    common = {"levels": args.levels, "alpha": args.alpha, "freq": got.freq, "names": names}
    if args.method == "svo":
        res = svo(X, weights, n_boot=args.n_boot, block_const=args.block_const,
                  seed=args.seed, mbb=args.mbb, **common)
    else:
        res = (rdvg if args.method == "rdvg" else equal)(X, **common)
    seconds = time.perf_counter() - t0
    wv = res.wv()
    if args.output:
        write_table(args.output, WV_HEADERS, wv_rows(wv))
    if args.plot:
        from gmwm.plots import plot_virtual_wv

        save_plot(plot_virtual_wv(res), args.plot)
    if args.json:
        out.write(json_text({"command": "svo", "input": args.input, **res.to_json_dict(),
                             "seconds": seconds}))
        return EXIT_OK
    out.write(f"{res.summary()}\n")
    out.write(f"({args.input}, freq = {wv.freq:g} Hz, {seconds:.2f} s)\n")
    return EXIT_OK
