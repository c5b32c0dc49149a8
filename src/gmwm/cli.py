"""The ``gmwm`` command line tool: simulate, wv, av, fit, model-wv.

Exit status: 0 success; 1 a problem with the input, model or files (one line
``gmwm: error: ...`` on stderr, never a traceback); 2 a usage error (bad options, malformed
``--param``); 3 ``gmwm fit`` ran but the optimizer did not report convergence (the estimate is
still printed, with a warning on stderr); 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn, TextIO

import numpy as np

from gmwm import __version__
from gmwm.errors import GMWMError, IdentifiabilityError, InputError, ModelError

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NOT_CONVERGED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

_EXIT_STATUS_HELP = """exit status:
  0  success
  1  bad input, model or file (one line 'gmwm: error: ...' on stderr)
  2  usage error (unknown option, malformed --param, ...)
  3  (fit only) the optimizer did not converge: the estimate is printed with a warning"""

_PARAM = re.compile(r"^\s*([A-Za-z][A-Za-z0-9]*\[\d+\]\.[A-Za-z][A-Za-z0-9_]*)\s*=\s*(\S+)\s*$")


class UsageError(Exception):
    """A command-line usage problem found after parsing (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr, ``gmwm: error: ...``, exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"gmwm: error: {message} (see '{self.prog} --help')\n")


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Keep the hand-wrapped descriptions/epilogs; show defaults that carry information."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default
        if not (d is None or d is False or d == "" or d == [] or d is argparse.SUPPRESS
                or "%(default)" in text):
            text += " (default: %(default)s)"
        return text


# --------------------------------------------------------------------------------------------------
# argument parsing
# --------------------------------------------------------------------------------------------------


def _param(text: str) -> tuple[str, float]:
    """``AR1[1].phi=0.975`` -> ('AR1[1].phi', 0.975)."""
    m = _PARAM.match(text)
    if m is None:
        raise argparse.ArgumentTypeError(
            f"malformed --param {text!r}: write NAME=VALUE with NAME like AR1[1].phi or WN[1].sigma2"
        )
    try:
        value = float(m.group(2))
    except ValueError:
        raise argparse.ArgumentTypeError(f"malformed --param {text!r}: {m.group(2)!r} is not a number") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"--param {text!r}: the value must be finite")
    name = m.group(1)
    typ, rest = name.split("[", 1)
    return f"{typ.upper()}[{rest}", value


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (np.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return v


def _alpha(text: str) -> float:
    v = _positive_float(text)
    if not v < 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1), got {text!r}")
    return v


def _column(text: str) -> str | int:
    return int(text) if re.fullmatch(r"\d+", text.strip()) else text


def _add_input(p: argparse.ArgumentParser, what: str = "signal") -> None:
    p.add_argument("input", metavar="FILE", help=f"{what}: .npy, .csv/.tsv/.txt or HDF5 (.h5/.hdf5)")
    p.add_argument("--column", type=_column, default=None,
                   help="CSV column (header name or 0-based index); needed when the file has several")
    p.add_argument("--dataset", default=None,
                   help="HDF5 dataset path (default: the only 1-D dataset in the file)")


def _add_common(p: argparse.ArgumentParser, levels_help: str) -> None:
    p.add_argument("--freq", type=_positive_float, default=1.0,
                   help="sampling frequency in Hz (scales are then also reported in seconds)")
    p.add_argument("--levels", "-J", type=_positive_int, default=None, metavar="J", help=levels_help)
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--plot", metavar="FILE.png", default=None,
                   help="draw a log-log figure to this file (.png, .pdf or .svg)")
    p.add_argument("--units", default="",
                   help="unit of the signal for the plot axis labels, e.g. 'deg/s'")


def _add_params(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", metavar="MODEL",
                   help="model string, e.g. 'WN+RW+AR1+SIN', '2*AR1+2*SIN', 'QN+WN+2*GM+RW+DR'")
    p.add_argument("--param", "-p", action="append", type=_param, default=[], metavar="NAME=VALUE",
                   help="parameter value, repeatable, e.g. --param 'AR1[1].phi=0.975'. "
                        "Names: WN[k].sigma2 QN[k].Q2 RW[k].gamma2 DR[k].omega AR1[k].phi "
                        "AR1[k].sigma2 GM[k].beta GM[k].sigma2 SIN[k].alpha SIN[k].beta")


