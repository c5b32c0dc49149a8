"""The ``gmwm`` argument parser: the subcommands, their options and help, the argument types, the
option groups several commands share (input, units, fit, robust and export options), and the
checks of option values made before any computation.

Light by design: it imports only the standard library and :mod:`gmwm.errors`, so ``gmwm --help``
and usage errors load neither NumPy nor any command. A parsed ``args.command`` names the module of
:mod:`gmwm.cli.commands` that runs it.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from gmwm import __version__
from gmwm.errors import InputError

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NOT_CONVERGED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: ``gmwm report`` over several topics: some were calibrated, some could not be (their reasons
#: are on stderr and in the report)
EXIT_SOME_FAILED = 4
#: ``gmwm report``: the report is written but no configuration file (the recording moved beyond
#: the share that may be excluded, too few samples, an ambiguous rate): the last line says why
EXIT_NO_CONFIGURATION = 5

_EXIT_STATUS_HELP = """exit status:
  0  success
  1  bad input, model or file (one line 'gmwm: error: ...' on stderr)
  2  usage error (unknown option, malformed --param, ...)
  3  (fit, report) the optimizer did not converge: the estimate is printed with a warning
  4  (report, several topics) some topics could not be calibrated: the others are, and
     the report lists each failed topic with its one-line reason
  5  (report) the report is written but no configuration file: the recording moved
     beyond --motion-share (the last line names its longest static segment), it is too
     short, or its rate is ambiguous; the last line 'gmwm: verdict: ...' says which"""

_PARAM = re.compile(r"^\s*([A-Za-z][A-Za-z0-9]*\[\d+\]\.[A-Za-z][A-Za-z0-9_]*)\s*=\s*(\S+)\s*$")
#: a model typed with a negative count ('-1*WN') that argparse would take for an option
_NEGATIVE_COUNT = re.compile(r"^-\d+(\.\d*)?\s*\*\s*[A-Za-z]")
#: levels beyond this give scales 2^J that overflow the model formulas (and no signal has them)
MAX_MODEL_LEVELS = 60
#: .npy / HDF5 inputs of at least this many bytes are streamed (gmwm.stream); raw binary always
STREAM_MIN_BYTES = 64 << 20


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
# argument types and option groups
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
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"--param {text!r}: the value must be finite")
    name = m.group(1)
    typ, rest = name.split("[", 1)
    return f"{typ.upper()}[{rest}", value


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v > 0):
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


def _share(text: str) -> float:
    """A share in [0, 1)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0 <= v < 1:
        raise argparse.ArgumentTypeError(f"a share in [0, 1) is needed, got {text}")
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


def _efficiency(text: str) -> float:
    v = _positive_float(text)
    if not 0.05 <= v <= 0.99:
        raise argparse.ArgumentTypeError(f"must be in [0.05, 0.99], got {text!r}")
    return v



