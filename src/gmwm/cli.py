"""The ``gmwm`` command line tool: simulate, wv, av, fit, model-wv, report, plan.

Exit status: 0 success; 1 a problem with the input, model or files (one line
``gmwm: error: ...`` on stderr, never a traceback); 2 a usage error (bad options, malformed
``--param``); 3 ``gmwm fit`` ran but the optimizer did not report convergence (the estimate is
still printed, with a warning on stderr); 130 interrupted.

Every fit's diagnostics (boundary estimates, weak identification, ...) are printed as one
``gmwm: warning: ...`` line each on stderr and listed under ``"warnings"`` in ``--json``; Python and
NumPy warning text never reaches the user (numerical transients are dropped, anything else becomes
one ``gmwm: warning:`` line; ``--debug`` shows them all).

Start-up: this module imports only NumPy and the error classes; every subcommand imports what it
needs when it runs, so ``gmwm --help`` does not load SciPy, Numba or matplotlib.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import re
import sys
import threading
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn, TextIO

from gmwm import __version__
from gmwm.errors import GMWMError, IdentifiabilityError, InputError, ModelError

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NOT_CONVERGED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

_EXIT_STATUS_HELP = """exit status:
  0  success
  1  bad input, model or file (one line 'gmwm: error: ...' on stderr)
  2  usage error (unknown option, malformed --param, ...)
  3  (fit only) the optimizer did not converge: the estimate is printed with a warning"""

_PARAM = re.compile(r"^\s*([A-Za-z][A-Za-z0-9]*\[\d+\]\.[A-Za-z][A-Za-z0-9_]*)\s*=\s*(\S+)\s*$")
#: a model typed with a negative count ('-1*WN') that argparse would take for an option
_NEGATIVE_COUNT = re.compile(r"^-\d+(\.\d*)?\s*\*\s*[A-Za-z]")
#: levels beyond this give scales 2^J that overflow the model formulas (and no signal has them)
MAX_MODEL_LEVELS = 60
#: samples of the warm-up call that loads the compiled WV kernel (reported as the first-call cost)
_WARMUP_SAMPLES = 1024
#: .npy / HDF5 inputs of at least this many bytes are streamed (gmwm.stream); raw binary always
_STREAM_MIN_BYTES = 64 << 20


class _LazyNumpy:
    """NumPy, imported on first attribute access: ``gmwm --help`` and usage errors never load it."""

    def __getattr__(self, name: str) -> Any:
        import numpy

        return getattr(numpy, name)


np: Any = _LazyNumpy()


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


class _Progress:
    """Per-stage lines on stderr (``gmwm: [  1.2 s] fitting ...``) when stderr is a terminal and
    ``--quiet`` is not given; a no-op otherwise."""

    def __init__(self, err: TextIO, quiet: bool) -> None:
        self.err = err
        self.on = not quiet and _isatty(err)
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        if self.on:
            self.err.write(f"gmwm: [{time.perf_counter() - self.t0:6.1f} s] {message}\n")
            self.err.flush()


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


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


def _int_at_least(text: str, low: int, what: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < low:
        raise argparse.ArgumentTypeError(f"must be a {what} integer, got {text!r}")
    return v


def _nonneg_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not 0 <= v < float("inf"):  # also refuses NaN
        raise argparse.ArgumentTypeError(f"expected a number of seconds >= 0, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    return _int_at_least(text, 1, "positive")


def _nonneg_int(text: str) -> int:
    return _int_at_least(text, 0, "non-negative")


def _alpha(text: str) -> float:
    v = _positive_float(text)
    if not v < 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1), got {text!r}")
    return v


def _column(text: str) -> str | int:
    return int(text) if re.fullmatch(r"\d+", text.strip()) else text


def _columns(text: str) -> str | list[str | int]:
    """``gx,gy,gz`` / ``1,2,3`` / ``all``."""
    if text.strip().lower() == "all":
        return "all"
    items = [t.strip() for t in text.split(",")]
    if not all(items):
        raise argparse.ArgumentTypeError(f"malformed --columns {text!r}: write names or indices "
                                         "separated by commas, or 'all'")
    return [_column(t) for t in items]


def _add_input(p: argparse.ArgumentParser, what: str = "signal") -> None:
    p.add_argument("input", metavar="FILE",
                   help=f"{what}: ROS 1/2 bag (.bag, .db3, .mcap or a bag folder), PX4 ULog, "
                        "CSV/TSV/text (EuRoC, rostopic echo -p, ';' and decimal commas, .gz), "
                        ".npy, .npz, HDF5 (.h5/.hdf5) or raw binary (--dtype); .npy, HDF5 and raw "
                        f"files of {_STREAM_MIN_BYTES >> 20} MiB or more are streamed (bounded "
                        "memory, the same numbers)")
    p.add_argument("--column", type=_column, default=None,
                   help="CSV column (header name or 0-based index); needed when the file has several "
                        "data columns (a time column aside)")
    p.add_argument("--columns", type=_columns, default=None, metavar="C1,C2,...|all",
                   help="several columns (names or 0-based indices; HDF5: dataset paths), each "
                        "processed on its own; 'all' = every numeric column except a time column")
    p.add_argument("--dataset", default=None,
                   help="HDF5 dataset path (default: the only 1-D dataset in the file)")
    p.add_argument("--topic", default=None,
                   help="bag topic (sensor_msgs/Imu or Vector3Stamped) or ULog topic "
                        "(sensor_combined, sensor_gyro:N, sensor_accel:N); default: the only one")
    p.add_argument("--time-unit", choices=("s", "ms", "us", "ns"), default=None,
                   help="unit of an unlabelled time column (default: from its name, else from "
                        "the magnitude of the stamps; an ambiguous case is an error)")
    p.add_argument("--gaps", choices=("auto", "longest", "combine", "error"), default="auto",
                   help="what a gap in the time stamps does to the WV: 'longest' clean segment, "
                        "'combine' the clean segments' coefficients (fit, report), 'error'; "
                        "'auto' = longest when it holds >= 90%% of the samples, else combine")
    p.add_argument("--start", type=_nonneg_float, default=None, metavar="S",
                   help="use the recording from S seconds after its first sample on")
    p.add_argument("--end", type=_nonneg_float, default=None, metavar="S",
                   help="use the recording up to S seconds after its first sample")
    p.add_argument("--segment", choices=("all", "longest-static"), default="all",
                   help="'longest-static': use the longest stretch (within --start/--end) that "
                        "the stationarity check does not flag")
    p.add_argument("--strict", action="store_true",
                   help="a recording whose used part moved, stepped or shook is an error (exit "
                        "1), not a warning")
    p.add_argument("--dtype", default=None, metavar="DTYPE",
                   help="read FILE as raw binary samples of this NumPy dtype (float32, <i2, "
                        ">f8, ...); channels are named 0, 1, ... (the file's name if only one)")
    p.add_argument("--raw-channels", type=_positive_int, default=1, metavar="N",
                   help="raw binary: channels interleaved per sample row")
    p.add_argument("--raw-offset", type=_nonneg_int, default=0, metavar="BYTES",
                   help="raw binary: header bytes to skip")


def _add_units(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--units", action="append", default=[], metavar="[COLS=]UNIT",
                   help=f"signal unit ({what}): deg/s, rad/s, m/s^2, g (datasheet units) or any "
                        "label; repeatable, 'gx,gy,gz=deg/s' sets it for some columns")


def _add_common(p: argparse.ArgumentParser, levels_help: str, plot: bool = True) -> None:
    p.add_argument("--freq", type=_positive_float, default=None,
                   help="sampling frequency in Hz (default: from the file's time column or HDF5 "
                        "attribute, else 1; a contradiction with the file is an error)")
    p.add_argument("--levels", "-J", type=_positive_int, default=None, metavar="J", help=levels_help)
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    if plot:
        p.add_argument("--plot", metavar="FILE.png", default=None,
                       help="draw a log-log figure to this file (.png, .pdf or .svg)")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress lines on stderr (they are shown only on a terminal anyway)")


def _add_params(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", metavar="MODEL",
                   help="model string, e.g. 'WN+RW+AR1+SIN', '2*AR1+2*SIN', 'QN+WN+2*GM+RW+DR'")
    p.add_argument("--param", "-p", action="append", type=_param, default=[], metavar="NAME=VALUE",
                   help="parameter value, repeatable, e.g. --param 'AR1[1].phi=0.975'. "
                        "Names: WN[k].sigma2 QN[k].Q2 RW[k].gamma2 DR[k].omega AR1[k].phi "
                        "AR1[k].sigma2 GM[k].beta GM[k].sigma2 SIN[k].alpha SIN[k].beta")


_DEFAULT_LEVELS = "number of dyadic scales tau_j = 2^j, j = 1..J (default floor(log2 T) - 1)"
_MODEL_HELP = ("model string, e.g. 'WN+RW+AR1+SIN'; with --columns one model for all or "
               "COL=MODEL pairs separated by commas ('gx=WN+RW,ax=QN+WN+RW'; a bare model is the "
               "default for the other columns)")


def build_parser() -> argparse.ArgumentParser:
    """The ``gmwm`` argument parser and its subcommands."""
    parser = _Parser(
        prog="gmwm",
        formatter_class=_Formatter,
        description=(
            "Stochastic calibration of inertial sensors with the Generalized Method of Wavelet\n"
            "Moments (GMWM): simulate error models, compute Haar wavelet and Allan variances,\n"
            "fit composite models (WN, QN, RW, DR, AR1, GM, SIN), read datasheet coefficients,\n"
            "plan recording lengths, judge a sensor against its datasheet and write calibration\n"
            "reports. Parameters are discrete-time, per sample; scales are\n"
            "filter lengths tau_j = 2^j samples."
        ),
        epilog=(
            "examples:\n"
            "  gmwm simulate 'WN+AR1' -p 'WN[1].sigma2=1' -p 'AR1[1].phi=0.9' -p 'AR1[1].sigma2=0.1' \\\n"
            "       -n 100000 --seed 1 -o x.npy\n"
            "  gmwm wv x.npy --plot wv.png\n"
            "  gmwm fit x.npy 'WN+AR1' --json\n"
            "  gmwm fit imu.csv 'WN+GM+RW' --columns gx,gy,gz --units deg/s\n"
            "  gmwm report imu.csv --columns all --units gx,gy,gz=deg/s --units ax,ay,az=m/s^2 -o rep\n"
            "  gmwm plan --datasheet mti-1 --sensor gyroscope --freq 100 --target BI=10%\n\n"
            + _EXIT_STATUS_HELP
        ),
    )
    parser.add_argument("--version", action="version", version=f"gmwm {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of unexpected errors and every Python warning")
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
    p.add_argument("--quiet", "-q", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=cmd_simulate)

    for name, what in (("wv", "Haar wavelet variance"), ("av", "Allan variance")):
        extra = (
            "AV at cluster length m = 2^(j-1) samples equals 2 x the Haar WV at level j\n"
            "(maximal-overlap estimator, same coefficients). Also prints the IEEE 952 readings:\n"
            "N on the slope -1/2 line at tau = 1 s, K on the slope +1/2 line at tau = 3 s and the\n"
            "bias instability B = AD minimum / 0.664, with 95% CIs, in datasheet units (--units)."
            if name == "av" else
            "Mean square of the boundary-free maximal-overlap Haar coefficients at\n"
            "tau_j = 2^j samples, with chi-square confidence intervals (Percival's eta_3 edof)."
        )
        p = sub.add_parser(
            name, formatter_class=_Formatter, help=f"empirical {what} with confidence intervals",
            description=f"Empirical {what} of a signal at dyadic scales, with {100 * 0.95:g}% CIs.\n"
                        f"{extra}\nWith --columns: one table with a column per channel.",
            epilog=f"examples:\n  gmwm {name} imu.csv --column gyro_z --freq 200 --plot {name}.png\n"
                   f"  gmwm {name} imu.h5 --dataset /imu/gyro_z --freq 200 --json > {name}.json\n"
                   f"  gmwm {name} imu.csv --columns gx,gy,gz -o {name}_table.csv\n\n"
                   + _EXIT_STATUS_HELP,
        )
        _add_input(p)
        _add_common(p, _DEFAULT_LEVELS)
        _add_units(p, "axis labels" + (" and the readings" if name == "av" else ""))
        p.add_argument("--alpha", type=_alpha, default=0.05, help="CI level is 1 - alpha")
        p.add_argument("-o", "--output", metavar="TABLE.csv", default=None,
                       help="also write the table as CSV (readable by 'gmwm fit' as a WV table)")
        if name == "av":
            p.add_argument("--adev", action="store_true",
                           help="plot the Allan deviation with the reading lines (N, K, B) instead "
                                "of the Allan variance")
        if name == "wv":
            _add_robust(p)
        p.set_defaults(func=cmd_wv if name == "wv" else cmd_av)

    p = sub.add_parser(
        "fit", formatter_class=_Formatter, help="fit a composite model to a signal or a WV table",
        description=(
            "Estimate the parameters of a composite model by GMWM (or ARMAV / AVSM).\n"
            "FILE is a signal (.npy, .csv, .h5) or a precomputed wavelet-variance table: a CSV with\n"
            "a header holding 'scale' (tau_j = 2^j samples; or 'scale_s' in seconds, or 'level'),\n"
            "'variance' and optionally 'ci_low', 'ci_high' and 'n' (coefficients per level; without\n"
            "it give the signal length with --n-samples). 'gmwm wv -o' writes such a table (its\n"
            "'scale_s' column records the frequency), 'gmwm av -o' an Allan-variance table that is\n"
            "read the same way (WV = AV / 2). Estimates are per-sample (discrete-time) parameters\n"
            "with sandwich standard errors, followed by the datasheet coefficients in --units."
        ),
        epilog=(
            "examples:\n"
            "  gmwm fit sim1.npy 'WN+RW+AR1+SIN' --plot fit.png\n"
            "  gmwm fit imu.csv 'AR1+RW' --column gyro_z --freq 200 --json\n"
            "  gmwm fit imu.csv 'gx=WN+GM+RW,ax=QN+WN+RW' --columns gx,ax --units gx=deg/s \\\n"
            "       --units ax=m/s^2\n"
            "  gmwm fit wv_table.csv 'WN+RW' --n-samples 2500000 --freq 250\n\n" + _EXIT_STATUS_HELP
        ),
    )
    _add_input(p, what="signal or WV table")
    p.add_argument("model", metavar="MODEL", help=_MODEL_HELP)
    _add_common(p, _DEFAULT_LEVELS + "; with a WV table: use its first J scales")
    _add_units(p, "datasheet coefficients and plot labels")
    _add_fit_options(p)
    p.add_argument("--check", action="store_true",
                   help="also run identifiability checks on the estimate (module gmwm.identify)")
    _add_robust(p)
    _add_datasheet(p)
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
                   help=f"number of dyadic scales tau_j = 2^j, j = 1..J (at most {MAX_MODEL_LEVELS})")
    p.add_argument("--freq", type=_positive_float, default=1.0,
                   help="sampling frequency in Hz (GM parameters; scales in seconds)")
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--plot", metavar="FILE.png", default=None, help="draw the model WV to this file")
    p.add_argument("--units", action="append", default=[], metavar="UNIT",
                   help="signal unit for the plot, e.g. 'deg/s'")
    p.set_defaults(func=cmd_model_wv)

    p = sub.add_parser(
        "report", formatter_class=_Formatter,
        help="calibration report of an IMU: plots, datasheet table, warnings, Kalibr YAML",
        description=(
            "Fit every axis of an IMU recording and write one Markdown page and one HTML page:\n"
            "per axis the WV with the fitted model and its components, the datasheet coefficients\n"
            "with 95% CIs and the fit's warnings, then a YAML block of noise densities in SI units\n"
            "as Kalibr-style tools expect (gyroscope_noise_density, gyroscope_random_walk,\n"
            "accelerometer_noise_density, accelerometer_random_walk, update_rate). Gyroscope and\n"
            "accelerometer axes are told apart by their --units."
        ),
        epilog=(
            "example:\n"
            "  gmwm report imu.csv 'WN+RW' --columns gx,gy,gz,ax,ay,az \\\n"
            "       --units gx,gy,gz=deg/s --units ax,ay,az=m/s^2 -o imu_report\n\n" + _EXIT_STATUS_HELP
        ),
    )
    _add_input(p)
    p.add_argument("model", metavar="MODEL", nargs="?", default="WN+RW",
                   help=_MODEL_HELP + "; WN+RW gives the two terms Kalibr needs")
    _add_common(p, _DEFAULT_LEVELS, plot=False)
    _add_units(p, "datasheet coefficients; deg/s or rad/s marks a gyroscope, m/s^2 or g an "
                  "accelerometer")
    _add_fit_options(p)
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="directory for report.md, report.html, imu.yaml and the figures")
    p.add_argument("--title", default=None, help="page title (default: the input file name)")
    _add_datasheet(p)
    p.set_defaults(func=cmd_report)
    _add_select_parser(sub)
    _add_svo_parser(sub)
    _add_plan_parser(sub)
    return parser


def _add_svo_parser(sub: Any) -> None:
    """``gmwm svo``: virtual gyroscope from redundant signals of one axis (paper 003)."""
    p = sub.add_parser(
        "svo", formatter_class=_Formatter,
        help="virtual gyroscope from redundant gyros (Scale-wise Variance Optimisation)",
        description="Combine p signals of one axis into S = c'X (sum of c = 1) minimising the\n"
                    "omega-weighted Haar wavelet variance of S (SVO, paper 003), with moving-block\n"
                    "bootstrap CIs for c. --method rdvg / equal give the comparison methods.",
        epilog="examples:\n  gmwm svo array.csv --columns g1,g2,g3,g4,g5,g6 --weights short --freq 10\n"
               "  gmwm svo array.npy --columns all --weights long -o virtual_wv.csv --plot svo.png\n"
               "  gmwm svo array.csv --columns all --weights omega.txt --json\n\n"
               + _EXIT_STATUS_HELP,
    )
    p.add_argument("input", metavar="FILE", help="signals: .npy, .csv/.tsv/.txt or HDF5")
    p.add_argument("--columns", type=_columns, required=True, metavar="C1,C2,...|all",
                   help="the p >= 2 signals (names or 0-based indices; HDF5: dataset paths)")
    p.add_argument("--dataset", default=None, help="HDF5 dataset path of a 2-D array")
    p.add_argument("--weights", "-w", default="short", metavar="short|long|equal|FILE",
                   help="scale weights omega: 'short' (paper omega_2, from level 1), 'long' (paper "
                        "omega_1, ending at level J), 'equal', or a file with J numbers "
                        "(renormalised)")
    p.add_argument("--method", choices=("svo", "rdvg", "equal"), default="svo",
                   help="svo (default), rdvg (minimum random-walk variance) or equal weights")
    p.add_argument("--n-boot", type=_nonneg_int, default=500,
                   help="moving-block bootstrap draws for the CIs (0: no CIs)")
    p.add_argument("--block-const", type=_positive_float, default=10.0, metavar="A",
                   help="block length l = A * T^(1/3) samples")
    p.add_argument("--mbb", choices=("paper", "time"), default="paper",
                   help="bootstrap scheme: paper (Algorithm 1 of paper 003) or time (blocks over "
                        "the whole time axis, no refill stretch)")
    p.add_argument("--seed", type=_nonneg_int, default=0, help="seed of the bootstrap draws")
    p.add_argument("--alpha", type=_alpha, default=0.05, help="CI level is 1 - alpha")
    p.add_argument("-o", "--output", metavar="TABLE.csv", default=None,
                   help="write the virtual signal's WV table as CSV (readable by 'gmwm fit')")
    _add_common(p, _DEFAULT_LEVELS)
    p.set_defaults(func=cmd_svo)


def _add_fit_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--weights", choices=("ci", "gaussian", "identity", "efficient"), default="ci",
                   help="weight matrix: inverse squared CI width, Gaussian approximation, identity, "
                        "efficient (two-step, inverse model covariance of the WV)")
    p.add_argument("--method", choices=("gmwm", "armav", "avsm"), default="gmwm",
                   help="gmwm: WV moments; armav: log10 Allan variance; avsm: Allan-variance slopes")
    p.add_argument("--n-samples", type=_positive_int, default=None, metavar="T",
                   help="signal length T, for a WV table without an 'n' column")
    p.add_argument("--n-starts", type=_positive_int, default=None, metavar="K",
                   help="number of optimizer starts (default: the library's)")
    p.add_argument("--seed", type=int, default=0, help="seed for the random starting values")
    p.add_argument("--reweight", type=_nonneg_int, default=0, metavar="K",
                   help="refit K >= 0 times with weights from the fitted model WV (reduces bias)")


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


def _resolve_freq(args: argparse.Namespace, found: float | None, source: str | None,
                  names: Sequence[str]) -> float:
    """--freq, else the file's frequency; both given and different (> 1 %) is an error. Without
    either, per-sample scales (1 Hz) only for a plain signal: a unit or a report needs a time
    base, so that is an error asking for --freq, never a silent 1 Hz."""
    given, where = args.freq, args.input
    if found is None:
        if given is not None:
            return float(given)
        units = _units_by_column(args, list(names))
        with_unit = [c for c, u in units.items() if u]
        if args.command == "report" or with_unit:
            why = "a calibration report" if args.command == "report" else \
                f"coefficients in {units[with_unit[0]]}"
            raise InputError(f"{where} has no time stamps and no sampling frequency: {why} needs "
                             "one; give --freq HZ")
        return 1.0
    if given is None:
        return float(found)
    if abs(given / found - 1.0) > 0.01:
        raise InputError(f"--freq {given:g} contradicts the sampling frequency {found:g} Hz given by "
                         f"the {source} of {where}; drop --freq or fix the file")
    return float(given)


def _wanted_columns(args: argparse.Namespace) -> Any:
    if args.columns is not None and args.column is not None:
        raise UsageError("give --column (one signal) or --columns (several), not both")
    return args.columns if args.columns is not None else (None if args.column is None
                                                          else [args.column])


def _raw_source(args: argparse.Namespace) -> Any:
    from gmwm.stream import RawSource

    if args.dataset is not None:
        raise UsageError("--dataset applies to HDF5 files, not to raw binary (--dtype)")
    return RawSource(args.input, args.dtype, args.raw_channels, args.raw_offset,
                     _wanted_columns(args))


def _stream_min_bytes() -> int:
    """The size from which .npy / HDF5 inputs are streamed (``GMWM_STREAM_MIN_BYTES`` overrides)."""
    env = os.environ.get("GMWM_STREAM_MIN_BYTES", "").strip()
    if not env:
        return _STREAM_MIN_BYTES
    try:
        return max(0, int(float(env)))
    except ValueError:
        raise UsageError(f"GMWM_STREAM_MIN_BYTES must be a number of bytes, got {env!r}") from None


def _open_stream(args: argparse.Namespace) -> Any:
    """A :class:`gmwm.stream.Source` when the input is streamed (raw binary; .npy / HDF5 from
    :func:`_stream_min_bytes` on, in a layout the stream reads), else None. Sets ``args.freq_hz``.
    The robust WV needs the whole signal: never streamed."""
    if getattr(args, "robust", False):
        return None
    if getattr(args, "dtype", None) is not None:
        src = _raw_source(args)
    else:
        p = Path(args.input)
        if p.suffix.lower() not in (".npy", ".h5", ".hdf5") or not p.is_file() \
                or p.stat().st_size < _stream_min_bytes():
            return None
        from gmwm.stream import open_source

        try:
            src = open_source(p, _wanted_columns(args), args.dataset)
        except InputError as exc:  # a layout only the in-memory reader handles (or a bad file:
            # the reader then reports it in its own words)
            args.err.write(f"gmwm: note: {args.input} is read into memory, not streamed "
                           f"({_one_line(exc)})\n")
            return None
    args.freq_hz = _resolve_freq(args, src.freq, src.freq_source, src.names)
    for note in src.notes:
        args.err.write(f"gmwm: warning: {note}\n")
    return src


def _stream_wvs(args: argparse.Namespace, src: Any) -> dict[str, Any]:
    """Streamed WV per channel (:class:`gmwm.stream.ChannelWV`) with the command's options."""
    from gmwm.stream import wvar_stream

    with src:
        _check_levels(src.n_samples, args.levels)
        args.progress(f"streaming {args.input} ({src.n_samples} samples x {len(src.names)} "
                      "channels)")
        return wvar_stream(src, levels=args.levels, alpha=getattr(args, "alpha", 0.05),
                           freq=args.freq_hz)


