"""``gmwm simulate``: one realisation of a composite model, written to a signal file."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TextIO

import numpy as np

from gmwm.cli.inputs import model_theta
from gmwm.cli.parser import EXIT_OK
from gmwm.errors import InputError
from gmwm.formatting import json_text


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.atomic import write_signal
    from gmwm.readers.tables import SIGNAL_SUFFIXES

    suffix = Path(args.output).suffix.lower()
    if suffix not in SIGNAL_SUFFIXES:  # before a possibly long simulation
        raise InputError(f"unknown output extension '{suffix}' for {args.output}: "
                         f"use one of {', '.join(SIGNAL_SUFFIXES)}")
    model, theta = model_theta(args.model, args.param, args.freq)
    args.progress(f"simulating {args.n_samples} samples of {model.spec}")
    t0 = time.perf_counter()
    x = model.simulate(theta, args.n_samples, np.random.default_rng(args.seed))
    seconds = time.perf_counter() - t0
    args.progress(f"writing {args.output}")
    path = write_signal(args.output, x)
    if args.json:
        out.write(json_text({"command": "simulate", "model": model.spec,
                             "params": model.as_dict(theta), "n": args.n_samples,
                             "seed": args.seed, "freq": args.freq, "output": str(path),
                             "seconds": seconds}))
    else:
        out.write(f"wrote {args.n_samples} samples of {model.spec} (seed {args.seed}) to {path} "
                  f"[{seconds:.3f} s]\n")
    return EXIT_OK
