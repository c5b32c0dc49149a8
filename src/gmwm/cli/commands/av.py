"""``gmwm av``: the maximal-overlap Allan variance (2 x the Haar WV) of one or several channels,
with CIs and the IEEE 952 readings N, K, B."""

from __future__ import annotations

import argparse
from typing import Any, TextIO

import numpy as np

from gmwm.cli.commands.wv import channel_wvs
from gmwm.cli.outputs import plot_channels, write_table
from gmwm.cli.parser import EXIT_OK
from gmwm.formatting import (
    AV_HEADERS,
    av_channel_table,
    av_channel_text,
    av_rows,
    json_text,
    readings_text,
    table,
)


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.datasheet import allan_readings
    from gmwm.wv import AllanVariance

    got, wvs, seconds, costs = channel_wvs(args, err)
    avs = {c: AllanVariance.from_wv(w) for c, w in wvs.items()}
    units = got.units
    readings = {c: allan_readings(av, units[c] or None) for c, av in avs.items()}
    if args.plot:
        from gmwm.plots import plot_av

        plot_channels(avs, lambda av, ax, c: plot_av(av, ax=ax, units=units[c], deviation=args.adev,
                                                     readings=readings[c] if args.adev else None),
                      args.plot)
    name, av = next(iter(avs.items()))
    single = args.columns is None
    headers, rows = (AV_HEADERS, av_rows(av)) if single else av_channel_table(avs)
    if args.output:
        write_table(args.output, headers, rows)
    if args.json:
        what = ({**_json(av, units[name], readings[name], args.alpha), "seconds": seconds[name]}
                if single else
                {"columns": list(avs), "av": {c: {**a.to_dict(), "units": units[c] or None}
                                             for c, a in avs.items()},
                 "readings": readings, "seconds": seconds})
        out.write(json_text({"command": "av", "input": args.input, **what, **costs}))
    elif single:
        out.write(f"Allan variance (maximal overlap) of {args.input}: T = {av.n_samples} "
                  f"samples, freq = {av.freq:g} Hz, {100 * (1 - args.alpha):g}% CI, "
                  f"{seconds[name]:.3f} s\n")
        out.write(table(headers, rows) + "\n")
        out.write(readings_text({name: readings[name]}, single=True) + "\n")
    else:
        out.write(f"Allan deviation (maximal overlap) of {args.input}: {len(avs)} channels, "
                  f"T = {av.n_samples} samples, freq = {av.freq:g} Hz\n")
        out.write(av_channel_text(avs) + "\n")
        out.write(readings_text(readings, single=False) + "\n")
    return EXIT_OK


def _json(av: Any, units: str, readings: dict[str, Any], alpha: float) -> dict[str, Any]:
    """``gmwm av --json`` of one channel (its own keys; several channels use ``to_dict``)."""
    m = np.asarray(av.clusters, dtype=float)
    var = np.asarray(av.avar, float)
    return {"levels": np.asarray(av.levels).tolist(), "cluster": m.astype(int).tolist(),
            "tau_s": (m / av.freq).tolist(), "variance": var.tolist(),
            "ci_low": np.asarray(av.ci_low, float).tolist(),
            "ci_high": np.asarray(av.ci_high, float).tolist(),
            "deviation": np.sqrt(var).tolist(), "n": np.asarray(av.n).tolist(),
            "n_samples": int(av.n_samples), "freq": av.freq, "alpha": alpha,
            "units": units or None, "readings": readings}