def _add_input(p: argparse.ArgumentParser, what: str = "signal") -> None:
    p.add_argument("input", metavar="FILE",
                   help=f"{what}: ROS 1/2 bag (.bag, .db3, .mcap or a bag folder), PX4 ULog, "
                        "ArduPilot DataFlash (.bin, .log), a phone export folder (Gyroscope.csv, "
                        "Accelerometer.csv), CSV/TSV/text (EuRoC, rostopic echo -p, ';' and decimal commas, .gz), "
                        ".npy, .npz, HDF5 (.h5/.hdf5) or raw binary (--dtype); .npy, HDF5 and raw "
                        f"files of {STREAM_MIN_BYTES >> 20} MiB or more are streamed (bounded "
                        "memory, the same numbers)")
    p.add_argument("--column", type=_column, default=None,
                   help="CSV column (header name or 0-based index); needed when the file has several "
                        "data columns (a time column aside)")
    p.add_argument("--columns", type=_columns, default=None, metavar="C1,C2,...|all",
                   help="several columns (names or 0-based indices; HDF5: dataset paths), each "
                        "processed on its own; 'all' = every numeric column except a time column")
    p.add_argument("--dataset", default=None,
                   help="HDF5 dataset path (default: the only 1-D dataset in the file)")
    p.add_argument("--topic", action="append", default=None, metavar="TOPIC",
                   help="bag topic (sensor_msgs/Imu or Vector3Stamped), ULog topic "
                        "(sensor_combined, sensor_gyro:N, sensor_accel:N), DataFlash IMU (IMU[N], "
                        "also IMU2, IMU3) or phone export sensor (Gyroscope, Accelerometer); "
                        "default: the only one. "
                        "gmwm report: repeat it, or 'all', to calibrate several IMUs of one file "
                        "in one run (a section per IMU, a configuration folder per topic)")
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
    p.add_argument("--motion-share", type=_share, default=0.05, metavar="F",
                   help="flagged motion up to this share of the samples used is left out of "
                        "the estimate (padded by 1 s; the files say so); beyond it no "
                        "configuration file is written (exit 5; default 0.05)")
    p.add_argument("--allow-motion", action="store_true",
                   help="write the configuration even if the recording moved beyond "
                        "--motion-share; its first comment lines say that it moved and where")
    p.add_argument("--dtype", default=None, metavar="DTYPE",
                   help="read FILE as raw binary samples of this NumPy dtype (float32, <i2, "
                        ">f8, ...); channels are named 0, 1, ... (the file's name if only one)")
    p.add_argument("--raw-channels", type=_positive_int, default=1, metavar="N",
                   help="raw binary: channels interleaved per sample row")
    p.add_argument("--raw-offset", type=_nonneg_int, default=0, metavar="BYTES",
                   help="raw binary: header bytes to skip")


#: the input options of _add_input, for a command (svo) that reads a recording without them
_INPUT_DEFAULTS = {"column": None, "topic": None, "time_unit": None, "gaps": "auto", "start": None,
                   "end": None, "segment": "all", "strict": False, "motion_share": 0.05,
                   "allow_motion": False, "dtype": None,
                   "raw_channels": 1, "raw_offset": 0, "units": []}


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
_MODEL_HELP = ("model string, e.g. 'WN+RW+AR1+SIN', or 'auto' (chosen per axis by the data: "
               "WN, QN, RW, DR, up to three GM, SIN on a WV bump, ranked by WIC, the best one "
               "the goodness-of-fit test does not reject; docs/METHODS.md §6.1); with --columns "
               "one model for all or COL=MODEL pairs separated by commas "
               "('gx=WN+RW,ax=QN+WN+RW'; a bare model is the default for the other columns)")


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
            "       --units gx,gy,gz=deg/s --units ax,ay,az=m/s^2 -o imu_report\n"
            "  gmwm report imu.bag --topic /imu0 --export kalibr,openvins --inflate noise=2,walk=10 \\\n"
            "       -o imu_report\n\n" + _EXIT_STATUS_HELP
        ),
    )
    _add_input(p)
    p.add_argument("model", metavar="MODEL", nargs="?", default="auto",
                   help=_MODEL_HELP + "; default auto (every gyroscope or accelerometer candidate "
                        "has the WN and RW terms filters need)")
    _add_common(p, _DEFAULT_LEVELS, plot=False)
    _add_units(p, "datasheet coefficients; deg/s or rad/s marks a gyroscope, m/s^2 or g an "
                  "accelerometer")
    _add_fit_options(p)
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="directory for report.md, report.html, imu.yaml and the figures")
    p.add_argument("--title", default=None, help="page title (default: the input file name)")
    _add_datasheet(p)
    _add_export(p)
    _add_select_parser(sub)
    _add_svo_parser(sub)
    _add_plan_parser(sub)
    from gmwm.cli.commands.fleet import register as _register_fleet

    _register_fleet(sub, _Formatter)
    return parser


