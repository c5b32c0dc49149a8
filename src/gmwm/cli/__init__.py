"""The ``gmwm`` command line tool: simulate, wv, av, fit, model-wv, report, select, svo, plan.

Exit status: 0 success; 1 a problem with the input, model or files (one line
``gmwm: error: ...`` on stderr, never a traceback); 2 a usage error (bad options, malformed
``--param``); 3 ``gmwm fit`` or ``gmwm report`` ran but the optimizer did not report convergence
(the estimate is still printed, with a warning on stderr); 4 ``gmwm report`` over several topics
calibrated some of them but not all (each failed topic named with its one-line reason on stderr
and in the report); 130 interrupted.

Every fit's diagnostics (boundary estimates, weak identification, ...) are printed as one
``gmwm: warning: ...`` line each on stderr and listed under ``"warnings"`` in ``--json``; Python and
NumPy warning text never reaches the user (numerical transients are dropped, anything else becomes
one ``gmwm: warning:`` line; ``--debug`` shows them all).

A thin layer over the library. Layout: :mod:`gmwm.cli.parser` (options, help, checks before any
computation), one module per command in :mod:`gmwm.cli.commands` (``run(args, out, err)``),
:mod:`gmwm.cli.inputs` (a file and the input options to data: reading, frequency, stationarity,
gaps, streaming; a recording to calibrate is read by :func:`gmwm.calibrate.calibrate`), :mod:`gmwm.formatting` (text, tables and JSON; shared with :mod:`gmwm.report`).
Start-up: this module and the parser import only the standard library and the error classes;
:func:`main` imports the one command it runs, so ``gmwm --help`` loads neither NumPy nor SciPy,
Numba or matplotlib.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from gmwm.cli.errors import as_flags
from gmwm.cli.parser import (
    EXIT_ERROR,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    UsageError,
    build_parser,
    check_args,
    negative_count,
)
from gmwm.errors import GMWMError

__all__ = ["Progress", "build_parser", "main"]


class Progress:
    """Per-stage lines on stderr (``gmwm: [  1.2 s] fitting ...``) when stderr is a terminal and
    ``--quiet`` is not given; a no-op otherwise. :func:`main` sets one as ``args.progress``."""

    def __init__(self, err: TextIO, quiet: bool) -> None:
        self.err = err
        self.on = not quiet and _isatty(err)
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        if self.on:
            self.err.write(f"gmwm: [{time.perf_counter() - self.t0:6.1f} s] {message}\n")
            self.err.flush()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gmwm`` command line; return the exit status (see the module docstring)."""
    out, err = sys.stdout, sys.stderr
    argv = list(sys.argv[1:] if argv is None else argv)
    bad = negative_count(argv)
    if bad is not None:
        err.write(f"gmwm: error: model '{bad}': the number of components must be a positive "
                  "integer, e.g. '2*AR1'\n")
        return EXIT_ERROR
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    args.progress = Progress(err, getattr(args, "quiet", False))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return _run(args, out, err)
        finally:
            python_warnings(caught, err, args.debug)


def console_main() -> None:
    """The ``gmwm`` command (and ``python -m gmwm``): :func:`main`, then exit at once. The exit
    handlers run (temporary files, multiprocessing) and the streams are flushed, but the
    interpreter is not torn down module by module: with SciPy, pandas and matplotlib loaded
    that teardown takes ~0.5 s after the work is done and changes nothing on disk."""
    import atexit
    import contextlib

    code = main()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # a closed pipe: nothing left to say
            stream.flush()
    os._exit(code)


def _run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    try:
        check_args(args)
        # a note on stderr if this command has to compile kernels (no valid cache: they are
        # normally compiled at install time, see gmwm._precompile); does not import Numba
        from gmwm._precompile import announce_compiles

        announce_compiles(err)
        command = importlib.import_module(f"gmwm.cli.commands.{args.command.replace('-', '_')}")
        return command.run(args, out, err)
    except UsageError as exc:
        err.write(f"gmwm: error: {as_flags(one_line(exc))} (see 'gmwm {args.command} --help')\n")
        return EXIT_USAGE
    except GMWMError as exc:
        err.write(f"gmwm: error: {as_flags(one_line(exc))}\n")
        return EXIT_ERROR
    except OSError as exc:
        if isinstance(exc, BrokenPipeError):  # e.g. 'gmwm wv x.npy | head': not an error
            _silence_stdout()
            return EXIT_OK
        err.write(f"gmwm: error: {one_line(exc)}\n")
        return EXIT_ERROR
    except KeyboardInterrupt:
        err.write("gmwm: error: interrupted\n")
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: still one line, unless --debug
        if args.debug:
            raise
        err.write(f"gmwm: error: internal error ({type(exc).__name__}: {one_line(exc)}); "
                  "rerun with --debug for the traceback and please report it\n")
        return EXIT_ERROR


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (an OSError: its reason and file name)."""
    text = str(exc).strip()
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.strerror or text}: {exc.filename}"
    return text.splitlines()[0] if text else type(exc).__name__


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no real file descriptor (e.g. captured)
        pass


def python_warnings(caught: Sequence[warnings.WarningMessage], err: TextIO, debug: bool) -> None:
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
