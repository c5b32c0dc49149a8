"""The one place the ``gmwm`` commands turn a file and the input options into data.

A recording (any format of :func:`gmwm.readers.read_recording`) gives per channel a signal, or,
when the gap policy pools the clean segments, their wavelet variance; before that, the
stationarity check (:func:`gmwm.stationarity.check_stationarity`) picks the part to use
(``--start/--end``, ``--segment longest-static``) and may refuse it (``--strict``). Raw binary
(``--dtype``) and large .npy / HDF5 files are streamed (:mod:`gmwm.stream`): their channels' WVs
come out of one pass with bounded memory. A WV or AV table gives per channel a
:class:`gmwm.wv.WaveletVariance`. The frequency comes from the file or ``--freq`` (a contradiction
is an error) and a unit without a time base is an error, never 1 Hz. The rules are the library's;
this module calls them and prints their warnings.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from gmwm.cli.parser import STREAM_MIN_BYTES, UsageError
from gmwm.errors import InputError

if TYPE_CHECKING:  # what a command works on is the library's record (gmwm.calibrate.Prepared)
    from gmwm.calibrate import Prepared


def model_theta(spec: str, params: Sequence[tuple[str, float]], freq: float) -> tuple[Any, Any]:
    """The model of ``spec`` and its parameter vector from the ``--param`` pairs."""
    from gmwm.model import Model

    model = Model(spec, freq=freq)
    values: dict[str, float] = {}
    for name, value in params:
        if name in values:
            raise UsageError(f"--param {name} given twice")
        values[name] = value
    if not values and model.n_params:
        raise UsageError(f"give the parameter values with --param, e.g. --param "
                         f"'{model.param_names[0]}=...'; model {model.spec} needs "
                         f"{', '.join(model.param_names)}")
    return model, model.theta(values)


def check_levels(n: int, levels: int | None) -> None:
    """A signal of ``n`` samples and ``--levels``: clear messages before any computation."""
    if n < 4:
        raise InputError(f"signal has {n} samples; at least 4 are needed for one wavelet scale")
    jmax = int(n).bit_length() - 1
    if levels is not None and levels > jmax:
        raise InputError(
            f"signal of {n} samples is too short for --levels {levels} "
            f"(scale 2^{levels} = {2 ** levels} samples needs at least that many; at most "
            f"J = {jmax})")


# -- signals ------------------------------------------------------------------------------------
def read_signals(args: argparse.Namespace, err: TextIO, *, allow_wv: bool = False,
                 require_time: str | None = None) -> Prepared:
    """The requested channels, read whole (:func:`gmwm.calibrate.prepare`: stationarity, part
    used, gaps): signals, or with ``allow_wv`` the pooled WV of the clean segments where the gap
    policy combines them. A channel with a unit, or ``require_time`` (what needs the rate),
    makes a recording without time stamps or ``--freq`` an error, never 1 Hz."""
    from gmwm.calibrate import MOTION_SHARE, prepare
    from gmwm.readers.recording import read_recording

    args.progress(f"reading {args.input}")
    t0 = time.perf_counter()
    if args.dtype is not None:  # raw binary read whole (e.g. for the robust WV)
        return _read_raw(args, require_time, t0)
    policy = args.gaps
    if policy == "combine" and not allow_wv:
        raise UsageError("--gaps combine applies to fit and report (use longest here)")
    rec = read_recording(args.input, topic=args.topic, columns=wanted_columns(args),
                         dataset=args.dataset, freq=args.freq, time_unit=args.time_unit)
    args.progress("checking stationarity")
    prep = prepare(rec, units=getattr(args, "units", None) or None, levels=args.levels,
                   gaps=policy if allow_wv or policy != "auto" else "longest",
                   start_s=getattr(args, "start", None), end_s=getattr(args, "end", None),
                   segment=getattr(args, "segment", "all"),
                   strict=getattr(args, "strict", False), require_time=require_time,
                   where=args.input, motion_share=getattr(args, "motion_share", MOTION_SHARE),
                   allow_motion=getattr(args, "allow_motion", False))
    tell(err, prep.messages)
    return dataclasses.replace(prep, seconds=time.perf_counter() - t0)


def tell(err: TextIO, messages: Sequence[str]) -> None:
    """Library messages (``warning: ...``, ``note: ...``) as ``gmwm: ...`` lines on stderr."""
    err.writelines(f"gmwm: {m}\n" for m in messages)


def _read_raw(args: argparse.Namespace, require_time: str | None, t0: float) -> Prepared:
    from gmwm.calibrate import Prepared

    with raw_source(args) as src:
        rows = src.read(0, src.n_samples)
        signals = {n: np.ascontiguousarray(rows[:, i], dtype=np.float64)
                   for i, n in enumerate(src.names)}
    units = units_by_column(args, list(signals), {})
    freq = resolve_freq(args, None, None, units, require_time)
    for name, x in signals.items():
        bad = ~np.isfinite(x)
        if bad.any():
            raise InputError(f"{args.input} ({name}) contains a non-finite value at sample "
                             f"{int(np.argmax(bad))}; clean or interpolate it first")
    return Prepared(signals, freq, units, seconds=time.perf_counter() - t0)


def wanted_columns(args: argparse.Namespace) -> Any:
    """``--column`` / ``--columns`` as the readers take them (None: the file's only channel)."""
    if args.columns is not None and args.column is not None:
        raise UsageError("give --column (one signal) or --columns (several), not both")
    return args.columns if args.columns is not None else (None if args.column is None
                                                          else [args.column])


def resolve_freq(args: argparse.Namespace, found: float | None, source: str | None,
                 units: Mapping[str, str], require_time: str | None = None) -> float:
    """--freq, else the file's frequency; both given and different (> 1 %) is an error. Without
    either, per-sample scales (1 Hz) only for a plain signal: a unit or ``require_time`` needs a
    time base, so that is an error asking for --freq, never a silent 1 Hz."""
    given, where = args.freq, args.input
    if found is None:
        if given is not None:
            return float(given)
        with_unit = [c for c, u in units.items() if u]
        if require_time or with_unit:
            why = require_time or f"coefficients in {units[with_unit[0]]}"
            raise InputError(f"{where} has no time stamps and no sampling frequency: {why} needs "
                             "one; give --freq HZ")
        return 1.0
    if given is None:
        return float(found)
    if abs(given / found - 1.0) > 0.01:
        raise InputError(f"--freq {given:g} contradicts the sampling frequency {found:g} Hz given "
                         f"by the {source} of {where}; drop --freq or fix the file")
    return float(given)


# -- streaming ----------------------------------------------------------------------------------
def raw_source(args: argparse.Namespace) -> Any:
    """The raw binary file of ``--dtype`` as a :class:`gmwm.stream.RawSource`."""
    from gmwm.stream import RawSource

    if args.dataset is not None:
        raise UsageError("--dataset applies to HDF5 files, not to raw binary (--dtype)")
    return RawSource(args.input, args.dtype, args.raw_channels, args.raw_offset,
                     wanted_columns(args))


def stream_min_bytes() -> int:
    """The size from which .npy / HDF5 inputs are streamed (``GMWM_STREAM_MIN_BYTES`` overrides)."""
    env = os.environ.get("GMWM_STREAM_MIN_BYTES", "").strip()
    if not env:
        return STREAM_MIN_BYTES
    try:
        return max(0, int(float(env)))
    except ValueError:
        raise UsageError(f"GMWM_STREAM_MIN_BYTES must be a number of bytes, got {env!r}") from None


def stream_wvs(args: argparse.Namespace, err: TextIO, require_time: str | None = None
               ) -> Prepared | None:
    """The WV per channel of a streamed input (raw binary; .npy / HDF5 from
    :func:`stream_min_bytes` on, in a layout the stream reads) with ``--levels``/``--alpha``, or
    None when the input is read whole. The robust WV needs the whole signal: never streamed."""
    from gmwm.cli import one_line

    if getattr(args, "robust", False):
        return None
    if args.dtype is not None:
        src = raw_source(args)
    else:
        p = Path(args.input)
        if p.suffix.lower() not in (".npy", ".h5", ".hdf5") or not p.is_file() \
                or p.stat().st_size < stream_min_bytes():
            return None
        from gmwm.stream import open_source

        try:
            src = open_source(p, wanted_columns(args), args.dataset)
        except InputError as exc:  # a layout only the in-memory reader handles (or a bad file:
            # the reader then reports it in its own words)
            err.write(f"gmwm: note: {args.input} is read into memory, not streamed "
                      f"({one_line(exc)})\n")
            return None
    with src:
        units = units_by_column(args, list(src.names), {})
        freq = resolve_freq(args, src.freq, src.freq_source, units, require_time)
        _warn(err, src.notes)
        got, st = _stream_checked(args, src, units, freq, err)
    from gmwm.calibrate import Prepared

    return Prepared({c: v.wv for c, v in got.items()}, freq, units, stationarity=st,
                    streamed=got)


def _stream_checked(args: argparse.Namespace, src: Any, units: Mapping[str, str],
                    freq: float, err: TextIO) -> tuple[dict[str, Any], Any]:
    """The streamed WVs of the part to use and the stationarity report, in bounded memory. The
    whole recording (no --start/--end/--segment/--strict): one read, the check riding along
    with the WV. Otherwise the check reads first (the part must be known before its WV), then
    the WV reads only that part."""
    from gmwm.stationarity import StationarityStream, check_stationarity_stream
    from gmwm.stream import uniform_sample_range, wvar_stream

    n = src.n_samples
    chk_units = {c: (u or None) for c, u in units.items()}
    chk_freq = None if src.freq is None and args.freq is None else freq
    kw = {"levels": args.levels, "alpha": getattr(args, "alpha", 0.05), "freq": freq}
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    whole = start is None and end is None and getattr(args, "segment", "all") == "all"
    if whole and not getattr(args, "strict", False):
        check_levels(n, args.levels)
        args.progress(f"streaming {args.input} ({n} samples x {len(src.names)} channels): WV "
                      "and stationarity check in one read")
        check = StationarityStream.for_source(src, freq=chk_freq, units=chk_units)
        got = wvar_stream(src, observe=check.push, **kw)
        st, _, _ = _choose_part(args, check.finish(), 0, n, err)
        return got, st
    args.progress(f"checking stationarity of {args.input} (streamed)")
    st = check_stationarity_stream(src, freq=chk_freq, units=chk_units)
    if start is None and end is None:
        i0, i1 = 0, n
    else:
        if chk_freq is None:
            raise InputError(f"{args.input} has no sampling rate: --start/--end need --freq (Hz)")
        i0, i1 = uniform_sample_range(n, freq, start, end, args.input)
    st, i0, i1 = _choose_part(args, st, i0, i1, err)
    check_levels(i1 - i0, args.levels)
    args.progress(f"streaming {args.input} (samples {i0}-{i1} of {n})")
    return wvar_stream(src, start=i0, stop=i1, **kw), st


# -- what fit and report fit --------------------------------------------------------------------
def read_fit_data(args: argparse.Namespace, err: TextIO, require_time: str | None = None
                  ) -> Prepared | None:
    """What ``gmwm fit`` and ``gmwm report`` fit when it is not a recording read whole: the
    channels of a WV (or AV) table, cut to ``--levels``; of a streamed input, their WVs; of raw
    binary (``--dtype``) read whole, its signals. None for a recording, which
    :func:`gmwm.calibrate.calibrate` reads."""
    from gmwm.readers.tables import is_wv_table, read_wv_table, table_channels

    p = Path(args.input)
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if args.dtype is not None or not is_wv_table(p):  # --dtype: raw binary, whatever the name
        if args.n_samples is not None:
            raise UsageError("--n-samples applies to a WV table (a CSV with 'scale' and "
                             "'variance' columns)")
        got = stream_wvs(args, err, require_time)  # a WV is all a fit needs
        if got is None and args.dtype is not None:
            got = read_signals(args, err, allow_wv=True, require_time=require_time)
        return got
    if args.start is not None or args.end is not None or args.segment != "all" or args.strict:
        raise UsageError("--start/--end/--segment/--strict apply to recordings, not to a WV table")
    if getattr(args, "robust", False):
        raise UsageError("--robust needs the signal; a WV table is already an estimate")
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
    from gmwm.calibrate import Prepared

    return Prepared(data, next(iter(data.values())).freq, units_by_column(args, list(data), {}))


# -- per-column options -------------------------------------------------------------------------
def units_by_column(args: argparse.Namespace, columns: Sequence[str],
                    file_units: Mapping[str, str | None]) -> dict[str, str]:
    """Per column: the ``--units`` given, else the unit the file defines, else ''
    (:func:`gmwm.calibrate.units_for`)."""
    from gmwm.calibrate import units_for

    return units_for(getattr(args, "units", []) or [], columns, file_units, args.input)


def models_by_column(spec: str, columns: Sequence[str]) -> dict[str, str]:
    """'WN+RW' for every column, or 'gx=WN+RW,ax=QN+WN+RW[,DEFAULT]' pairs
    (:func:`gmwm.calibrate.models_for`)."""
    from gmwm.calibrate import models_for

    return models_for(spec, columns)


# -- stationarity -------------------------------------------------------------------------------
def _choose_part(args: argparse.Namespace, st: Any, i0: int, i1: int, err: TextIO
                 ) -> tuple[Any, int, int]:
    """The part of a checked streamed recording to use (:func:`gmwm.calibrate.choose_part` with
    ``--start/--end``, ``--segment``, ``--strict``), its warnings printed."""
    from gmwm.calibrate import choose_part, part_messages

    st, i0, i1 = choose_part(st, i0, i1, segment=getattr(args, "segment", "all"),
                             strict=getattr(args, "strict", False), where=args.input)
    tell(err, part_messages(st))
    return st, i0, i1


def _warn(err: TextIO, messages: Sequence[str]) -> None:
    err.writelines(f"gmwm: warning: {m}\n" for m in messages)