def _add_svo_parser(sub: Any) -> None:
    """``gmwm svo``: virtual gyroscope from redundant signals of one axis ([SVO])."""
    p = sub.add_parser(
        "svo", formatter_class=_Formatter,
        help="virtual gyroscope from redundant gyros (Scale-wise Variance Optimisation)",
        description="Combine p signals of one axis into S = c'X (sum of c = 1) minimising the\n"
                    "omega-weighted Haar wavelet variance of S (SVO, [SVO]), with moving-block\n"
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
                   help="bootstrap scheme: paper (Algorithm 1 of [SVO]) or time (blocks over "
                        "the whole time axis, no refill stretch)")
    p.add_argument("--seed", type=_nonneg_int, default=0, help="seed of the bootstrap draws")
    p.add_argument("--alpha", type=_alpha, default=0.05, help="CI level is 1 - alpha")
    p.add_argument("-o", "--output", metavar="TABLE.csv", default=None,
                   help="write the virtual signal's WV table as CSV (readable by 'gmwm fit')")
    _add_common(p, _DEFAULT_LEVELS)
    p.set_defaults(**_INPUT_DEFAULTS)


#: gmwm.settings.WEIGHT_KINDS (the parser stays free of NumPy; tests/test_cli.py checks they agree)
_WEIGHTS = ("ci", "ci-eta3", "ci-mixture", "gaussian", "identity", "efficient")


def _add_fit_options(p: argparse.ArgumentParser) -> None:
    # weights, starts and reweighting are passed to the fit only when given: the library's
    # defaults (gmwm.settings.FitSettings) apply otherwise, and with AVSM, which has none of them,
    # giving one is an error rather than silently ignored
    p.add_argument("--weights", choices=_WEIGHTS, default=None,
                   help="weight matrix: inverse squared CI width (ci = ci-eta3: the eta_3 intervals "
                        "of R and the papers; ci-mixture: the default WV intervals), Gaussian "
                        "approximation, identity, efficient (two-step, inverse model covariance "
                        "of the WV) (default: ci)")
    p.add_argument("--method", choices=("gmwm", "armav", "avsm"), default="gmwm",
                   help="gmwm: WV moments; armav: log10 Allan variance; avsm: Allan-variance slopes")
    p.add_argument("--n-samples", type=_positive_int, default=None, metavar="T",
                   help="signal length T, for a WV table without an 'n' column")
    p.add_argument("--n-starts", type=_positive_int, default=None, metavar="K",
                   help="number of optimizer starts (default: the library's)")
    p.add_argument("--seed", type=int, default=0, help="seed for the random starting values")
    p.add_argument("--reweight", type=_nonneg_int, default=None, metavar="K",
                   help="refit K >= 0 times with weights from the fitted model WV (reduces bias) "
                        "(default: 0)")


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def _add_robust(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robust", action="store_true",
                   help="robust WV: Tukey-biweight M-estimate per scale (bounded influence of "
                        "outliers); the CI uses eff x the chi-square edof")
    p.add_argument("--eff", type=_efficiency, default=0.6, metavar="E",
                   help="Gaussian efficiency of the robust WV (lower = more robust)")