def _read_input(args: argparse.Namespace, allow_wv: bool = False) -> dict[str, Any]:
    """The requested signals (name -> array; with ``allow_wv`` a pooled WaveletVariance where the
    gap policy combines clean segments); sets ``args.freq_hz`` and ``args.recording``. A unit or
    a report without time stamps or --freq is an error, never 1 Hz."""
    from gmwm.readers.recording import read_recording
    from gmwm.readers.timebase import signal_for_wv

    cols = _wanted_columns(args)
    args.progress(f"reading {args.input}")
    if getattr(args, "dtype", None) is not None:  # raw binary, read whole (e.g. the robust WV)
        with _raw_source(args) as src:
            rows = src.read(0, src.n_samples)
            signals = {n: np.ascontiguousarray(rows[:, i], dtype=np.float64)
                       for i, n in enumerate(src.names)}
        args.freq_hz = _resolve_freq(args, None, None, list(signals))
        for name, x in signals.items():
            bad = ~np.isfinite(x)
            if bad.any():
                raise InputError(f"{args.input} ({name}) contains a non-finite value at sample "
                                 f"{int(np.argmax(bad))}; clean or interpolate it first")
        return signals
    rec = read_recording(args.input, topic=getattr(args, "topic", None), columns=cols,
                         dataset=args.dataset, freq=args.freq,
                         time_unit=getattr(args, "time_unit", None))
    args.recording = rec
    units = _units_by_column(args, list(rec.channels))
    if rec.time is None:
        with_unit = [c for c, u in units.items() if u]
        if args.command == "report" or with_unit:
            why = "a calibration report" if args.command == "report" else \
                f"coefficients in {units[with_unit[0]]}"
            rec.require_time(why)
        args.freq_hz = 1.0  # per-sample scales of a signal without a unit
    else:
        args.freq_hz = rec.time.freq
    for note in rec.notes:
        args.err.write(f"gmwm: warning: {note}\n")
    rec = _stationarity(args, rec, units)
    args.recording = rec
    policy = getattr(args, "gaps", "auto")
    if policy == "combine" and not allow_wv:
        raise UsageError("--gaps combine applies to fit and report (use longest here)")
    decision = rec.gaps(policy if allow_wv or policy != "auto" else "longest")
    if decision.message:
        args.err.write(f"gmwm: warning: {decision.message}\n")
    args.gap_decision = decision
    return {c: signal_for_wv(x, decision, args.levels, args.freq_hz)
            for c, x in rec.channels.items()}


