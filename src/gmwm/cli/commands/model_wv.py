"""``gmwm model-wv``: the theoretical WV of a model at given values, in total and per component."""

from __future__ import annotations

import argparse
from typing import TextIO

import numpy as np

from gmwm.cli.inputs import model_theta
from gmwm.cli.outputs import save_plot
from gmwm.cli.parser import EXIT_OK, MAX_MODEL_LEVELS
from gmwm.errors import InputError
from gmwm.formatting import json_text, table


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    if args.levels > MAX_MODEL_LEVELS:
        raise InputError(f"--levels {args.levels} is too large: scales 2^j beyond "
                         f"2^{MAX_MODEL_LEVELS} samples exceed any recording (at most "
                         f"J = {MAX_MODEL_LEVELS})")
    model, theta = model_theta(args.model, args.param, args.freq)
    if model.n_params > args.levels:
        # not an error (a theoretical WV is defined anyway) but worth a note for fitting
        err.write(f"gmwm: note: {model.n_params} parameters on {args.levels} scales could not be "
                  "identified from this WV\n")
    levels = np.arange(1, args.levels + 1)
    scales = 2.0 ** levels
    with np.errstate(all="ignore"):
        total = model.wv(theta, scales)
        comps = model.component_wv(theta, scales)
    if not np.all(np.isfinite(total)):
        j = int(levels[np.argmax(~np.isfinite(total))])
        raise InputError(f"the model WV is not finite from level {j} on (scale 2^{j} samples): "
                         "use fewer --levels")
    units = (args.units or [""])[-1]
    if args.plot:
        from gmwm.plots import plot_model_wv

        save_plot(plot_model_wv(model, theta, scales, freq=args.freq, units=units), args.plot)
    if args.json:
        out.write(json_text({"command": "model-wv", "model": model.spec,
                             "params": model.as_dict(theta), "freq": args.freq,
                             "levels": levels.tolist(), "scales": scales.tolist(),
                             "scales_s": (scales / args.freq).tolist(), "total": total.tolist(),
                             "components": {k: v.tolist() for k, v in comps.items()}}))
    else:
        out.write(f"theoretical Haar WV of {model.spec} at freq = {args.freq:g} Hz\n")
        rows = [(int(j), s, s / args.freq, t, *(c[i] for c in comps.values()))
                for i, (j, s, t) in enumerate(zip(levels, scales, total, strict=True))]
        out.write(table(["level", "scale", "scale_s", "total", *comps], rows) + "\n")
    return EXIT_OK