def _add_select_parser(sub: Any) -> None:
    p = sub.add_parser(
        "select", formatter_class=_Formatter, help="rank candidate models (model selection)",
        description=(
            "Fit each candidate model by GMWM to the signal's wavelet variance and rank them, best\n"
            "first, by the Wavelet Information Criterion WIC = objective + k x tr(Omega A G V), the\n"
            "objective plus k times the optimism of the fit (its effective number of parameters).\n"
            "k = 2 log log T (default, wic-hq); k = log T (wic-log); k = 2 (wic): an estimate of\n"
            "how well the fitted model predicts the WV of a new signal. Candidates the\n"
            "goodness-of-fit test rejects rank below those it accepts; a first-ranked candidate\n"
            "loses each SIN/GM/AR1 whose removal leaves a candidate the test accepts (printed\n"
            "as 'parsimony:' lines).\n"
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
    # the library's criteria and default (gmwm.criteria), not a second choice made here
    p.add_argument("--criterion", choices=("wic", "wic-hq", "wic-log"), default="wic-hq",
                   help="penalty factor of the ranking: wic-hq 2 log log T (the default, as "
                        "the library's, gmwm.criteria.DEFAULT), wic 2 (the WV prediction "
                        "error; a spurious component more often), wic-log log T (drops "
                        "components below ~3.5 standard errors the test does not see)")
    p.add_argument("--freq", type=_positive_float, default=None,
                   help="sampling frequency in Hz (default: from the file, else 1)")
    p.add_argument("--levels", "-J", type=_positive_int, default=None, metavar="J",
                   help=_DEFAULT_LEVELS)
    p.add_argument("--weights", choices=tuple(w for w in _WEIGHTS if w != "efficient"),
                   default="ci", help="GMWM weight matrix of every fit")
    p.add_argument("--n-starts", type=_positive_int, default=None, metavar="K",
                   help="optimizer starts per fit (default: the library's)")
    p.add_argument("--seed", type=int, default=0, help="seed for the random starting values")
    _add_robust(p)
    p.add_argument("--json", action="store_true", help="print machine-readable JSON on stdout")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress lines on stderr (they are shown only on a terminal anyway)")


_DATASHEET_HELP = ("sensor datasheet: a YAML file of noise terms in datasheet units (see "
                   "docs/METHODS.md §17.1) or a packaged example: adis16448, mti-1, stim300")


def _add_datasheet(p: argparse.ArgumentParser) -> None:
    p.add_argument("--datasheet", metavar="FILE", default=None,
                   help=_DATASHEET_HELP + "; adds a verdict table per axis (within / better / "
                        "worse than the datasheet) and draws the datasheet's WV and Allan "
                        "deviation beside the measured ones (needs --units per axis)")



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


def _add_export(p: argparse.ArgumentParser) -> None:
    p.add_argument("--export", default="kalibr", metavar="TARGETS",
                   help="filter configuration files to write, comma-separated: kalibr (imu.yaml), "
                        "openvins, vins-fusion, orb-slam3, lio-sam, fast-lio, json, or all "
                        "(gmwm.exports.TARGETS)")
    p.add_argument("--inflate", default=None, metavar="SPEC",
                   help="inflate the exported noise densities after the axis rule, e.g. "
                        "'noise=2,walk=10' (factors >= 1 on the densities) or one factor for both")
    p.add_argument("--rostopic", default=None, metavar="TOPIC",
                   help="ROS topic the configuration files name (rostopic, imu_topic); default: "
                        "the bag's topic, else a placeholder /imu0 marked as one (ULog, "
                        "DataFlash, CSV, ...)")


_PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".tif", ".tiff")


def check_args(args: argparse.Namespace) -> None:
    """Checks of option values that argparse cannot do, made before any computation."""
    plot = getattr(args, "plot", None)
    if plot and Path(plot).suffix.lower() not in _PLOT_SUFFIXES:
        raise UsageError(f"--plot {plot}: use a .png, .pdf or .svg file name")
    for opt in ("plot", "output"):
        path = getattr(args, opt, None)
        if path and Path(path).is_dir() and not (args.command in ("report", "fleet")
                                                  and opt == "output"):
            raise InputError(f"--{opt} {path} is a directory: give a file name")
    if args.command == "report" and Path(args.output).exists() and not Path(args.output).is_dir():
        raise InputError(f"--output {args.output} exists and is not a directory")
    topics = getattr(args, "topic", None)
    if getattr(args, "rostopic", None) and topics is not None \
            and (len(topics) > 1 or topics == ["all"]):
        raise UsageError("--rostopic names the topic of one IMU: give it with a single --topic")
    if topics is not None:
        several = len(topics) > 1 or topics == ["all"]
        if several and args.command != "report":
            raise UsageError("several topics (or --topic all) are calibrated by 'gmwm report'; "
                             f"'gmwm {args.command}' reads one")
        if several and ("all" in topics and len(topics) > 1):
            raise UsageError("--topic all already takes every IMU topic: give it alone")
        if several and (getattr(args, "robust", False) or getattr(args, "method", "gmwm") == "avsm"
                        or getattr(args, "dtype", None) is not None):
            raise UsageError("several topics: --robust, --method avsm and --dtype apply to one "
                             "recording")
        args.topics = topics if several else None
        args.topic = None if several else topics[0]
    table = args.output if args.command in ("wv", "av", "svo") else None
    if table and Path(table).suffix.lower() != ".csv":
        raise UsageError(f"--output {table}: the table is written as CSV, use a .csv name")


def negative_count(argv: Sequence[str]) -> str | None:
    """A model typed with a negative count, e.g. '-1*WN' (argparse would call it an option)."""
    return next((a for a in argv if _NEGATIVE_COUNT.match(a)), None)