def _stationarity(args: argparse.Namespace, rec: Any, units: dict[str, str]) -> Any:
    """Check the recording for motion (docs/METHODS.md §16), choose the part to use
    (--start/--end, --segment longest-static), print the warnings, and with --strict refuse a
    used part that moved. Sets ``args.stationarity``; returns the recording part to use."""
    from gmwm.readers.recording import sample_range, select_samples
    from gmwm.stationarity import NonStationaryError, check_stationarity

    args.progress("checking stationarity")
    st = check_stationarity(rec, units={c: (u or None) for c, u in units.items()})
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    i0, i1 = (0, rec.n) if start is None and end is None else sample_range(rec, start, end)
    how = "the whole recording" if (i0, i1) == (0, rec.n) else "--start/--end"
    if getattr(args, "segment", "all") == "longest-static":
        free = [(max(a, i0), min(b, i1)) for a, b in _free_stretches(st)]
        free = [(a, b) for a, b in free if b - a > 0]
        if not free:
            raise NonStationaryError(f"--segment longest-static: every part of {args.input} "
                                     "is flagged as moving (" + _ranges(st) + ")")
        a, b = max(free, key=lambda e: e[1] - e[0])
        if b - a < 64:
            raise NonStationaryError(f"--segment longest-static: the longest static stretch of "
                                     f"{args.input} has only {b - a} samples")
        i0, i1 = a, b
        how = "longest static segment" + ("" if how.startswith("the whole") else
                                          " within --start/--end")
    st = st.using(i0, i1, how)
    args.stationarity = st
    if getattr(args, "strict", False) and st.moving_in_used:
        raise NonStationaryError(f"{args.input} is not static in the part used ({_ranges(st)}) "
                                 "and --strict is set: calibrate a static part with --segment "
                                 "longest-static or --start/--end")
    for w in st.warnings():
        args.err.write(f"gmwm: warning: {w}\n")
    if (i0, i1) != (0, rec.n):
        if not st.segments:
            args.err.write(f"gmwm: note: the estimate uses {st.used_text()}\n")
        rec = select_samples(rec, i0, i1)
    return rec


def _free_stretches(st: Any) -> list[tuple[int, int]]:
    """The sample ranges that no flagged segment touches."""
    out, start = [], 0
    for s in st.segments:
        if s.i0 > start:
            out.append((start, s.i0))
        start = max(start, s.i1)
    if start < st.n:
        out.append((start, st.n))
    return out


def _ranges(st: Any, limit: int = 4) -> str:
    a, b = st.used or (0, st.n)
    segs = st.segments_in(a, b) or list(st.segments)
    text = ", ".join(st.span(s.start_s, s.end_s) for s in segs[:limit])
    return text + (f" and {len(segs) - limit} more" if len(segs) > limit else "")


def _by_column(items: Sequence[str], columns: Sequence[str], what: str, default: str | None
               ) -> dict[str, str | None]:
    """Per-column values from 'VALUE' (every other column) and 'C1,C2=VALUE' items."""
    explicit: dict[str, str] = {}
    fallback = default
    for item in items:
        if "=" in item:
            cols, value = item.rsplit("=", 1)
            for c in (t.strip() for t in cols.split(",")):
                if c not in columns:
                    raise InputError(f"{what} for column '{c}', which is not among the columns "
                                     f"used ({', '.join(columns)})")
                explicit[c] = value.strip()
        else:
            fallback = item.strip()
    return {c: explicit.get(c, fallback) for c in columns}


def _units_by_column(args: argparse.Namespace, columns: Sequence[str]) -> dict[str, str]:
    """Per column: the --units given (validated; an unknown unit is an error listing the known
    ones), else the unit the file defines (bags, ULog, EuRoC headers), else ''."""
    from gmwm.datasheet import parse_unit

    given = _by_column(getattr(args, "units", []) or [], columns, "--units", None)
    rec = getattr(args, "recording", None)
    out = {}
    for c in columns:
        file_unit = rec.units.get(c) if rec is not None else None
        u = given.get(c)
        if u:
            pu = parse_unit(u)
            if file_unit and pu != parse_unit(file_unit):
                raise InputError(f"--units {u} for {c} contradicts {args.input}, which says "
                                 f"{file_unit}")
        out[c] = u or file_unit or ""
    return out


def _models_by_column(spec: str, columns: Sequence[str]) -> dict[str, str]:
    """'WN+RW' for every column, or 'gx=WN+RW,ax=QN+WN+RW[,DEFAULT]' pairs."""
    if "=" not in spec:
        return dict.fromkeys(columns, spec)
    default = None
    pairs = {}
    for item in (t.strip() for t in spec.split(",")):
        if not item:
            continue
        if "=" in item:
            col, model = (t.strip() for t in item.split("=", 1))
            pairs[col] = model
        else:
            default = item
    unknown = [c for c in pairs if c not in columns]
    if unknown:
        raise InputError(f"model given for column(s) {', '.join(unknown)}, not among the columns "
                         f"used ({', '.join(columns)}); select them with --columns")
    missing = [c for c in columns if c not in pairs and default is None]
    if missing:
        raise InputError(f"no model for column(s) {', '.join(missing)}: add COL=MODEL pairs or a "
                         "bare default model")
    return {c: pairs.get(c, default) for c in columns}


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
    if isinstance(v, bool):
        return "yes" if v else "no"
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
    from gmwm.atomic import to_jsonable

    out.write(json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")


def _save_plot(ax_or_fig: Any, path: str) -> None:
    from gmwm.atomic import save_figure

    save_figure(getattr(ax_or_fig, "figure", ax_or_fig), path)


_PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".tif", ".tiff")