_DEFAULT_LEVELS = "number of dyadic scales tau_j = 2^j, j = 1..J (default floor(log2 T) - 1)"


def build_parser() -> argparse.ArgumentParser:
    """The ``gmwm`` argument parser with its five subcommands."""
    parser = _Parser(
        prog="gmwm",
        formatter_class=_Formatter,
        description=(
            "Stochastic calibration of inertial sensors with the Generalized Method of Wavelet\n"
            "Moments (GMWM): simulate error models, compute Haar wavelet and Allan variances,\n"
            "fit composite models (WN, QN, RW, DR, AR1, GM, SIN) and evaluate model WVs.\n"
            "Parameters are discrete-time, per sample; scales are filter lengths tau_j = 2^j samples."
        ),
        epilog=(
            "examples:\n"
            "  gmwm simulate 'WN+AR1' -p 'WN[1].sigma2=1' -p 'AR1[1].phi=0.9' -p 'AR1[1].sigma2=0.1' \\\n"
            "       -n 100000 --seed 1 -o x.npy\n"
            "  gmwm wv x.npy --plot wv.png\n"
            "  gmwm fit x.npy 'WN+AR1' --json\n\n" + _EXIT_STATUS_HELP
        ),
    )
    parser.add_argument("--version", action="version", version=f"gmwm {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of unexpected errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p = sub.add_parser(
        "simulate", formatter_class=_Formatter, help="simulate a signal from a composite model",
        description="Simulate one realisation of a composite model (sum of independent processes)\n"
                    "and write it to .npy, .csv/.tsv/.txt or HDF5 (dataset 'signal').\n"
                    "Reproducible: the same --seed gives the same signal.",
        epilog="example:\n"
               "  gmwm simulate 'WN+RW+AR1+SIN' -p 'WN[1].sigma2=1' -p 'RW[1].gamma2=4e-4' \\\n"
               "       -p 'AR1[1].phi=0.975' -p 'AR1[1].sigma2=0.03' -p 'SIN[1].alpha=0.85' \\\n"
               "       -p 'SIN[1].beta=0.35' -n 100000 --seed 42 -o sim1.npy\n\n" + _EXIT_STATUS_HELP,
    )
    _add_params(p)
    p.add_argument("-n", "--n-samples", type=_positive_int, required=True, metavar="N",
                   help="number of samples")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file; format from the extension (.npy, .csv, .tsv, .txt, .h5, .hdf5)")
    p.add_argument("--freq", type=_positive_float, default=1.0,
                   help="sampling frequency in Hz (used by GM parameters)")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(func=cmd_simulate)

    for name, what, quantity in (
        ("wv", "Haar wavelet variance", "WV"),
        ("av", "Allan variance", "AV"),
    ):
        extra = (
            "AV at cluster length m = 2^(j-1) samples equals 2 x the Haar WV at level j\n"
            "(maximal-overlap estimator, same coefficients)."
            if name == "av" else
            "Mean square of the boundary-free maximal-overlap Haar coefficients at\n"
            "tau_j = 2^j samples, with chi-square confidence intervals (Percival's eta_3 edof)."
        )
        p = sub.add_parser(
            name, formatter_class=_Formatter, help=f"empirical {what} with confidence intervals",
            description=f"Empirical {what} of a signal at dyadic scales, with {100 * 0.95:g}% CIs.\n"
                        f"{extra}",
            epilog=f"examples:\n  gmwm {name} imu.csv --column gyro_z --freq 200 --plot {name}.png\n"
                   f"  gmwm {name} imu.h5 --dataset /imu/gyro_z --freq 200 --json > {name}.json\n\n"
                   + _EXIT_STATUS_HELP,
        )
        _add_input(p)
        _add_common(p, _DEFAULT_LEVELS)
        p.add_argument("--alpha", type=_alpha, default=0.05, help="CI level is 1 - alpha")
        p.add_argument("-o", "--output", metavar="TABLE.csv", default=None,
                       help="also write the table as CSV (readable by 'gmwm fit' as a WV table)")
        p.set_defaults(func=cmd_wv if name == "wv" else cmd_av, quantity=quantity)

    p = sub.add_parser(
        "fit", formatter_class=_Formatter, help="fit a composite model to a signal or a WV table",
        description=(
            "Estimate the parameters of a composite model by GMWM (or ARMAV / AVSM).\n"
            "FILE is a signal (.npy, .csv, .h5) or a precomputed wavelet-variance table: a CSV with\n"
            "a header holding 'scale' (tau_j = 2^j samples; or 'scale_s' in seconds, or 'level'),\n"
            "'variance' and optionally 'ci_low', 'ci_high' and 'n' (coefficients per level; without\n"
            "it give the signal length with --n-samples). 'gmwm wv -o' writes such a table.\n"
            "Estimates are per-sample (discrete-time) parameters; standard errors come from the\n"
            "asymptotic sandwich covariance."
        ),
        epilog=(
            "examples:\n"
            "  gmwm fit sim1.npy 'WN+RW+AR1+SIN' --plot fit.png\n"
            "  gmwm fit imu.csv 'AR1+RW' --column gyro_z --freq 200 --json\n"
            "  gmwm fit wv_table.csv 'WN+RW' --n-samples 2500000 --freq 250\n\n" + _EXIT_STATUS_HELP
        ),
    )
    _add_input(p, what="signal or WV table")
    p.add_argument("model", metavar="MODEL", help="model string, e.g. 'WN+RW+AR1+SIN'")
    _add_common(p, _DEFAULT_LEVELS + "; with a WV table: use its first J scales")
    p.add_argument("--weights", choices=("ci", "gaussian", "identity"), default="ci",
                   help="weight matrix: inverse squared CI width, Gaussian approximation, identity")
    p.add_argument("--method", choices=("gmwm", "armav", "avsm"), default="gmwm",
                   help="gmwm: WV moments; armav: log10 Allan variance; avsm: Allan-variance slopes")
    p.add_argument("--n-samples", type=_positive_int, default=None, metavar="T",
                   help="signal length T, for a WV table without an 'n' column")
    p.add_argument("--n-starts", type=_positive_int, default=None, metavar="K",
                   help="number of optimizer starts (default: the library's)")
    p.add_argument("--seed", type=int, default=0, help="seed for the random starting values")
    p.add_argument("--reweight", type=int, default=0, metavar="K",
                   help="refit K times with weights from the fitted model WV (reduces bias)")
    p.add_argument("--check", action="store_true",
                   help="also run identifiability checks on the estimate (module gmwm.identify)")
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser(
        "model-wv", formatter_class=_Formatter,
        help="theoretical WV of a model at given parameter values",
        description="Theoretical Haar wavelet variance of a model at given parameter values on J\n"
                    "dyadic scales tau_j = 2^j samples, in total and per component (e.g. to draw a\n"
                    "datasheet model next to an empirical WV).",
        epilog="example:\n"
               "  gmwm model-wv 'WN+RW' -p 'WN[1].sigma2=1.7e-3' -p 'RW[1].gamma2=1.5e-13' \\\n"
               "       --levels 20 --freq 250 --plot stim300_gyro.png\n\n" + _EXIT_STATUS_HELP,
    )
    _add_params(p)
    p.add_argument("--levels", "-J", type=_positive_int, required=True, metavar="J",
                   help="number of dyadic scales tau_j = 2^j, j = 1..J")
    p.add_argument("--freq", type=_positive_float, default=1.0,
                   help="sampling frequency in Hz (GM parameters; scales in seconds)")
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--plot", metavar="FILE.png", default=None, help="draw the model WV to this file")
    p.add_argument("--units", default="", help="signal unit for the plot, e.g. 'deg/s'")
    p.set_defaults(func=cmd_model_wv)
    return parser


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def _model_theta(spec: str, params: Sequence[tuple[str, float]], freq: float):
    from gmwm.model import Model

    model = Model(spec, freq=freq)
    values: dict[str, float] = {}
    for name, value in params:
        if name in values:
            raise UsageError(f"--param {name} given twice")
        values[name] = value
    if not values and model.n_params:
        raise UsageError(f"give the parameter values with --param, e.g. --param '{model.param_names[0]}=...'; "
                         f"model {model.spec} needs {', '.join(model.param_names)}")
    return model, model.theta(values)


def _read_signal(args: argparse.Namespace) -> np.ndarray:
    from gmwm.io import read_signal

    return read_signal(args.input, column=args.column, dataset=args.dataset)


def _check_levels(n: int, levels: int | None, n_params: int = 0) -> None:
    """Clear messages for requests the data cannot support (before any computation)."""
    if n < 4:
        raise InputError(f"signal has {n} samples; at least 4 are needed for one wavelet scale")
    jmax = int(np.floor(np.log2(n)))
    if levels is not None and levels > jmax:
        raise InputError(
            f"signal of {n} samples is too short for --levels {levels} "
            f"(scale 2^{levels} = {2 ** levels} samples needs at least that many; at most J = {jmax})"
        )
    j = levels if levels is not None else jmax - 1
    if n_params > j:
        raise IdentifiabilityError(
            f"model has {n_params} parameters but only {j} wavelet scales are available: "
            "more parameters than scales cannot be identified"
            + ("" if levels is None or levels >= jmax else f" (raise --levels, at most {jmax})")
        )


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return "nan" if not np.isfinite(v) else f"{float(v):.6g}"
    return str(v)


def format_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """Right-aligned plain-text table."""
    cells = [list(map(str, headers))] + [[_fmt(v) for v in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _print_json(obj: Any, out: TextIO) -> None:
    from gmwm.io import to_jsonable

    out.write(json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")


def _save_plot(ax_or_fig: Any, path: str) -> None:
    from gmwm.io import save_figure

    save_figure(getattr(ax_or_fig, "figure", ax_or_fig), path)


_PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".tif", ".tiff")


def _check_args(args: argparse.Namespace) -> None:
    """Checks of option values that argparse cannot do, made before any computation."""
    plot = getattr(args, "plot", None)
    if plot and Path(plot).suffix.lower() not in _PLOT_SUFFIXES:
        raise UsageError(f"--plot {plot}: use a .png, .pdf or .svg file name")


def _wv_dict(wv: Any) -> dict[str, Any]:
    return {
        "levels": np.asarray(wv.levels).tolist(),
        "scales": np.asarray(wv.scales).tolist(),
        "scales_s": (np.asarray(wv.scales, float) / wv.freq).tolist(),
        "variance": np.asarray(wv.variance).tolist(),
        "ci_low": np.asarray(wv.ci_low).tolist(),
        "ci_high": np.asarray(wv.ci_high).tolist(),
        "n": np.asarray(wv.n).tolist(),
        "n_samples": int(wv.n_samples),
        "freq": float(wv.freq),
        "alpha": float(wv.alpha),
    }


def _wv_table_rows(wv: Any, factor: float = 1.0, halve: bool = False):
    scales = np.asarray(wv.scales, float) / (2.0 if halve else 1.0)
    return [
        (int(lv), s, s / wv.freq, factor * v, factor * lo, factor * hi, int(n))
        for lv, s, v, lo, hi, n in zip(wv.levels, scales, wv.variance, wv.ci_low, wv.ci_high, wv.n,
                                       strict=True)
    ]


# --------------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------------


def cmd_simulate(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.io import SIGNAL_SUFFIXES, write_signal

    suffix = Path(args.output).suffix.lower()
    if suffix not in SIGNAL_SUFFIXES:  # before a possibly long simulation
        raise InputError(f"unknown output extension '{suffix}' for {args.output}: "
                         f"use one of {', '.join(SIGNAL_SUFFIXES)}")
    model, theta = _model_theta(args.model, args.param, args.freq)
    t0 = time.perf_counter()
    x = model.simulate(theta, args.n_samples, np.random.default_rng(args.seed))
    seconds = time.perf_counter() - t0
    path = write_signal(args.output, x)
    if args.json:
        _print_json({"command": "simulate", "model": model.spec, "params": model.as_dict(theta),
                     "n": args.n_samples, "seed": args.seed, "freq": args.freq,
                     "output": str(path), "seconds": seconds}, out)
    else:
        out.write(f"wrote {args.n_samples} samples of {model.spec} (seed {args.seed}) to {path} "
                  f"[{seconds:.3f} s]\n")
    return EXIT_OK


def _compute_wv(args: argparse.Namespace, x: np.ndarray):
    from gmwm.wv import wvar

    _check_levels(x.size, args.levels)
    t0 = time.perf_counter()
    wv = wvar(x, levels=args.levels, alpha=args.alpha, freq=args.freq)
    return wv, time.perf_counter() - t0


def cmd_wv(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    x = _read_signal(args)
    wv, seconds = _compute_wv(args, x)
    headers = ["level", "scale", "scale_s", "variance", "ci_low", "ci_high", "n"]
    rows = _wv_table_rows(wv)
    _write_outputs(args, headers, rows)
    if args.plot:
        from gmwm.plots import plot_wv

        _save_plot(plot_wv(wv, units=args.units), args.plot)
    if args.json:
        _print_json({"command": "wv", "input": args.input, **_wv_dict(wv), "seconds": seconds}, out)
    else:
        out.write(f"Haar wavelet variance of {args.input}: T = {wv.n_samples} samples, "
                  f"freq = {wv.freq:g} Hz, {100 * (1 - wv.alpha):g}% CI, {seconds:.3f} s\n")
        out.write(format_table(headers, rows) + "\n")
    return EXIT_OK


def cmd_av(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.wv import avar

    x = _read_signal(args)
    _check_levels(x.size, args.levels)
    t0 = time.perf_counter()
    av = avar(x, levels=args.levels, alpha=args.alpha, freq=args.freq)
    seconds = time.perf_counter() - t0
    m = np.asarray(av.clusters, dtype=float)
    var = np.asarray(av.avar, float)
    lo, hi = np.asarray(av.ci_low, float), np.asarray(av.ci_high, float)
    n = np.asarray(av.n)
    headers = ["cluster_m", "tau_s", "allan_var", "ci_low", "ci_high", "allan_dev", "n"]
    rows = [(int(mi), mi / args.freq, v, a, b, np.sqrt(v), int(k))
            for mi, v, a, b, k in zip(m, var, lo, hi, n, strict=True)]
    _write_outputs(args, headers, rows)
    if args.plot:
        from gmwm.plots import plot_av

        _save_plot(plot_av(av, units=args.units), args.plot)
    if args.json:
        _print_json({
            "command": "av", "input": args.input, "levels": np.asarray(av.levels).tolist(),
            "cluster": m.astype(int).tolist(),
            "tau_s": (m / args.freq).tolist(), "variance": var.tolist(), "ci_low": lo.tolist(),
            "ci_high": hi.tolist(), "deviation": np.sqrt(var).tolist(), "n": n.tolist(),
            "n_samples": int(x.size), "freq": args.freq, "alpha": args.alpha, "seconds": seconds,
        }, out)
    else:
        out.write(f"Allan variance (maximal overlap) of {args.input}: T = {x.size} samples, "
                  f"freq = {args.freq:g} Hz, {100 * (1 - args.alpha):g}% CI, {seconds:.3f} s\n")
        out.write(format_table(headers, rows) + "\n")
    return EXIT_OK


def _write_outputs(args: argparse.Namespace, headers: Sequence[str], rows: Sequence[Sequence]) -> None:
    if not getattr(args, "output", None):
        return
    from gmwm.io import write_text_atomic

    if Path(args.output).suffix.lower() != ".csv":
        raise UsageError(f"--output {args.output}: the table is written as CSV, use a .csv name")
    lines = [",".join(headers)] + [",".join(repr(float(v)) if isinstance(v, float | np.floating)
                                            else str(v) for v in r) for r in rows]
    write_text_atomic(args.output, "\n".join(lines) + "\n")


def _load_fit_data(args: argparse.Namespace, n_params: int):
    """The signal (ndarray) or a WaveletVariance read from a WV table, plus seconds spent on the WV."""
    from gmwm.io import is_wv_table, read_wv_table

    if is_wv_table(args.input):
        wv = read_wv_table(args.input, n_samples=args.n_samples, freq=args.freq)
        if args.levels is not None:
            if args.levels > wv.n_levels:
                raise InputError(f"--levels {args.levels} but the table {args.input} has "
                                 f"{wv.n_levels} scales")
            wv = wv.subset(np.arange(1, args.levels + 1))
        if n_params > wv.n_levels:
            raise IdentifiabilityError(
                f"model has {n_params} parameters but the table has only {wv.n_levels} scales: "
                "more parameters than scales cannot be identified")
        return wv, 0.0
    if args.n_samples is not None:
        raise UsageError("--n-samples applies to a WV table (a CSV with 'scale' and 'variance' columns)")
    x = _read_signal(args)
    _check_levels(x.size, args.levels, n_params)
    return x, None


def _run_fit(args: argparse.Namespace, data: Any, model: Any) -> tuple[Any, float | None]:
    """The fit result and the seconds spent computing the WV here (None: the result knows)."""
    levels = args.levels if isinstance(data, np.ndarray) else None  # a table is already subset
    if args.method == "avsm":
        try:
            from gmwm.avsm import fit_avsm
        except ModuleNotFoundError as exc:
            raise GMWMError(f"--method avsm needs the module {exc.name}, not available here") from None
        seconds_wv = 0.0
        if isinstance(data, np.ndarray):
            from gmwm.wv import wvar

            t0 = time.perf_counter()
            data = wvar(data, levels=levels, freq=args.freq)
            seconds_wv = time.perf_counter() - t0
        return fit_avsm(data, model), seconds_wv
    from gmwm.fit import fit

    options = {} if args.n_starts is None else {"n_starts": args.n_starts}
    res = fit(data, model, levels=levels, freq=args.freq, weights=args.weights,
              method=args.method, seed=args.seed, reweight=args.reweight, **options)
    return res, None


def _identify_module():
    try:
        identify = importlib.import_module("gmwm.identify")
    except ModuleNotFoundError as exc:
        if exc.name != "gmwm.identify":
            raise
        raise GMWMError("--check needs the identifiability module gmwm.identify, which is not "
                        "available in this installation yet; run without --check") from None
    return identify


def cmd_fit(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.model import Model

    identify = _identify_module() if args.check else None
    model = Model(args.model, freq=args.freq)
    data, seconds_wv = _load_fit_data(args, model.n_params)
    t0 = time.perf_counter()
    res, seconds_wv_here = _run_fit(args, data, model)
    elapsed = time.perf_counter() - t0
    if seconds_wv is None:  # a signal: the WV was computed by the fit (or just above for AVSM)
        seconds_wv = seconds_wv_here if seconds_wv_here is not None else getattr(res, "seconds_wv", None)
    seconds_fit = getattr(res, "seconds_fit", None)
    if seconds_fit is None:
        seconds_fit = elapsed - (seconds_wv or 0.0)
    check = None
    if identify is not None:
        if not hasattr(identify, "check"):
            raise GMWMError("--check: gmwm.identify does not provide check(result) yet")
        check = identify.check(res)
    converged = bool(getattr(res, "converged", True))

    if args.plot:
        from gmwm.plots import plot_wv

        _save_plot(plot_wv(res.wv, result=res, units=args.units), args.plot)
    names = list(res.param_names)
    params = np.asarray(res.params, float)
    se = getattr(res, "se", None)  # AVSM has no standard errors
    se = [None] * len(names) if se is None else [float(s) for s in np.asarray(se, float)]
    if args.json:
        obj = {
            "command": "fit", "input": args.input, "model": res.model.spec, "method": args.method,
            "weights": args.weights, "n": int(res.wv.n_samples), "freq": args.freq,
            "params": dict(zip(names, params, strict=True)),
            "se": dict(zip(names, se, strict=True)),
            "objective": getattr(res, "objective", None), "converged": converged,
            "message": str(getattr(res, "message", "")),
            "wv": _wv_dict(res.wv), "seconds_wv": seconds_wv, "seconds_fit": seconds_fit,
        }
        if check is not None:
            obj["check"] = _check_json(check)
        _print_json(obj, out)
    else:
        how = "AVSM" if args.method == "avsm" else f"{args.method.upper()} ({args.weights} weights)"
        out.write(f"{how} fit of {res.model.spec} to {args.input}: T = {res.wv.n_samples} samples, "
                  f"J = {res.wv.n_levels} scales, freq = {args.freq:g} Hz\n")
        z = 1.959963984540054  # normal 97.5% quantile: 95% Wald intervals from the sandwich SE
        rows = [(n, p, s, None if s is None else p - z * s, None if s is None else p + z * s)
                for n, p, s in zip(names, params, se, strict=True)]
        out.write(format_table(["parameter", "estimate", "se", "ci95_low", "ci95_high"], rows) + "\n")
        out.write(f"objective {_fmt(getattr(res, 'objective', None))}, converged {'yes' if converged else 'NO'}; "
                  f"WV {_fmt_s(seconds_wv)}, fit {_fmt_s(seconds_fit)}\n")
        if check is not None:
            out.write(_check_text(check) + "\n")
    if not converged:
        msg = str(getattr(res, "message", "")).strip().splitlines()
        err.write("gmwm: warning: the optimizer did not converge"
                  + (f" ({msg[0]})" if msg else "") + "; treat the estimate with care (exit status 3)\n")
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _fmt_s(s: float | None) -> str:
    return "-" if s is None else f"{s:.3f} s"


def _check_json(check: Any) -> Any:
    for attr in ("to_json_dict", "to_dict", "as_dict"):
        if hasattr(check, attr):
            return getattr(check, attr)()
    return check if isinstance(check, dict | list | str | bool) else str(check)


def _check_text(check: Any) -> str:
    if hasattr(check, "summary"):
        return str(check.summary())
    return "identifiability check: " + json.dumps(_check_json(check), default=str)


def cmd_model_wv(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    model, theta = _model_theta(args.model, args.param, args.freq)
    if model.n_params > args.levels:
        # not an error (a theoretical WV is defined anyway) but worth a note for fitting
        err.write(f"gmwm: note: {model.n_params} parameters on {args.levels} scales could not be "
                  "identified from this WV\n")
    levels = np.arange(1, args.levels + 1)
    scales = 2.0 ** levels
    total = model.wv(theta, scales)
    comps = model.component_wv(theta, scales)
    if args.plot:
        from gmwm.plots import plot_model_wv

        _save_plot(plot_model_wv(model, theta, scales, freq=args.freq, units=args.units), args.plot)
    if args.json:
        _print_json({"command": "model-wv", "model": model.spec, "params": model.as_dict(theta),
                     "freq": args.freq, "levels": levels.tolist(), "scales": scales.tolist(),
                     "scales_s": (scales / args.freq).tolist(), "total": total.tolist(),
                     "components": {k: v.tolist() for k, v in comps.items()}}, out)
    else:
        out.write(f"theoretical Haar WV of {model.spec} at freq = {args.freq:g} Hz\n")
        headers = ["level", "scale", "scale_s", "total", *comps]
        rows = [(int(j), s, s / args.freq, t, *(c[i] for c in comps.values()))
                for i, (j, s, t) in enumerate(zip(levels, scales, total, strict=True))]
        out.write(format_table(headers, rows) + "\n")
    return EXIT_OK


# --------------------------------------------------------------------------------------------------
# entry point
# --------------------------------------------------------------------------------------------------


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.strerror or text}: {exc.filename}"
    first = text.splitlines()[0] if text else type(exc).__name__
    return first


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no real file descriptor (e.g. captured)
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gmwm`` command line; return the exit status (see the module docstring)."""
    out, err = sys.stdout, sys.stderr
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    try:
        _check_args(args)
        return args.func(args, out, err)
    except UsageError as exc:
        err.write(f"gmwm: error: {_one_line(exc)} (see 'gmwm {args.command} --help')\n")
        return EXIT_USAGE
    except (GMWMError, ModelError, InputError) as exc:
        err.write(f"gmwm: error: {_one_line(exc)}\n")
        return EXIT_ERROR
    except OSError as exc:
        if isinstance(exc, BrokenPipeError):  # e.g. 'gmwm wv x.npy | head': not an error
            _silence_stdout()
            return EXIT_OK
        err.write(f"gmwm: error: {_one_line(exc)}\n")
        return EXIT_ERROR
    except KeyboardInterrupt:
        err.write("gmwm: error: interrupted\n")
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: still one line, unless --debug
        if args.debug:
            raise
        err.write(f"gmwm: error: internal error ({type(exc).__name__}: {_one_line(exc)}); "
                  "rerun with --debug for the traceback and please report it\n")
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