def _check_args(args: argparse.Namespace) -> None:
    """Checks of option values that argparse cannot do, made before any computation."""
    plot = getattr(args, "plot", None)
    if plot and Path(plot).suffix.lower() not in _PLOT_SUFFIXES:
        raise UsageError(f"--plot {plot}: use a .png, .pdf or .svg file name")
    for opt in ("plot", "output"):
        path = getattr(args, opt, None)
        if path and Path(path).is_dir() and not (args.command == "report" and opt == "output"):
            raise InputError(f"--{opt} {path} is a directory: give a file name")
    if args.command == "report" and Path(args.output).exists() and not Path(args.output).is_dir():
        raise InputError(f"--output {args.output} exists and is not a directory")


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
        **({"robust": True, "efficiency": wv.efficiency} if getattr(wv, "robust", False) else {}),
    }


def _wv_table_rows(wv: Any):
    return [
        (int(lv), s, s / wv.freq, v, lo, hi, int(n))
        for lv, s, v, lo, hi, n in zip(wv.levels, np.asarray(wv.scales, float), wv.variance,
                                       wv.ci_low, wv.ci_high, wv.n, strict=True)
    ]


def _write_csv(args: argparse.Namespace, headers: Sequence[str], rows: Sequence[Sequence]) -> None:
    if not getattr(args, "output", None):
        return
    from gmwm.atomic import write_text_atomic

    if Path(args.output).suffix.lower() != ".csv":
        raise UsageError(f"--output {args.output}: the table is written as CSV, use a .csv name")
    lines = [",".join(headers)] + [",".join(repr(float(v)) if isinstance(v, float | np.floating)
                                            else str(v) for v in r) for r in rows]
    write_text_atomic(args.output, "\n".join(lines) + "\n")


def _fmt_s(s: float | None) -> str:
    return "-" if s is None else f"{s:.3f} s"


def _warn(err: TextIO, messages: Sequence[str], prefix: str = "") -> None:
    err.writelines(f"gmwm: warning: {prefix}{m}\n" for m in messages)


# --------------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------------


def cmd_simulate(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.atomic import write_signal
    from gmwm.readers.tables import SIGNAL_SUFFIXES

    suffix = Path(args.output).suffix.lower()
    if suffix not in SIGNAL_SUFFIXES:  # before a possibly long simulation
        raise InputError(f"unknown output extension '{suffix}' for {args.output}: "
                         f"use one of {', '.join(SIGNAL_SUFFIXES)}")
    model, theta = _model_theta(args.model, args.param, args.freq)
    args.progress(f"simulating {args.n_samples} samples of {model.spec}")
    t0 = time.perf_counter()
    x = model.simulate(theta, args.n_samples, np.random.default_rng(args.seed))
    seconds = time.perf_counter() - t0
    args.progress(f"writing {args.output}")
    path = write_signal(args.output, x)
    if args.json:
        _print_json({"command": "simulate", "model": model.spec, "params": model.as_dict(theta),
                     "n": args.n_samples, "seed": args.seed, "freq": args.freq,
                     "output": str(path), "seconds": seconds}, out)
    else:
        out.write(f"wrote {args.n_samples} samples of {model.spec} (seed {args.seed}) to {path} "
                  f"[{seconds:.3f} s]\n")
    return EXIT_OK


def _wvar(args: argparse.Namespace, x: np.ndarray):
    """The WV of one signal with the command's options (the one place a WV is computed)."""
    from gmwm.wv import wvar

    return wvar(x, levels=args.levels, alpha=args.alpha, freq=args.freq_hz, **_robust_kw(args))


def _import_quietly(name: str, took: dict[str, float]) -> None:
    """Import ``name`` for its side effect (module cache) and record its wall time in
    ``took[name]``; errors surface at the real import."""
    t0 = time.perf_counter()
    with contextlib.suppress(Exception):  # a failing import is reported by the real import
        importlib.import_module(name)
    took[name] = time.perf_counter() - t0


def _compute_wvs(args: argparse.Namespace, signals: dict[str, np.ndarray]) -> tuple[dict, dict]:
    """WV per signal and the timings: ``first_call_s`` (loading the compiled kernel, measured on
    a short warm-up call) apart from ``wv_s`` per signal (the WV and its CI, wall; the first
    signal's includes waiting for the end of scipy.special's import, ``import_s``, which runs
    beside it); ``kernel`` names the classical WV kernel ("c" or "numba")."""
    for x in signals.values():
        _check_levels(x.size, args.levels)
    first = next(iter(signals.values()))
    t0 = time.perf_counter()
    # The CI's chi-square quantiles need scipy.special (~0.2 s to import): import it on a second
    # thread while this one loads the kernel and computes the first WV (the C kernel releases the
    # GIL; so do LLVM's compile and load steps of the Numba fallback). chi2_ci's own import waits
    # for it if it has not finished.
    took: dict[str, float] = {}
    prefetch = threading.Thread(target=_import_quietly, args=("scipy.special", took), daemon=True)
    prefetch.start()
    from gmwm.wv import load_kernel

    kernel = load_kernel(min(first.size, _WARMUP_SAMPLES))
    first_call = time.perf_counter() - t0
    wvs, seconds = {}, {}
    for name, x in signals.items():
        args.progress(f"wavelet variance of {name} ({x.size} samples)")
        t0 = time.perf_counter()
        wvs[name] = _wvar(args, x)
        seconds[name] = time.perf_counter() - t0
    prefetch.join()
    return wvs, {"first_call_s": first_call, "wv_s": seconds, "kernel": kernel,
                 "import_s": took.get("scipy.special", 0.0)}


def _input_wvs(args: argparse.Namespace) -> tuple[dict, dict, float]:
    """WV per channel of the input, the timings of :func:`_compute_wvs` and the read seconds:
    streamed (:func:`_open_stream`; the reading is then part of the WV's seconds) or read whole."""
    t0 = time.perf_counter()
    src = _open_stream(args)
    if src is None:
        signals = _read_input(args)
        read_s = time.perf_counter() - t0
        wvs, timing = _compute_wvs(args, signals)
        return wvs, {**timing, "streamed": False}, read_s
    from gmwm.wv import kernel_name

    got = _stream_wvs(args, src)
    return ({k: v.wv for k, v in got.items()},
            {"first_call_s": 0.0, "wv_s": {k: v.seconds for k, v in got.items()},
             "kernel": kernel_name(), "import_s": 0.0, "streamed": True}, 0.0)


def _channel_table(wvs: dict[str, Any], fields: Sequence[tuple[str, Any]], what: str
                   ) -> tuple[list[str], list[list]]:
    """One CSV table over channels: shared level/scale/n columns, then ``field[channel]``."""
    ref = next(iter(wvs.values()))
    for name, wv in wvs.items():
        if not np.array_equal(wv.n, ref.n):
            raise InputError(f"channel {name} has a different length or number of levels: write the "
                             f"{what} tables of such channels separately")
    headers = ["level", "scale", "scale_s", "n"] + [f"{f}[{c}]" for c in wvs for f, _ in fields]
    rows = []
    for i, (lv, s) in enumerate(zip(ref.levels, np.asarray(ref.scales, float), strict=True)):
        row = [int(lv), s, s / ref.freq, int(ref.n[i])]
        for wv in wvs.values():
            row += [float(get(wv)[i]) for _, get in fields]
        rows.append(row)
    return headers, rows


def _plot_channels(items: dict[str, Any], draw, path: str) -> None:
    """One panel per channel (``draw(obj, ax, name)``), saved to ``path``."""
    from gmwm.plots import channel_grid

    fig, axes = channel_grid(len(items))
    for ax, (name, obj) in zip(axes, items.items(), strict=False):
        draw(obj, ax, name)
        if len(items) > 1:
            ax.set_title(name)
    _save_plot(fig, path)


def cmd_wv(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    wvs, timing, read_s = _input_wvs(args)
    units = _units_by_column(args, list(wvs))
    multi = args.columns is not None
    if args.plot:
        from gmwm.plots import plot_wv

        _plot_channels(wvs, lambda wv, ax, c: plot_wv(wv, ax=ax, units=units[c]), args.plot)
    secs = {"seconds_read": read_s, "seconds_first_call": timing["first_call_s"],
            "seconds_import_scipy": timing["import_s"], "wv_kernel": timing["kernel"],
            "streamed": timing["streamed"]}
    if not multi:
        name, wv = next(iter(wvs.items()))
        headers = ["level", "scale", "scale_s", "variance", "ci_low", "ci_high", "n"]
        rows = _wv_table_rows(wv)
        _write_csv(args, headers, rows)
        seconds = timing["wv_s"][name]
        if args.json:
            _print_json({"command": "wv", "input": args.input, **_wv_dict(wv), "seconds": seconds,
                         **secs}, out)
        else:
            out.write(f"Haar wavelet variance of {args.input}: T = {wv.n_samples} samples, "
                      f"freq = {wv.freq:g} Hz, {100 * (1 - wv.alpha):g}% CI, {seconds:.3f} s\n")
            out.write(format_table(headers, rows) + "\n")
        return EXIT_OK
    headers, rows = _channel_table(
        wvs, [("variance", lambda w: w.variance), ("ci_low", lambda w: w.ci_low),
              ("ci_high", lambda w: w.ci_high)], "WV")
    _write_csv(args, headers, rows)
    if args.json:
        _print_json({"command": "wv", "input": args.input, "columns": list(wvs),
                     "wv": {c: _wv_dict(w) for c, w in wvs.items()}, "seconds": timing["wv_s"],
                     **secs}, out)
    else:
        ref = next(iter(wvs.values()))
        out.write(f"Haar wavelet variance of {args.input}: {len(wvs)} channels, T = {ref.n_samples} "
                  f"samples, freq = {ref.freq:g} Hz, {sum(timing['wv_s'].values()):.3f} s\n")
        _write_channel_text(out, wvs, lambda w: w.variance, "variance")
    return EXIT_OK


def _write_channel_text(out: TextIO, items: dict[str, Any], values, what: str) -> None:
    """Text table: level, scale, scale_s, then one ``what`` column per channel."""
    longest = max(items.values(), key=lambda w: len(w.levels))
    headers = ["level", "scale", "scale_s", *items]
    rows = []
    for i, lv in enumerate(longest.levels):
        s = float(np.asarray(longest.scales, float)[i]) if hasattr(longest, "scales") else None
        row: list[Any] = [int(lv), s, None if s is None else s / longest.freq]
        for w in items.values():
            v = values(w)
            row.append(float(v[i]) if i < len(v) else None)
        rows.append(row)
    out.write(f"{what} per channel:\n" + format_table(headers, rows) + "\n")


def cmd_av(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.datasheet import allan_readings
    from gmwm.wv import AllanVariance

    wvs, timing, read_s = _input_wvs(args)
    avs = {c: AllanVariance.from_wv(w) for c, w in wvs.items()}
    units = _units_by_column(args, list(avs))
    readings = {c: allan_readings(av, units[c] or None) for c, av in avs.items()}
    if args.plot:
        from gmwm.plots import plot_av

        _plot_channels(avs, lambda av, ax, c: plot_av(av, ax=ax, units=units[c], deviation=args.adev,
                                                      readings=readings[c] if args.adev else None),
                       args.plot)
    multi = args.columns is not None
    secs = {"seconds_read": read_s, "seconds_first_call": timing["first_call_s"],
            "seconds_import_scipy": timing["import_s"], "wv_kernel": timing["kernel"],
            "streamed": timing["streamed"]}
    if not multi:
        name, av = next(iter(avs.items()))
        m = np.asarray(av.clusters, dtype=float)
        var = np.asarray(av.avar, float)
        lo, hi = np.asarray(av.ci_low, float), np.asarray(av.ci_high, float)
        n = np.asarray(av.n)
        headers = ["cluster_m", "tau_s", "allan_var", "ci_low", "ci_high", "allan_dev", "n"]
        rows = [(int(mi), mi / av.freq, v, a, b, np.sqrt(v), int(k))
                for mi, v, a, b, k in zip(m, var, lo, hi, n, strict=True)]
        _write_csv(args, headers, rows)
        seconds = timing["wv_s"][name]
        if args.json:
            _print_json({
                "command": "av", "input": args.input, "levels": np.asarray(av.levels).tolist(),
                "cluster": m.astype(int).tolist(),
                "tau_s": (m / av.freq).tolist(), "variance": var.tolist(), "ci_low": lo.tolist(),
                "ci_high": hi.tolist(), "deviation": np.sqrt(var).tolist(), "n": n.tolist(),
                "n_samples": int(av.n_samples), "freq": av.freq, "alpha": args.alpha,
                "units": units[name] or None, "readings": readings[name], "seconds": seconds, **secs,
            }, out)
        else:
            out.write(f"Allan variance (maximal overlap) of {args.input}: T = {av.n_samples} samples, "
                      f"freq = {av.freq:g} Hz, {100 * (1 - args.alpha):g}% CI, {seconds:.3f} s\n")
            out.write(format_table(headers, rows) + "\n")
            out.write(_readings_text({name: readings[name]}, single=True) + "\n")
        return EXIT_OK
    headers, rows = _av_channel_table(avs)
    _write_csv(args, headers, rows)
    if args.json:
        _print_json({"command": "av", "input": args.input, "columns": list(avs),
                     "av": {c: {**av.to_dict(), "units": units[c] or None}
                            for c, av in avs.items()},
                     "readings": readings, "seconds": timing["wv_s"], **secs}, out)
    else:
        ref = next(iter(avs.values()))
        out.write(f"Allan deviation (maximal overlap) of {args.input}: {len(avs)} channels, "
                  f"T = {ref.n_samples} samples, freq = {ref.freq:g} Hz\n")
        headers_t = ["cluster_m", "tau_s", *avs]
        rows_t = [[int(mv), float(tv), *(float(a.adev[i]) if i < a.adev.size else None
                                         for a in avs.values())]
                  for i, (mv, tv) in enumerate(zip(ref.clusters, ref.tau, strict=True))]
        out.write(format_table(headers_t, rows_t) + "\n")
        out.write(_readings_text(readings, single=False) + "\n")
    return EXIT_OK


def _av_channel_table(avs: dict[str, Any]) -> tuple[list[str], list[list]]:
    ref = next(iter(avs.values()))
    for name, av in avs.items():
        if not np.array_equal(av.n, ref.n):
            raise InputError(f"channel {name} has a different length or number of levels: write the "
                             "AV tables of such channels separately")
    headers = ["cluster_m", "tau_s", "n"] + [f"{f}[{c}]" for c in avs
                                             for f in ("allan_var", "ci_low", "ci_high", "allan_dev")]
    rows = []
    for i, m in enumerate(ref.clusters):
        row: list[Any] = [int(m), float(ref.tau[i]), int(ref.n[i])]
        for av in avs.values():
            row += [float(av.avar[i]), float(av.ci_low[i]), float(av.ci_high[i]), float(av.adev[i])]
        rows.append(row)
    return headers, rows


def _readings_text(readings: dict[str, dict], single: bool) -> str:
    headers = ([] if single else ["column"]) + ["reading", "value", "ci95_low", "ci95_high", "unit",
                                                 "from"]
    rows = []
    for col, r in readings.items():
        for key in ("N", "K", "B"):
            e = r[key]
            ci = e.get("ci95") or [None, None]
            if key == "B":
                where = f"AD minimum at tau = {e['tau_s']:.4g} s" + (
                    " (last scale: floor not reached, upper bound)" if e["at_end"] else "")
            elif e.get("value") is None:
                where = e.get("note", "")
            else:
                lo_t, hi_t = e["tau_range_s"]
                where = (f"slope {'-' if key == 'N' else '+'}1/2 over tau {lo_t:.4g}-{hi_t:.4g} s, "
                         f"read at {e['read_at_tau_s']:g} s" + (" (extrapolated)" if e["extrapolated"]
                                                                 else ""))
            label = f"{key} ({e['name']})" if key != "B" else "B (bias instability)"
            rows.append(([] if single else [col]) + [label, e.get("value"), ci[0], ci[1], e["unit"],
                                                     where])
    return "IEEE 952 Allan-deviation readings:\n" + format_table(headers, rows)


# ---- fit -------------------------------------------------------------------------------------


def _fit_data(args: argparse.Namespace) -> tuple[dict[str, Any], bool]:
    """Per-column data (a signal, or a WaveletVariance from a table) and whether it is a table;
    sets ``args.freq_hz``."""
    from gmwm.readers.tables import is_wv_table, read_wv_table, table_channels

    p = Path(args.input)
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if args.dtype is None and is_wv_table(p):  # --dtype: raw binary, whatever the name
        if (args.start is not None or args.end is not None or args.segment != "all"
                or args.strict):
            raise UsageError("--start/--end/--segment/--strict apply to recordings, not to a WV "
                             "table")
        channels = table_channels(p)
        if args.columns is None:
            wanted: list[Any] = [None] if args.column is None else [str(args.column)]
        elif args.columns == "all":
            wanted = channels or [None]
        else:
            wanted = [str(c) for c in args.columns]
        data = {}
        for c in wanted:
            wv = read_wv_table(p, n_samples=args.n_samples, freq=args.freq, channel=c)
            if args.levels is not None:
                if args.levels > wv.n_levels:
                    raise InputError(f"--levels {args.levels} but the table {args.input} has "
                                     f"{wv.n_levels} scales")
                wv = wv.subset(np.arange(1, args.levels + 1))
            data[p.stem if c is None else c] = wv
        args.freq_hz = next(iter(data.values())).freq
        return data, True
    if args.n_samples is not None:
        raise UsageError("--n-samples applies to a WV table (a CSV with 'scale' and 'variance' columns)")
    src = _open_stream(args)
    if src is not None:  # a WV is all a fit needs: stream it, keep the drift sign and timing
        args.streamed = _stream_wvs(args, src)
        return {k: v.wv for k, v in args.streamed.items()}, False
    data = _read_input(args, allow_wv=True)
    return data, any(not isinstance(d, np.ndarray) for d in data.values())


def _run_fit(args: argparse.Namespace, data: Any, model: Any) -> tuple[Any, float | None]:
    """The fit result and the seconds spent computing the WV here (None: the result knows)."""
    levels = args.levels if isinstance(data, np.ndarray) else None  # a table is already subset
    if getattr(args, "robust", False):  # robust WV here, then the usual fit on it
        if not isinstance(data, np.ndarray):
            raise UsageError("--robust needs the signal; a WV table is already an estimate")
        from gmwm.wv import wvar

        t0 = time.perf_counter()
        wv = wvar(data, levels=levels, freq=args.freq_hz, **_robust_kw(args))
        seconds = time.perf_counter() - t0
        res, _ = _run_fit(argparse.Namespace(**{**vars(args), "robust": False}), wv, model)
        return res, seconds
    if args.method == "avsm":
        try:
            from gmwm.avsm import fit_avsm
        except ModuleNotFoundError as exc:
            raise GMWMError(f"--method avsm needs the module {exc.name}, not available here") from None
        seconds_wv = 0.0
        if isinstance(data, np.ndarray):
            from gmwm.wv import wvar

            t0 = time.perf_counter()
            data = wvar(data, levels=levels, freq=args.freq_hz)
            seconds_wv = time.perf_counter() - t0
        return fit_avsm(data, model), seconds_wv
    import gmwm

    options = {} if args.n_starts is None else {"n_starts": args.n_starts}
    res = gmwm.fit(data, model, levels=levels, freq=args.freq_hz, weights=args.weights,
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


def _fit_warnings(res: Any) -> list[str]:
    """The fit's diagnostics warnings (the non-convergence one is reported with exit status 3)."""
    found = list((getattr(res, "diagnostics", None) or {}).get("warnings", []))
    if not getattr(res, "converged", True):
        found = [w for w in found if "converge" not in w.lower()]
    return [str(w) for w in found]


def _fit_columns(args: argparse.Namespace) -> tuple[dict[str, dict[str, Any]], bool]:
    """Fit every requested column; per column the result, timings, check, warnings, unit."""
    from gmwm.model import Model

    identify = _identify_module() if getattr(args, "check", False) else None
    data, is_table = _fit_data(args)
    streamed = getattr(args, "streamed", None) or {}
    models = _models_by_column(args.model, list(data))
    units = _units_by_column(args, list(data))
    built = {}
    for name, d in data.items():
        model = Model(models[name], freq=args.freq_hz)
        if name in streamed:
            _check_levels(d.n_samples, args.levels, model.n_params)
        elif is_table:
            if model.n_params > d.n_levels:
                raise IdentifiabilityError(
                    f"model has {model.n_params} parameters but the table has only {d.n_levels} "
                    "scales: more parameters than scales cannot be identified")
        else:
            _check_levels(d.size, args.levels, model.n_params)
        built[name] = model
    fits: dict[str, dict[str, Any]] = {}
    for name, d in data.items():
        model = built[name]
        args.progress(f"fitting {model.spec} to {name}")
        t0 = time.perf_counter()
        res, seconds_wv = _run_fit(args, d, model)
        elapsed = time.perf_counter() - t0
        if name in streamed:  # the WV was streamed for all channels together, before the fit
            from gmwm.select import _fix_drift_sign

            if args.method != "avsm":
                res = _fix_drift_sign(res, streamed[name].drift_sign)
            seconds_wv = streamed[name].seconds
        elif is_table:
            seconds_wv = 0.0
        elif seconds_wv is None:
            seconds_wv = getattr(res, "seconds_wv", None)
        seconds_fit = getattr(res, "seconds_fit", None)
        if seconds_fit is None:
            seconds_fit = elapsed - (seconds_wv or 0.0)
        check = None
        if identify is not None:
            if not hasattr(identify, "check"):
                raise GMWMError("--check: gmwm.identify does not provide check(result) yet")
            args.progress(f"identifiability check of {name}")
            check = identify.check(res)
        fits[name] = {"result": res, "seconds_wv": seconds_wv, "seconds_fit": seconds_fit,
                      "check": check, "warnings": _fit_warnings(res), "units": units[name]}
    return fits, is_table


def _datasheet(res: Any, units: str) -> dict[str, Any]:
    from gmwm.units import datasheet

    return datasheet(res, units or None)


def _fit_json(args: argparse.Namespace, name: str, f: dict[str, Any]) -> dict[str, Any]:
    res = f["result"]
    names = list(res.param_names)
    params = np.asarray(res.params, float)
    se = getattr(res, "se", None)  # AVSM has no standard errors
    se = [None] * len(names) if se is None else [float(s) for s in np.asarray(se, float)]
    obj = {
        "command": "fit", "input": args.input, "model": res.model.spec, "method": args.method,
        "weights": args.weights, "n": int(res.wv.n_samples), "freq": float(res.wv.freq),
        "params": dict(zip(names, params, strict=True)),
        "se": dict(zip(names, se, strict=True)),
        "objective": getattr(res, "objective", None),
        "converged": bool(getattr(res, "converged", True)),
        "message": str(getattr(res, "message", "")),
        "warnings": f["warnings"],
        "units": f["units"] or None,
        "datasheet": _datasheet(res, f["units"]),
        "wv": _wv_dict(res.wv), "seconds_wv": f["seconds_wv"], "seconds_fit": f["seconds_fit"],
    }
    if f["check"] is not None:
        obj["check"] = _check_json(f["check"])
    if f.get("verdict") is not None:
        obj["datasheet_verdict"] = {k: v for k, v in f["verdict"].items() if k != "curves"}
    return obj


def datasheet_rows(ds: dict[str, dict]) -> list[tuple]:
    """Rows (term, quantity, value, ci95_low, ci95_high, unit) of a datasheet dict."""
    rows = []
    for term, e in ds.items():
        parts = [("", e)] if "value" in e else list(e.items())
        for what, v in parts:
            ci = v.get("ci95") or [None, None]
            rows.append((term, what, v["value"], ci[0], ci[1], v["unit"]))
    return rows


def _fit_text(args: argparse.Namespace, name: str | None, f: dict[str, Any], out: TextIO) -> None:
    res = f["result"]
    names = list(res.param_names)
    params = np.asarray(res.params, float)
    se = getattr(res, "se", None)
    se = [None] * len(names) if se is None else [float(s) for s in np.asarray(se, float)]
    converged = bool(getattr(res, "converged", True))
    how = "AVSM" if args.method == "avsm" else f"{args.method.upper()} ({args.weights} weights)"
    what = args.input if name is None else f"{name} of {args.input}"
    out.write(f"{how} fit of {res.model.spec} to {what}: T = {res.wv.n_samples} samples, "
              f"J = {res.wv.n_levels} scales, freq = {res.wv.freq:g} Hz\n")
    z = 1.959963984540054  # normal 97.5% quantile: 95% Wald intervals from the sandwich SE
    rows = [(n, p, s, None if s is None else p - z * s, None if s is None else p + z * s)
            for n, p, s in zip(names, params, se, strict=True)]
    out.write(format_table(["parameter", "estimate", "se", "ci95_low", "ci95_high"], rows) + "\n")
    ds_rows = datasheet_rows(_datasheet(res, f["units"]))
    if ds_rows:
        unit = f["units"] or "signal units"
        out.write(f"datasheet coefficients (signal in {unit}):\n")
        out.write(format_table(["term", "quantity", "value", "ci95_low", "ci95_high", "unit"],
                               ds_rows) + "\n")
    out.write(f"objective {_fmt(getattr(res, 'objective', None))}, converged {'yes' if converged else 'NO'}; "
              f"WV {_fmt_s(f['seconds_wv'])}, fit {_fmt_s(f['seconds_fit'])}\n")
    if f["check"] is not None:
        out.write(_check_text(f["check"]) + "\n")
    if f.get("verdict") is not None:
        out.write(_verdict_text(f["verdict"]) + "\n")


def _fit_status(fits: dict[str, dict[str, Any]], err: TextIO, multi: bool) -> int:
    """Warning lines on stderr; exit status 3 when a fit did not converge."""
    status = EXIT_OK
    for name, f in fits.items():
        prefix = f"{name}: " if multi else ""
        _warn(err, f["warnings"], prefix)
        res = f["result"]
        if not getattr(res, "converged", True):
            msg = str(getattr(res, "message", "")).strip().splitlines()
            err.write(f"gmwm: warning: {prefix}the optimizer did not converge"
                      + (f" ({msg[0]})" if msg else "") + "; treat the estimate with care (exit status 3)\n")
            status = EXIT_NOT_CONVERGED
    return status


def cmd_fit(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    sheet = _load_datasheet(args)
    fits, _ = _fit_columns(args)
    multi = args.columns is not None
    _attach_verdicts(fits, sheet, err, multi)
    if args.plot and sheet is not None:
        _plot_with_datasheet(fits, args.plot)
    elif args.plot:
        from gmwm.plots import plot_wv

        _plot_channels(fits, lambda f, ax, c: plot_wv(f["result"].wv, result=f["result"], ax=ax,
                                                      units=f["units"]), args.plot)
    st = getattr(args, "stationarity", None)
    if args.json:
        objs = {c: _fit_json(args, c, f) for c, f in fits.items()}
        if multi:
            obj = {"command": "fit", "input": args.input, "fits": objs}
        else:
            obj = next(iter(objs.values()))
        if st is not None:
            obj["stationarity"] = st.to_json_dict()
        _print_json(obj, out)
    else:
        if st is not None and st.used not in (None, (0, st.n)):
            out.write(f"recording part used: {st.used_text()}\n")
        for i, (c, f) in enumerate(fits.items()):
            if i:
                out.write("\n")
            _fit_text(args, c if multi else None, f, out)
    return _fit_status(fits, err, multi)


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
    if args.levels > MAX_MODEL_LEVELS:
        raise InputError(f"--levels {args.levels} is too large: scales 2^j beyond 2^{MAX_MODEL_LEVELS} "
                         f"samples exceed any recording (at most J = {MAX_MODEL_LEVELS})")
    model, theta = _model_theta(args.model, args.param, args.freq)
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

        _save_plot(plot_model_wv(model, theta, scales, freq=args.freq, units=units), args.plot)
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


def cmd_report(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.report import write_report

    args.check = False
    sheet = _load_datasheet(args)
    fits, _ = _fit_columns(args)
    _attach_verdicts(fits, sheet, err, True)
    args.progress(f"writing the report to {args.output}")
    per_axis = {c: {"result": f["result"], "units": f["units"], "warnings": f["warnings"],
                    "datasheet": _datasheet(f["result"], f["units"]),
                    "verdict": f.get("verdict")} for c, f in fits.items()}
    st = getattr(args, "stationarity", None)
    if st is not None:  # each flagged axis says so in its own section and in the summary
        a, b = st.used or (0, st.n)
        for c, entry in per_axis.items():
            segs = [s for s in st.segments_in(a, b) if c in s.channels]
            if segs:
                where = ", ".join(st.span(s.start_s, s.end_s) for s in segs[:4])
                entry["warnings"] = [*entry["warnings"], f"not static in {where}"
                                     + (f" and {len(segs) - 4} more ranges" if len(segs) > 4
                                        else "") + " (see Stationarity): the coefficients "
                                     "include that motion"]
    rec, gaps = getattr(args, "recording", None), getattr(args, "gap_decision", None)
    timing = None
    if rec is not None and rec.time is not None:
        timing = [f"Recording ({rec.format}{', topic ' + rec.topic if rec.topic else ''}): "
                  + rec.time.summary()]
        if gaps is not None and gaps.message:
            timing.append(gaps.message)
    files = write_report(args.output, per_axis, source=args.input,
                         title=args.title or f"Calibration report: {Path(args.input).name}",
                         timing=timing, stationarity=st)
    if args.json:
        obj = {"command": "report", "input": args.input, "files": [str(p) for p in files],
               "fits": {c: _fit_json(args, c, f) for c, f in fits.items()}}
        if st is not None:
            obj["stationarity"] = st.to_json_dict()
        _print_json(obj, out)
    else:
        out.write(f"report of {len(fits)} axes of {args.input} written to: "
                  + ", ".join(str(p) for p in files if p.suffix in (".md", ".html", ".yaml")) + "\n")
    return _fit_status(fits, err, True)


# --------------------------------------------------------------------------------------------------
# datasheets (fit, report) and the plan command (gmwm.sensor_datasheet, gmwm.plan)
# --------------------------------------------------------------------------------------------------

_DATASHEET_HELP = ("sensor datasheet: a YAML file of noise terms in datasheet units (see "
                   "docs/METHODS.md §17.1) or a packaged example: adis16448, mti-1, stim300")


def _add_datasheet(p: argparse.ArgumentParser) -> None:
    p.add_argument("--datasheet", metavar="FILE", default=None,
                   help=_DATASHEET_HELP + "; adds a verdict table per axis (within / better / "
                        "worse than the datasheet) and draws the datasheet's WV and Allan "
                        "deviation beside the measured ones (needs --units per axis)")


def _load_datasheet(args: argparse.Namespace) -> Any:
    if not getattr(args, "datasheet", None):
        return None
    from gmwm.sensor_datasheet import load_datasheet

    return load_datasheet(args.datasheet)


def _attach_verdicts(fits: dict[str, dict[str, Any]], sheet: Any, err: TextIO, multi: bool
                     ) -> None:
    """Per column the datasheet verdict (``f["verdict"]``); a column the datasheet does not cover
    (no section for its sensor type) gets a warning, a column without a known unit an error."""
    if sheet is None:
        return
    from gmwm.datasheet import parse_unit
    from gmwm.sensor_datasheet import judge

    covered = 0
    for name, f in fits.items():
        parsed = parse_unit(f["units"]) if f["units"] else None
        if parsed is None:
            raise InputError(f"--datasheet: give the unit of {name} with --units (e.g. deg/s or "
                             "m/s^2) to tell a gyroscope from an accelerometer")
        if parsed[2] not in sheet.sensors:
            err.write(f"gmwm: warning: {name + ': ' if multi else ''}the datasheet "
                      f"{sheet.where} has no {parsed[2]} section: no verdict\n")
            f["verdict"] = None
            continue
        f["verdict"] = judge(f["result"], sheet, f["units"])
        covered += 1
    if not covered:
        raise InputError(f"--datasheet {sheet.where}: no fitted column is of a sensor type it "
                         f"describes ({', '.join(sheet.sensors)})")


def _verdict_text(v: dict[str, Any]) -> str:
    rows = [(r["term"] + (f" {r['quantity']}" if r["quantity"] else ""), r["datasheet"],
             r["measured"], *(r["ci95"] or [None, None]), r["unit"], r["verdict"])
            for r in v["rows"]]
    lines = [f"against the {v['sensor']} section of the datasheet {v['part']}"
             + (f" ({v['source']})" if v["source"] else "") + ":",
             format_table(["term", "datasheet", "measured", "ci95_low", "ci95_high", "unit",
                           "verdict"], rows)]
    lines += [f"  {r['term']}: {r['note']}" for r in v["rows"] if r.get("note")]
    lines.append(f"  rule: {v['rule']}")
    return "\n".join(lines)


def _plot_with_datasheet(fits: dict[str, dict[str, Any]], path: str) -> None:
    """Per column one row: WV with the fit and the datasheet's WV; Allan deviation with the
    datasheet's."""
    from gmwm.plots import add_datasheet_line, channel_grid, plot_av, plot_wv
    from gmwm.wv import AllanVariance

    fig, axes = channel_grid(2 * len(fits), ncols=2)
    for i, (name, f) in enumerate(fits.items()):
        res, v = f["result"], f.get("verdict")
        ax_wv, ax_ad = axes[2 * i], axes[2 * i + 1]
        plot_wv(res.wv, result=res, ax=ax_wv, units=f["units"])
        plot_av(AllanVariance.from_wv(res.wv), deviation=True, ax=ax_ad, units=f["units"])
        if v is not None:
            c = v["curves"]
            add_datasheet_line(ax_wv, c["scales_s"], c["wv"], v["label"])
            add_datasheet_line(ax_ad, c["tau_s"], c["adev"], v["label"])
        if len(fits) > 1:
            ax_wv.set_title(f"{name}: WV")
            ax_ad.set_title(f"{name}: Allan deviation")
    _save_plot(fig, path)


def _add_plan_parser(sub: Any) -> None:
    p = sub.add_parser(
        "plan", formatter_class=_Formatter,
        help="how long to record: predicted precision of every coefficient by recording length",
        description=(
            "Plan a static recording before making it: from a datasheet (--datasheet, noise terms\n"
            "in datasheet units) or a model with parameter values (MODEL -p ...), predict the\n"
            "relative standard error and 95% interval of every coefficient that the default fit\n"
            "('gmwm fit') will report, for recording lengths from minutes to days; the length from\n"
            "which each term is identifiable (each parameter's 95% Wald interval excludes 0); and\n"
            "with --target the length a precision needs. The prediction is the fit's own sandwich\n"
            "standard error (model covariance of the WV, default weights) at the given values.\n"
            "A datasheet's bias instability becomes a Gauss-Markov term whose Allan-deviation\n"
            "peak is the floor 0.664 B (correlation time from the file or a stated rule)."
        ),
        epilog=(
            "examples:\n"
            "  gmwm plan --datasheet mti-1 --sensor gyroscope --freq 100\n"
            "  gmwm plan --datasheet my_imu.yaml --freq 200 --duration 30min --duration 2h \\\n"
            "       --target BI=10% --plot plan.png\n"
            "  gmwm plan 'WN+RW' -p 'WN[1].sigma2=1.25e-3' -p 'RW[1].gamma2=3.9e-11' --freq 200 \\\n"
            "       --units deg/s --target RRW=20% --json\n\n" + _EXIT_STATUS_HELP
        ),
    )
    p.add_argument("model", metavar="MODEL", nargs="?", default=None,
                   help="model string (instead of --datasheet), with its values given by -p")
    p.add_argument("--param", "-p", action="append", type=_param, default=[], metavar="NAME=VALUE",
                   help="parameter value of MODEL (per sample, as in 'gmwm fit'), repeatable")
    p.add_argument("--datasheet", metavar="FILE", default=None, help=_DATASHEET_HELP)
    p.add_argument("--sensor", choices=("gyroscope", "accelerometer"), default=None,
                   help="with --datasheet: plan this sensor only (default: every sensor it has)")
    p.add_argument("--freq", type=_positive_float, default=None,
                   help="sampling frequency in Hz (default: the datasheet's 'rate', if it has one)")
    p.add_argument("--units", default=None, metavar="UNIT",
                   help="signal unit: of MODEL's parameters, or the unit the datasheet model is "
                        "written in (default deg/s for a gyroscope, m/s^2 for an accelerometer); "
                        "sets the units of the coefficients")
    p.add_argument("--duration", action="append", default=[], metavar="LENGTH",
                   help="recording length of a table row, repeatable, e.g. 30min, 2h, 1d "
                        "(default: eight lengths from 10min to 3d, gmwm.plan.DEFAULT_DURATIONS)")
    p.add_argument("--target", action="append", default=[], metavar="NAME=PRECISION",
                   help="the length a coefficient or parameter needs for this relative standard "
                        "error, repeatable, e.g. RRW=20%%, BI=10%%, 'WN[1].sigma2=1%%'")
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--plot", metavar="FILE.png", default=None,
                   help="draw the relative standard error of every coefficient against the length")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=cmd_plan)


def _plan_inputs(args: argparse.Namespace) -> list[dict[str, Any]]:
    """What to plan: per sensor (or the one model) the model, values, unit and notes."""
    from gmwm.datasheet import parse_unit

    if (args.datasheet is None) == (args.model is None):
        raise UsageError("give a datasheet (--datasheet FILE) or a MODEL with -p values, not both")
    if args.datasheet is None:
        if args.sensor:
            raise UsageError("--sensor applies to --datasheet")
        if args.freq is None:
            raise UsageError("give the sampling frequency with --freq")
        unit = args.units
        if unit:
            parse_unit(unit)
        model, theta = _model_theta(args.model, args.param, args.freq)
        return [{"name": None, "model": model, "theta": theta, "unit": unit or None,
                 "notes": [], "bi": None, "sheet": None}]
    if args.param:
        raise UsageError("-p gives the values of a MODEL; a datasheet carries its own")
    from gmwm.sensor_datasheet import load_datasheet, to_model

    sheet = load_datasheet(args.datasheet)
    freq = args.freq if args.freq is not None else sheet.rate
    if freq is None:
        raise UsageError(f"give the sampling frequency with --freq (the datasheet {sheet.where} "
                         "has no 'rate')")
    sensors = [args.sensor] if args.sensor else list(sheet.sensors)
    items = []
    for sensor in sensors:
        spec = sheet.sensor(sensor)
        unit = args.units
        if unit is not None:
            parsed = parse_unit(unit)
            if parsed is None or parsed[2] != sensor:
                if len(sensors) > 1:
                    raise UsageError(f"--units {unit} is not a {sensor} unit; with a datasheet "
                                     "of several sensors choose one with --sensor")
                raise InputError(f"--units {unit} is not a {sensor} unit")
        unit = unit or ("deg/s" if sensor == "gyroscope" else "m/s^2")
        dm = to_model(spec, freq, unit)
        notes = list(dm.notes)
        if args.freq is None:
            notes.insert(0, f"sampling frequency {freq:g} Hz from the datasheet's 'rate'")
        items.append({"name": sensor, "model": dm.model, "theta": dm.theta, "unit": unit,
                      "notes": notes, "bi": dm.bi, "sheet": sheet})
    return items


def _plan_labels(model: Any, unit: str | None, bi: str | None) -> dict[str, str]:
    """Component -> the name a datasheet gives it (ARW, RRW, ..., BI)."""
    from gmwm.datasheet import unit_system

    us = unit_system(unit)
    names = {"WN": us.white_name, "RW": us.rw_name, "QN": "QN", "DR": "RR"}
    out = {}
    for c in model.components:
        if c.name == bi:
            out[c.name] = f"BI ({c.name})"
        elif c.process.name in names:
            out[c.name] = names[c.process.name]
        else:
            out[c.name] = c.name
    return out


def _fmt_precision(e: dict[str, Any]) -> str:
    rse, ci = e.get("rse"), e.get("ci95")
    if rse is None or not np.isfinite(rse):
        return "-"
    pct = f"{100 * rse:.2g}%" if rse < 0.1 else f"{100 * rse:.0f}%"
    # enough digits that the two ends of a narrow interval differ
    digits = max(3, 2 + int(np.ceil(-np.log10(max(2 * 1.96 * rse, 1e-15)))))
    return pct if not ci else f"{pct} [{ci[0]:.{digits}g}, {ci[1]:.{digits}g}]"


def _plan_text(item: dict[str, Any], plan: Any) -> str:
    from gmwm.plan import IDENTIFIABLE_RSE, format_duration

    model = plan.model
    sheet = item["sheet"]
    what = (f"{item['name']} of the datasheet {sheet.part}" if sheet is not None
            else f"model {model.spec}")
    lines = [f"recording plan for the {what} at {model.freq:g} Hz"
             + (f", signal in {plan.unit}" if plan.unit else "")
             + f": model {model.spec}, default fit ({plan.method.upper()}, {plan.weights} weights)"]
    lines += [f"note: {n}" for n in plan.notes]
    first = plan.predictions[0] if plan.predictions else None
    coefs = [k for k in (first.coefficients if first else {})
             if not (plan.bi and k == f"{plan.bi}.sigma")]
    rows = []
    for c in model.components:
        v = plan.min_length[c.name]
        rows.append((plan.labels.get(c.name, c.name), "> 30 d" if v is None else format_duration(v)))
    lines.append(f"identifiable from (each parameter's 95% Wald interval excludes 0, i.e. relative "
                 f"SE <= {100 * IDENTIFIABLE_RSE:.0f}%):")
    lines.append(format_table(["term", "length"], rows))
    if first is not None:
        lines.append("predicted relative standard error [95% interval] of the fit's coefficients:")
        headers = ["length", "samples", "J"] + [
            f"{k} [{first.coefficients[k]['unit']}]" if first.coefficients[k]["unit"] else k
            for k in coefs]
        trows = [(format_duration(p.seconds), p.n_samples, p.levels,
                  *(_fmt_precision(p.coefficients.get(k, {})) for k in coefs))
                 for p in plan.predictions]
        lines.append(format_table(headers, trows))
        vals = ", ".join(f"{k} = {first.coefficients[k]['value']:.4g}"
                         f"{' ' + first.coefficients[k]['unit'] if first.coefficients[k]['unit'] else ''}"
                         for k in coefs if first.coefficients[k]["value"] is not None)
        lines.append(f"(at the values {vals})")
    for t in plan.targets.values():
        lines.append(f"target {t['name']} to {100 * t['relative_se']:g}% (relative SE): record "
                     + (f"at least {t['duration']}" if t["seconds"] is not None
                        else f"longer than {t['duration'][2:]} (not reached)"))
    return "\n".join(lines)


def cmd_plan(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.plan import DEFAULT_DURATIONS, make_plan, parse_duration, parse_target

    items = _plan_inputs(args)
    durations = [parse_duration(d) for d in (args.duration or DEFAULT_DURATIONS)]
    targets = [parse_target(t) for t in args.target]
    plans = []
    for item in items:
        args.progress(f"planning {item['name'] or item['model'].spec}")
        plans.append(make_plan(item["model"], item["theta"], sorted(durations), unit=item["unit"],
                               targets=targets, bi=item["bi"], notes=item["notes"],
                               labels=_plan_labels(item["model"], item["unit"], item["bi"])))
    if args.plot:
        from gmwm.plan import curve
        from gmwm.plots import channel_grid, plot_plan

        fig, axes = channel_grid(len(plans), ncols=2, panel=(4.6, 3.2))
        for ax, item, plan in zip(axes, items, plans, strict=True):
            secs, rse = curve(plan)
            plot_plan(secs, rse, plan, ax=ax)
            if item["name"]:
                ax.set_title(item["name"])
        _save_plot(fig, args.plot)
    if args.json:
        objs = []
        for item, plan in zip(items, plans, strict=True):
            sheet = item["sheet"]
            objs.append({"command": "plan", **({"datasheet": {
                "part": sheet.part, "source": sheet.source, "file": sheet.path,
                "sensor": item["name"]}} if sheet is not None else {}), **plan.to_dict()})
        if len(objs) == 1:
            _print_json(objs[0], out)
        else:
            _print_json({"command": "plan", "plans": {i["name"]: o for i, o in
                                                      zip(items, objs, strict=True)}}, out)
    else:
        out.write("\n\n".join(_plan_text(i, p) for i, p in zip(items, plans, strict=True)) + "\n")
    return EXIT_OK


# --------------------------------------------------------------------------------------------------
# robust WV option (wv, fit) and the select command (model selection, gmwm.select)
# --------------------------------------------------------------------------------------------------


def _efficiency(text: str) -> float:
    v = _positive_float(text)
    if not 0.05 <= v <= 0.99:
        raise argparse.ArgumentTypeError(f"must be in [0.05, 0.99], got {text!r}")
    return v


def _add_robust(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robust", action="store_true",
                   help="robust WV: Tukey-biweight M-estimate per scale (bounded influence of "
                        "outliers); the CI uses eff x the chi-square edof")
    p.add_argument("--eff", type=_efficiency, default=0.6, metavar="E",
                   help="Gaussian efficiency of the robust WV (lower = more robust)")


def _robust_kw(args: argparse.Namespace) -> dict[str, Any]:
    return {"robust": True, "eff": args.eff} if getattr(args, "robust", False) else {}


def _add_select_parser(sub: Any) -> None:
    p = sub.add_parser(
        "select", formatter_class=_Formatter, help="rank candidate models (model selection)",
        description=(
            "Fit each candidate model by GMWM to the signal's wavelet variance and rank them, best\n"
            "first, by the Wavelet Information Criterion WIC = objective + k x tr(Omega A G V), the\n"
            "objective plus k times the optimism of the fit (its effective number of parameters).\n"
            "k = log T (default, wic-log): consistent choice of the generating model; k = 2 (wic):\n"
            "an estimate of how well the fitted model predicts the WV of a new signal.\n"
            "--auto adds, for each MODEL given, the models with one or two of its components\n"
            "removed and with one component added (WN, QN, RW, DR, up to 3 AR1/GM, up to 2 SIN)."
        ),
        epilog=(
            "examples:\n"
            "  gmwm select imu.csv 'WN+RW' 'WN+AR1' 'WN+AR1+RW' --column gyro_z --freq 200\n"
            "  gmwm select imu.csv 'WN+AR1+RW' --auto --columns gx,gy,gz --json\n\n"
            + _EXIT_STATUS_HELP
        ),
    )
    _add_input(p)
    p.add_argument("models", metavar="MODEL", nargs="+",
                   help="candidate model strings (with --auto: base models)")
    p.add_argument("--auto", action="store_true",
                   help="build the candidate set from the MODEL(s) as base (see above)")
    p.add_argument("--criterion", choices=("wic-log", "wic"), default="wic-log",
                   help="wic-log: penalty factor log T (consistent choice of the generating "
                        "model); wic: factor 2 (WV prediction error, admits spurious components "
                        "more often)")
    p.add_argument("--freq", type=_positive_float, default=None,
                   help="sampling frequency in Hz (default: from the file, else 1)")
    p.add_argument("--levels", "-J", type=_positive_int, default=None, metavar="J",
                   help=_DEFAULT_LEVELS)
    p.add_argument("--weights", choices=("ci", "gaussian", "identity"), default="ci",
                   help="GMWM weight matrix of every fit")
    p.add_argument("--n-starts", type=_positive_int, default=None, metavar="K",
                   help="optimizer starts per fit (default: the library's)")
    p.add_argument("--seed", type=int, default=0, help="seed for the random starting values")
    _add_robust(p)
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress lines on stderr (they are shown only on a terminal anyway)")
    p.set_defaults(func=cmd_select)


def cmd_select(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.model import Model
    from gmwm.select import auto_candidates, rank_models

    if args.auto:
        models: list[str] = []
        for base in args.models:
            models += [m for m in auto_candidates(base) if m not in models]
    else:
        models = []
        for m in args.models:  # model errors before reading the file
            spec = Model(m).spec
            models += [] if spec in models else [spec]
    src = _open_stream(args)
    if src is not None:  # ranking needs the WV only (the drift sign does not enter it)
        signals: dict[str, Any] = {k: v.wv for k, v in _stream_wvs(args, src).items()}
    else:
        signals = _read_input(args)
    options = {} if args.n_starts is None else {"n_starts": args.n_starts}
    rankings: dict[str, tuple[Any, float]] = {}
    for col, x in signals.items():
        _check_levels(x.n_samples if src is not None else x.size, args.levels)
        where = "" if args.columns is None else f" [{col}]"

        def progress(i: int, n: int, spec: str, where: str = where) -> None:
            args.progress(f"select{where}: fitting candidate {i}/{n}: {spec}")

        t0 = time.perf_counter()
        r = rank_models(x, models, criterion=args.criterion, levels=args.levels,
                        freq=args.freq_hz, weights=args.weights, seed=args.seed,
                        progress=progress, **_robust_kw(args), **options)
        rankings[col] = (r, time.perf_counter() - t0)

    def skipped(r: Any) -> list[dict[str, Any]]:
        return [{"model": e.model, "error": e.error} for e in r.skipped]

    if args.json:
        obj: dict[str, Any] = {"command": "select", "input": args.input,
                               "criterion": args.criterion, "robust": bool(args.robust),
                               "candidates": models}
        if args.columns is None:
            r, sec = next(iter(rankings.values()))
            obj.update(ranking=[e.to_json_dict() for e in r.ranked], penalty_factor=r.factor,
                       skipped=skipped(r), seconds=sec)
        else:
            obj["rankings"] = {c: [e.to_json_dict() for e in r.ranked]
                               for c, (r, _) in rankings.items()}
            obj["skipped"] = {c: skipped(r) for c, (r, _) in rankings.items()}
            obj["seconds"] = {c: sec for c, (_, sec) in rankings.items()}
        _print_json(obj, out)
    else:
        for col, (r, sec) in rankings.items():
            what = args.input if args.columns is None else f"{args.input} column {col}"
            out.write(f"model ranking for {what}: T = {r.wv.n_samples}, J = {r.wv.n_levels}, "
                      f"{args.criterion.upper()} = objective + {r.factor:.3g} x penalty"
                      f"{', robust WV' if args.robust else ''}; {len(models)} candidates, "
                      f"{sec:.2f} s\n")
            rows = [(i, e.model, e.criterion, e.objective, e.penalty, e.n_params,
                     "yes" if e.converged else "NO") for i, e in enumerate(r.ranked, 1)]
            out.write(format_table(["rank", "model", "criterion", "objective", "penalty",
                                    "n_params", "converged"], rows) + "\n")
            out.writelines(f"skipped {e.model}: {e.error}\n" for e in r.skipped)
    for col, (r, _) in rankings.items():
        if not r.best.converged:
            where = "" if args.columns is None else f" (column {col})"
            err.write(f"gmwm: warning: the best model {r.best.model}{where} did not converge; "
                      "treat the ranking with care\n")
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


def _negative_count(argv: Sequence[str]) -> str | None:
    """A model typed with a negative count, e.g. '-1*WN' (argparse would call it an option)."""
    return next((a for a in argv if _NEGATIVE_COUNT.match(a)), None)


def _python_warnings(caught: Sequence[warnings.WarningMessage], err: TextIO, debug: bool) -> None:
    """Turn Python warnings raised while a command ran into ``gmwm: warning:`` lines.

    Numerical RuntimeWarnings (overflow in a trial step, ...) are transients of the search whose
    consequences the fit's own diagnostics report; deprecation notices concern us, not the user.
    Both are shown only with ``--debug``.
    """
    seen: set[str] = set()
    for w in caught:
        text = (str(w.message).strip().splitlines() or [w.category.__name__])[0]
        quiet = issubclass(w.category, RuntimeWarning | DeprecationWarning | PendingDeprecationWarning
                           | FutureWarning) or w.category.__module__.startswith("numba")
        if debug:
            line = f"gmwm: debug: {w.category.__name__} at {Path(w.filename).name}:{w.lineno}: {text}"
        elif quiet:
            continue
        else:
            line = f"gmwm: warning: {text}"
        if line not in seen:
            seen.add(line)
            err.write(line + "\n")


def cmd_svo(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Virtual gyroscope: coefficients with CIs, the virtual WV table (-o), a WV figure (--plot)."""
    from gmwm.virtual import equal, plot_virtual_wv, rdvg, read_weights, svo

    if args.output and Path(args.output).suffix.lower() != ".csv":
        raise UsageError(f"--output {args.output}: the table is written as CSV, use a .csv name")
    args.column = None
    signals = _read_input(args)
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
            raise InputError(f"--weights {weights}: not 'short', 'long', 'equal' nor an existing file")
        weights = read_weights(weights)
    t0 = time.perf_counter()
    args.progress(f"SVO ({args.method}) on {X.shape[1]} signals of {X.shape[0]} samples")
    common = {"levels": args.levels, "alpha": args.alpha, "freq": args.freq_hz, "names": names}
    if args.method == "svo":
        res = svo(X, weights, n_boot=args.n_boot, block_const=args.block_const,
                  seed=args.seed, mbb=args.mbb, **common)
    else:
        res = (rdvg if args.method == "rdvg" else equal)(X, **common)
    seconds = time.perf_counter() - t0
    wv = res.wv()
    headers = ["level", "scale", "scale_s", "variance", "ci_low", "ci_high", "n"]
    _write_csv(args, headers, _wv_table_rows(wv))
    if args.plot:
        _save_plot(plot_virtual_wv(res), args.plot)
    if args.json:
        _print_json({"command": "svo", "input": args.input, **res.to_dict(),
                     "conf_int": res.conf_int().tolist() if res.cov is not None else None,
                     "virtual_wv": _wv_dict(wv), "seconds": seconds}, out)
        return EXIT_OK
    out.write(f"{res.summary()}\n")
    out.write(f"({args.input}, freq = {wv.freq:g} Hz, {seconds:.2f} s)\n")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gmwm`` command line; return the exit status (see the module docstring)."""
    out, err = sys.stdout, sys.stderr
    argv = list(sys.argv[1:] if argv is None else argv)
    bad = _negative_count(argv)
    if bad is not None:
        err.write(f"gmwm: error: model '{bad}': the number of components must be a positive "
                  "integer, e.g. '2*AR1'\n")
        return EXIT_ERROR
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    args.err = err
    args.progress = _Progress(err, getattr(args, "quiet", False))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return _run(args, out, err)
        finally:
            _python_warnings(caught, err, args.debug)


def _announce_compiles(args: argparse.Namespace, err: TextIO) -> None:
    """A note on stderr if this command has to compile kernels (no valid cache: they are
    normally compiled at install time, see gmwm._precompile); does not import Numba."""
    from gmwm._precompile import announce_compiles

    announce_compiles(err)


def _run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    try:
        _check_args(args)
        _announce_compiles(args, err)
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
