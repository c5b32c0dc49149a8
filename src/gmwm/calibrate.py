"""One path from a recording to its calibration: :func:`calibrate` reads the recordings (one
topic or many), checks each one's stationarity, applies the part and the gap policy, fits every
axis (a given model or the automatic choice) and returns a :class:`CalibrationResult`: per topic
the fits, the datasheet coefficients, the warnings and what the report and the configuration
files need (:func:`gmwm.report.write_calibration` writes them). A topic that fails (unreadable,
broken stamps, too short) is kept with its one-line reason while the others are calibrated.

The fits are independent, so they run concurrently, at most one per core this process may use
(``os.sched_getaffinity``): worker processes for the automatic choices (mostly Python, which
threads would serialise), forked warm from a server that loads the fitting stack while this
process reads the input (:func:`start_warm_server`). Each fit is deterministic for a given
``seed``, so the results do not depend on the number of workers or their kind, nor on whether a
topic was calibrated alone or with others.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import GMWMError, InputError

__all__ = ["AUTO", "MIN_STATIC_SAMPLES", "AxisCalibration", "CalibrationResult", "Prepared",
           "TopicCalibration", "UnfittedAxis", "available_cores", "calibrate", "calibrate_imus", "choose_part",
           "executor", "models_for", "part_messages", "preload", "prepare", "start_warm_server",
           "stop_warm_server", "units_for", "warm_server_running"]

#: the model string asking for the automatic choice (:func:`gmwm.automodel.choose_model`)
AUTO = "auto"
#: the shortest static stretch ``segment="longest-static"`` accepts [samples]
MIN_STATIC_SAMPLES = 64
#: largest share of the samples used that flagged motion may take and still be excluded (the
#: estimate then pools the clean parts); beyond it no configuration is written
MOTION_SHARE = 0.05
#: padding of each flagged range on both sides before it is excluded [s] (the tests locate a
#: change to within their window; the shortest windows are ~0.1-1 s)
MOTION_PAD_S = 1.0


def available_cores() -> int:
    """The number of cores this process may run on (its CPU affinity; at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _is_auto(spec: str) -> bool:
    return spec.strip().lower() == AUTO


# -- per-channel settings -------------------------------------------------------------------------
def models_for(spec: str | Mapping[str, str], columns: Sequence[str]) -> dict[str, str]:
    """Channel -> model string: one model for every channel (``"WN+RW"``, ``"auto"``), a mapping,
    or ``"gx=WN+RW,ax=QN+WN+RW[,DEFAULT]"`` pairs (a bare item is the default of the others)."""
    if not isinstance(spec, str):
        missing = [c for c in columns if c not in spec]
        if missing:
            raise InputError(f"no model for column(s) {', '.join(missing)}")
        return {c: spec[c] for c in columns}
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
                         f"used ({', '.join(columns)}); select them with `columns`")
    missing = [c for c in columns if c not in pairs and default is None]
    if missing:
        raise InputError(f"no model for column(s) {', '.join(missing)}: add COL=MODEL pairs or a "
                         "bare default model")
    return {c: pairs.get(c, default) for c in columns}


def units_for(given: str | Sequence[str] | Mapping[str, str | None] | None,
              columns: Sequence[str], file_units: Mapping[str, str | None], where: str = "the file"
              ) -> dict[str, str]:
    """Channel -> signal unit ('' unknown): the unit ``given`` (one unit for every channel, a
    mapping, or ``"UNIT"`` / ``"C1,C2=UNIT"`` items), else the unit the file defines (bags, ULog,
    EuRoC headers). An unknown unit is an error listing the known ones; one contradicting the
    file's is an error naming ``where``."""
    from gmwm.units import parse_unit

    if given is None:
        chosen: dict[str, str | None] = {}
    elif isinstance(given, Mapping):
        chosen = dict(given)
    else:
        chosen = _by_column([given] if isinstance(given, str) else list(given), columns,
                            "`units`")
    out = {}
    for c in columns:
        file_unit = file_units.get(c)
        u = chosen.get(c)
        if u:
            pu = parse_unit(u)
            if file_unit and pu != parse_unit(file_unit):
                raise InputError(f"`units` {u} for {c} contradicts {where}, which says "
                                 f"{file_unit}")
        out[c] = u or file_unit or ""
    return out


def _by_column(items: Sequence[str], columns: Sequence[str], what: str
               ) -> dict[str, str | None]:
    """Per-column values from 'VALUE' (every other column) and 'C1,C2=VALUE' items."""
    explicit: dict[str, str] = {}
    fallback = None
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


# -- the part of a recording used -------------------------------------------------------------------
def choose_part(st: Any, i0: int, i1: int, *, segment: str = "all", strict: bool = False,
                where: str = "the recording") -> tuple[Any, int, int]:
    """The part of a checked recording to use: samples ``[i0, i1)`` (the whole recording, or
    the ``start_s``/``end_s`` range), narrowed by ``segment="longest-static"`` (the longest
    stretch no flagged range touches, at least :data:`MIN_STATIC_SAMPLES`). Returns the
    stationarity report (its ``used`` range set) and the range; ``strict``: a part used that
    moved is a :class:`gmwm.stationarity.NonStationaryError`. Shared by recordings read whole
    and streamed ones."""
    from gmwm.formatting import spans
    from gmwm.stationarity import NonStationaryError

    def flagged(s: Any) -> str:  # the flagged ranges in the part used (all when none is)
        a, b = s.used or (0, s.n)
        return spans(s, s.segments_in(a, b) or list(s.segments))

    how = "the whole recording" if (i0, i1) == (0, st.n) else "the asked start/end range"
    if segment == "longest-static":
        a, b = st.clean_segment(i0, i1)
        if b <= a:
            raise NonStationaryError(f"`segment` longest-static: every part of {where} "
                                     f"is flagged as moving ({flagged(st)})")
        if b - a < MIN_STATIC_SAMPLES:
            raise NonStationaryError(f"`segment` longest-static: the longest static stretch of "
                                     f"{where} has only {b - a} samples")
        i0, i1 = a, b
        how = "longest static segment" + ("" if how.startswith("the whole") else
                                          " within the asked start/end range")
    elif segment != "all":
        raise InputError(f"unknown segment choice {segment!r}; use all or longest-static")
    st = st.using(i0, i1, how)
    if strict and st.moving_in_used:
        raise NonStationaryError(f"{where} is not static in the part used ({flagged(st)}) "
                                 "and `strict` is set: calibrate a static part with `segment` "
                                 "longest-static or `start_s`/`end_s`")
    return st, i0, i1


def part_messages(st: Any) -> list[str]:
    """What a user is told about the part used: the stationarity warnings (``"warning: ..."``)
    and, for a part of a static recording, which part (``"note: ..."``)."""
    out = [f"warning: {w}" for w in st.warnings()]
    if st.used not in (None, (0, st.n)) and not st.segments:
        out.append(f"note: the estimate uses {st.used_text()}")
    return out


@dataclass(frozen=True)
class Prepared:
    """One topic ready to fit. ``data``: channel -> 1-D signal or :class:`gmwm.wv.WaveletVariance`
    (a table, a streamed channel, a recording's pooled clean segments); ``freq`` [Hz] (1 for a
    signal without time stamps or unit); ``units`` channel -> unit ('' unknown); ``recording``
    (the part used), ``stationarity`` (its ``used`` range set) and ``gaps`` (the gap decision)
    for a recording read whole; ``streamed`` channel -> :class:`gmwm.stream.ChannelWV` for a
    streamed input; ``timing``: report lines on the time base; ``messages``: what the user was
    told, in order (``"warning: ..."``, ``"note: ..."``)."""

    data: dict[str, Any]
    freq: float
    units: dict[str, str]
    recording: Any = None
    stationarity: Any = None
    gaps: Any = None
    streamed: dict[str, Any] = field(default_factory=dict)
    timing: tuple[str, ...] | None = None
    messages: tuple[str, ...] = ()
    topic: str | None = None
    #: why no configuration may be written (gmwm.verdict: motion beyond the excluded share, an
    #: ambiguous rate), and what the configuration files must say (motion excluded or allowed)
    refusals: tuple[str, ...] = ()
    caveats: tuple[str, ...] = ()
    #: samples the estimate uses (after gaps and excluded motion); None: not known (a table)
    n_used: int | None = None
    #: seconds the command spent reading it (the CLI's ``--json``)
    seconds: float = 0.0
    #: whether ``refusals`` holds the motion refusal (it moved beyond the share that may be
    #: excluded, without ``allow_motion``): :func:`calibrate` may then skip the fits
    motion_refused: bool = False

    @property
    def rostopic(self) -> str | None:
        """The ROS topic a filter subscribes to, for a bag recording (a ULog stream has none)."""
        rec = self.recording
        return rec.topic if rec is not None and rec.topic and rec.format.startswith("ros") \
            else None

    @property
    def label(self) -> str:
        rec = self.recording
        return "" if rec is None else f"{rec.format}, {rec.n} samples"


def _motion(st: Any, i0: int, i1: int, freq: float | None, share_max: float,
            allow: bool, cut: bool = True) -> tuple[list[tuple[int, int]], list[str], list[str]]:
    """The flagged ranges of ``[i0, i1)`` to exclude (padded by :data:`MOTION_PAD_S`, merged;
    relative to ``i0``), the refusals and the caveats of the motion policy (docs/recordings.md):
    a share up to ``share_max`` is excluded; beyond it the configuration is refused, naming the
    longest static segment, unless ``allow`` (then the caveat says the values describe motion).
    ``cut=False``: an input that cannot be cut (a streamed file): the same share rule, and within
    it a caveat that the motion is included."""
    from gmwm.formatting import spans

    segs = st.segments_in(i0, i1)
    if not segs:
        return [], [], []
    pad = round(MOTION_PAD_S * freq) if freq else 0
    ranges: list[tuple[int, int]] = []
    for seg in sorted(segs, key=lambda s: s.i0):
        a, b = max(i0, seg.i0 - pad), min(i1, seg.i1 + pad)
        if ranges and a <= ranges[-1][1]:
            ranges[-1] = (ranges[-1][0], max(ranges[-1][1], b))
        else:
            ranges.append((a, b))
    n = max(i1 - i0, 1)
    share = sum(b - a for a, b in ranges) / n
    where = spans(st, segs)
    padded = f", padded by {MOTION_PAD_S:g} s" if pad else ""  # the share counts the padding
    if allow:
        return [], [], [(f"the recording MOVED: {100 * share:.3g} % of the samples used are "
                        f"flagged as motion ({where}{padded}); written anyway (allow_motion): these "
                        "values describe the motion, not the sensor at rest")]
    if share > share_max:
        from gmwm.verdict import MIN_SAMPLES

        a, b = st.clean_segment(i0, i1)
        longest = ("no static stretch" if b <= a else
                   f"the longest static segment is {st.span(st.time_at(a), st.time_at(b))} "
                   f"({(st.time_at(b) - st.time_at(a)):.4g}{' s' if st.freq else ' samples'}, {b - a} "
                   "samples)" + (": calibrate it with `segment` longest-static"
                                 if b - a >= MIN_SAMPLES else
                                 f", too short for a configuration (fewer than {MIN_SAMPLES} "
                                 "samples): record the sensor at rest"))
        return [], [(f"the recording moved: {100 * share:.3g} % of the samples used are flagged "
                    f"as motion ({where}{padded}), more than the {100 * share_max:g} % that may "
                    f"be excluded; {longest} (or give `allow_motion`)")], []
    if not cut:
        return [], [], [(f"motion NOT excluded: {100 * share:.3g} % of the samples used "
                         f"({where}{padded}) are flagged as moving, but a streamed input is not "
                         "cut, so the values include that motion; read the file whole "
                         "(GMWM_STREAM_MIN_BYTES) or give `start_s`/`end_s`")]
    excluded = [(a - i0, b - i0) for a, b in ranges]
    return excluded, [], [(f"motion excluded: {100 * share:.3g} % of the samples used "
                          f"({where}{padded}) are flagged as moving and left out; the estimate "
                          "pools the clean parts")]


#: largest |mean| of a static gyroscope axis that a real bias explains [rad/s] (20 deg/s: MEMS
#: biases are up to a few deg/s); beyond it the unit is suspect (deg/s read as rad/s: x 57.3)
MAX_STATIC_GYRO_MEAN = 0.35


def _unit_caveats(rec: Any, units: Mapping[str, str]) -> list[str]:
    """Unit mix-ups a static recording shows: a gyroscope axis whose mean is beyond any bias
    (:data:`MAX_STATIC_GYRO_MEAN`), named with the likely cause."""
    from gmwm.units import unit_system

    out = []
    for c, u in units.items():
        us = unit_system(u or None)
        if us.sensor != "gyroscope" or not us.si or c not in rec.channels:
            continue
        x = np.asarray(rec.channels[c], float)
        m = float(np.nanmean(x)) * us.si if x.size else 0.0
        if abs(m) > MAX_STATIC_GYRO_MEAN:
            out.append(f"{c}: the static gyroscope reads {m:.3g} rad/s on average "
                       f"({np.degrees(m):.3g} deg/s), beyond any bias (> "
                       f"{MAX_STATIC_GYRO_MEAN:g} rad/s): check its unit (`units`); deg/s read as "
                       "rad/s would make every coefficient 57.3x too large")
    return out


def _streamed_motion(p: Prepared, share_max: float, allow: bool) -> Prepared:
    """The motion policy of :func:`prepare` for an input prepared elsewhere (a streamed file,
    whose WV was computed in one pass and cannot be cut afterwards): beyond ``share_max`` a
    refusal (or, with ``allow``, the moved caveat); within it a caveat that the flagged motion
    is *included* (a streamed input is not cut)."""
    st = p.stationarity
    if st is None or not getattr(st, "tested", False) or p.refusals or p.caveats:
        return p
    a, b = st.used or (0, st.n)
    _, refusals, caveats = _motion(st, a, b, st.freq, share_max, allow, cut=False)
    return dataclasses.replace(p, refusals=tuple(refusals), caveats=tuple(caveats),
                               motion_refused=bool(refusals),
                               messages=(*p.messages, *(f"note: {c}" for c in caveats)))


def _without(decision: Any, excluded: Sequence[tuple[int, int]], min_len: int = 4) -> Any:
    """The gap decision ``decision`` with the ``excluded`` sample ranges also left out: its
    segments cut around them and pooled (policy 'combine')."""
    from gmwm.readers.timebase import GapDecision

    if not excluded:
        return decision
    out: list[tuple[int, int]] = []
    for a, b in decision.segments:
        start = a
        for ea, eb in excluded:
            if eb <= start or ea >= b:
                continue
            if ea - start >= min_len:
                out.append((start, ea))
            start = max(start, eb)
        if b - start >= min_len:
            out.append((start, b))
    if not out:
        raise InputError("nothing is left once the flagged motion is excluded")
    used = sum(b - a for a, b in out)
    return GapDecision("combine", tuple(out), used, decision.n, decision.message)


def prepare(rec: Any, *, units: str | Sequence[str] | Mapping[str, str | None] | None = None,
            levels: int | None = None, gaps: str = "auto", start_s: float | None = None,
            end_s: float | None = None, segment: str = "all", strict: bool = False,
            require_time: str | None = None, where: str | None = None,
            motion_share: float = MOTION_SHARE, allow_motion: bool = False) -> Prepared:
    """The stationarity check, the part used and the fit inputs of one recording
    (:class:`gmwm.readers.Recording`).

    ``units``: as :func:`units_for` (replacing or completing the recording's); ``levels``: number
    of WV scales (None: all); ``gaps``: the gap policy
    (:meth:`gmwm.readers.recording.Recording.gaps`); ``start_s``/``end_s``: the part to use,
    seconds since the first sample; ``segment``, ``strict``: as :func:`choose_part`;
    ``require_time``: what needs the rate (a recording without stamps or rate is then an error;
    so it is when a channel has a unit, never 1 Hz); ``where``: the input's name in messages.
    ``motion_share``, ``allow_motion``: the motion policy (:func:`_motion`): flagged ranges up to
    that share of the part used are excluded like gaps; beyond it the :class:`Prepared` carries a
    refusal (no configuration file), unless ``allow_motion``."""
    from gmwm.readers.recording import sample_range, select_samples
    from gmwm.readers.timebase import signal_for_wv
    from gmwm.stationarity import check_stationarity

    where = where or (rec.path + (f" topic {rec.topic}" if rec.topic else ""))
    u = units_for(units, list(rec.channels), rec.units, where)
    if rec.time is None:
        with_unit = [c for c, v in u.items() if v]
        if require_time or with_unit:
            rec.require_time(require_time or f"coefficients in {u[with_unit[0]]}")
        freq = 1.0  # per-sample scales of a signal without a unit
    else:
        freq = rec.time.freq
    messages = [f"warning: {n}" for n in rec.notes]
    st = check_stationarity(rec, units={c: (v or None) for c, v in u.items()})
    i0, i1 = (0, rec.n) if start_s is None and end_s is None else \
        sample_range(rec, start_s, end_s)
    st, i0, i1 = choose_part(st, i0, i1, segment=segment, strict=strict, where=where)
    if not 0 <= motion_share < 1:
        raise InputError(f"`motion_share` must lie in [0, 1), got {motion_share}")
    excluded, refusals, caveats = _motion(st, i0, i1, freq if rec.time is not None else None,
                                          motion_share, allow_motion)
    moved = bool(refusals)
    if excluded:
        st = dataclasses.replace(st, excluded=True)
    messages += part_messages(st)
    used = rec if (i0, i1) == (0, rec.n) else select_samples(rec, i0, i1)
    decision = used.gaps(gaps)
    if decision.message:
        messages.append(f"warning: {decision.message}")
    decision = _without(decision, excluded)
    units_bad = _unit_caveats(used, u)
    messages += [f"note: {c}" for c in caveats] + [f"warning: {c}" for c in units_bad]
    caveats += units_bad
    if units_bad and refusals:  # a wrong unit looks like motion to the check: say it first
        refusals[0] = f"likely a unit mix-up, not motion ({units_bad[0]}); {refusals[0]}"
    ambiguous = getattr(used, "rate_ambiguity", None)  # None once `freq` settled it
    if ambiguous and gaps == "auto":
        refusals.append(f"{ambiguous}: no configuration's `update_rate` can be trusted; give "
                        "`freq` with the rate to assume, or a `gaps` policy")
    timing = None
    if used.time is not None:
        timing = [f"Recording ({used.format}{', topic ' + used.topic if used.topic else ''}): "
                  + used.time.summary()]
        timing += [n for n in used.notes if n not in timing]  # the reader's caveats
        if decision.message:
            timing.append(decision.message)
    data = {c: signal_for_wv(x, decision, levels, freq) for c, x in used.channels.items()}
    return Prepared(data, freq, u, used, st, decision, timing=None if timing is None
                    else tuple(timing), messages=tuple(messages), topic=rec.topic,
                    refusals=tuple(refusals), caveats=tuple(caveats), n_used=decision.used,
                    motion_refused=moved)


# -- results --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AxisCalibration:
    """One axis's calibration: the fit ``result`` (:class:`gmwm.results.FitResult`), the signal
    ``units`` ('' unknown), its ``datasheet`` coefficients (:func:`gmwm.datasheet.datasheet`),
    ``warnings`` (the fit's, less the non-convergence one, and where the part used moved in this
    axis), the automatic ``choice`` (:class:`gmwm.automodel.Choice`, None for a given model),
    the IEEE 952 ``readings`` (when computed beside the fit), the sensor-datasheet ``verdict``
    (:func:`gmwm.sensor_datasheet.judge`) and the identifiability ``check``, when asked for;
    ``figures``: the report figure files its worker drew (:func:`calibrate`'s ``draw``)."""

    result: Any
    units: str
    datasheet: dict[str, Any]
    warnings: tuple[str, ...] = ()
    choice: Any = None
    readings: dict[str, Any] | None = None
    verdict: dict[str, Any] | None = None
    check: Any = None
    figures: tuple[Any, ...] = ()  # report figure files drawn beside the fit (``draw``)

    def __getitem__(self, key: str) -> Any:  # the report's axis mapping (axes[name]["result"])
        return getattr(self, key)

    def get(self, key: str, default: Any = None) -> Any:
        return getattr(self, key, default)

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)


@dataclass(frozen=True)
class UnfittedAxis:
    """An axis of a topic refused for motion and not fitted (:func:`calibrate`'s
    ``fit_refused=False``): its wavelet variance ``wv`` (of the part used, as the fit would have
    used it) and its signal ``units`` ('' unknown)."""

    wv: Any
    units: str

    def __getitem__(self, key: str) -> Any:  # the report's axis mapping, as AxisCalibration's
        return getattr(self, key)


@dataclass(frozen=True)
class TopicCalibration:
    """One topic (IMU stream) of a calibration. ``status``: ``"calibrated"`` or ``"failed"``
    (then ``reason`` is the one-line cause and ``axes`` is empty); ``axes`` channel ->
    :class:`AxisCalibration`; ``timing`` report lines on the time base; ``stationarity`` (its
    ``used`` range set); ``gaps`` the gap decision; ``rostopic`` the ROS topic its configuration
    files name (None: not a ROS topic, e.g. a ULog stream or a CSV; the files hold a
    placeholder); ``label`` the recording's format and length; ``messages`` what the user was
    told while it was prepared (``"warning: ..."``, ``"note: ..."``); ``freq`` [Hz]."""

    topic: str
    status: str
    axes: dict[str, AxisCalibration] = field(default_factory=dict)
    reason: str | None = None
    freq: float | None = None
    timing: tuple[str, ...] | None = None
    stationarity: Any = None
    gaps: Any = None
    rostopic: str | None = None
    label: str = ""
    messages: tuple[str, ...] = ()
    error: BaseException | None = field(default=None, repr=False, compare=False)
    #: what happens to the configuration files (:class:`gmwm.verdict.Verdict`)
    verdict: Any = None
    #: a topic whose configuration was refused for motion before any fit (:func:`calibrate`'s
    #: ``fit_refused=False``): channel -> its :class:`UnfittedAxis` (``axes`` is then empty)
    #: and the one-line reason it was not fitted
    unfitted: dict[str, UnfittedAxis] = field(default_factory=dict)
    not_fitted: str | None = None

    @property
    def ok(self) -> bool:
        return self.status == "calibrated"

    @property
    def caveats(self) -> list[str]:
        """Every warning of this topic: its preparation's, then each axis's (``axis: ...``)."""
        out = [m.removeprefix("warning: ") for m in self.messages if m.startswith("warning: ")]
        for c, a in self.axes.items():
            if a.choice is not None and not a.choice.passed:
                out.append(f"{c}: {a.choice.warnings[0]}")
            out += [f"{c}: {w}" for w in a.warnings]
            if not a.converged:
                out.append(f"{c}: the optimizer did not converge")
        return out


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate` found: ``source`` (the input's name), ``topics`` topic ->
    :class:`TopicCalibration` in the order asked for (the file's order for ``"all"``; a file
    without topics has one entry, keyed by its topic or ``""``); ``several``: several topics
    were asked for (the report then has a section and a configuration folder per topic, failed
    ones listed)."""

    source: str
    topics: dict[str, TopicCalibration]
    several: bool = False
    #: where the time went [s, wall of this process]: ``read``, ``check`` (stationarity and the
    #: rest of the preparation), ``fits`` (waiting for every axis's work), ``verdict``; and
    #: ``axes`` [s, summed over the axes, in whichever process ran them]: ``choose`` (the
    #: automatic choice, or the given model's fit), ``page`` (datasheet and readings), ``draw``
    #: (the figures drawn beside the fits), ``identifiability`` (the verdict's length search)
    seconds: dict[str, Any] = field(default_factory=dict)

    @property
    def calibrated(self) -> dict[str, TopicCalibration]:
        return {t: s for t, s in self.topics.items() if s.ok}

    @property
    def failed(self) -> dict[str, str]:
        """Topic -> one-line reason, for every topic that failed."""
        return {t: s.reason or "failed" for t, s in self.topics.items() if not s.ok}

    @property
    def converged(self) -> bool:
        """Whether every fit of every calibrated topic converged."""
        return all(a.converged for s in self.calibrated.values() for a in s.axes.values())

    def only(self) -> TopicCalibration:
        """The one topic of a single-topic calibration."""
        if len(self.topics) != 1:
            raise InputError(f"{len(self.topics)} topics, not one")
        return next(iter(self.topics.values()))

    def to_json_dict(self) -> dict[str, Any]:
        """Per topic: status, reason, rate, warnings (for scripts; the fits are
        :meth:`gmwm.results.FitResult.to_json_dict`)."""
        return {"source": self.source,
                "topics": {t: {"status": s.status, "reason": s.reason, "freq": s.freq,
                               "rostopic": s.rostopic, "axes": list(s.axes or s.unfitted),
                               "not_fitted": s.not_fitted,
                               "warnings": s.caveats} for t, s in self.topics.items()}}


# -- worker processes -------------------------------------------------------------------------------
def _warm() -> None:
    """Load the compiled kernels in a new worker before the first fit (numba's on-disk cache)."""
    import gmwm  # noqa: F401
    from gmwm import estimator  # noqa: F401


def preload() -> None:
    """Import the fitting stack (SciPy's optimisers and special functions, the compiled
    kernels of the search, the WV covariance and the goodness-of-fit test) in this process by a
    tiny automatic model choice, so that worker processes forked from it start warm: ~1.5 s of
    imports and kernel loading happen once, not once in every worker (measured: started in each
    worker instead, even while the input is read, the four real recordings' reports took 1-2 s
    longer on two cores)."""
    from gmwm.automodel import choose_model

    rng = np.random.default_rng(0)
    x = rng.standard_normal(512) + np.cumsum(rng.standard_normal(512)) * 1e-2
    with contextlib.suppress(Exception):  # an optimisation only
        choose_model(x, freq=100.0, kind="gyroscope", max_gm=1, sin=False)


#: module the warm server imports before it forks workers (importing it runs :func:`preload`)
WARM_MODULE = "gmwm._warmserver"
_warm_server = False


def start_warm_server() -> bool:
    """Start a process that loads the fitting stack (:func:`preload`) now, beside this one, and
    later forks the workers of ``executor(..., warm=True)`` warm (multiprocessing's forkserver
    with a preload). A command that will choose several axes' models calls it first, so that the
    ~2 s of imports and kernel loading run while this process reads the input and checks its
    stationarity, instead of before the workers can start. False (nothing started) on one core
    or where there is no forkserver."""
    global _warm_server
    if _warm_server:
        return True
    if os.name != "posix" or available_cores() < 2 \
            or "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    from multiprocessing import forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload([WARM_MODULE])
    try:
        forkserver.ensure_running()
    except OSError:  # no server: the workers fork from this process as before
        return False
    _warm_server = True
    return True


def warm_server_running() -> bool:
    """Whether :func:`start_warm_server` started the warm server in this process."""
    return _warm_server


def stop_warm_server() -> None:
    """Stop the warm server of :func:`start_warm_server` (if any) and reap it, so that no process
    outlives the command and its CPU time counts in this process's children's. Its pools are
    shut down by then (their workers have exited) and it holds nothing to save, so it is
    terminated: told to exit, it would tear down its interpreter (SciPy, Numba, matplotlib:
    ~0.7 s) while the command waits; a server still loading would first finish loading."""
    global _warm_server
    if not _warm_server:
        return
    from multiprocessing import forkserver

    server = getattr(forkserver, "_forkserver", None)
    pid = getattr(server, "_forkserver_pid", None)
    with contextlib.suppress(Exception):  # a server already gone needs nothing
        if pid is not None:
            os.kill(pid, signal.SIGTERM)
        server._stop()  # closes its "alive" pipe and reaps it (what CPython's tests use)
    _warm_server = False


def executor(kind: str, workers: int, warm: bool = False) -> Executor:
    """A pool of ``workers`` threads or processes; ``warm``: worker processes start with the
    fitting stack loaded (forked by the warm server when :func:`start_warm_server` started one,
    else forked from this process after :func:`preload` ran here). Creating a pool of the warm
    server waits until the server has loaded the stack."""
    if kind == "thread":
        return ThreadPoolExecutor(max_workers=workers)
    if kind != "process":
        raise InputError(f"unknown executor {kind!r}; use 'process' or 'thread'")
    if warm and _warm_server:
        return ProcessPoolExecutor(max_workers=workers,
                                   mp_context=multiprocessing.get_context("forkserver"))
    # fork: a worker inherits the imported modules and loaded kernels and starts at once; with
    # other threads alive (which a fork would copy mid-flight) a fresh forkserver worker instead
    if os.name != "posix":
        return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(
            "spawn"), initializer=_warm)
    method = "fork" if threading.active_count() == 1 else "forkserver"
    if method == "fork" and warm:
        preload()
    return ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context(method),
                               initializer=None if method == "fork" else _warm)


def _thread(fn: Callable[[], None]) -> tuple[threading.Thread, list[BaseException]]:
    """``fn`` started in a thread; the list receives its exception, if any."""
    failed: list[BaseException] = []

    def body() -> None:
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - re-raised by the caller after join
            failed.append(exc)

    thread = threading.Thread(target=body, daemon=True)
    thread.start()
    return thread, failed


# -- one axis ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Job:
    """One axis to fit (picklable: it travels to a worker)."""

    topic: str
    name: str
    data: Any
    spec: str
    freq: float
    unit: str
    settings: Any  # FitSettings, levels already None for a WV
    explicit_starts: bool
    page: bool  # compute the datasheet (and with readings the IEEE 952 readings) beside the fit
    readings: bool
    draw: Any = None  # callable(topic, name, result, unit) -> files drawn, or None
    #: samples the estimate used, for the verdict's identifiability search beside the fit
    #: (:func:`gmwm.verdict.identifiability`); None: left to the verdict
    n_used: int | None = None


def _stopwatch() -> tuple[dict[str, float], Callable[[str], None]]:
    """(seconds per step, ``lap(step)``: records the wall time since the previous lap)."""
    spent: dict[str, float] = {}
    clock = [time.perf_counter()]

    def lap(what: str) -> None:
        now = time.perf_counter()
        spent[what] = now - clock[0]
        clock[0] = now

    return spent, lap


def _draw_axis(draw: Callable[..., Sequence[Any]], topic: str, name: str, res: Any,
               unit: str) -> list[Any]:
    """The files ``draw`` drew for one axis; none when it failed (the report draws the figure
    again then, and reports that failure)."""
    try:
        return list(draw(topic, name, res, unit))
    except Exception:  # noqa: BLE001 - reported by the report's own drawing
        return []


def _drawn_here(draw: Callable[..., Sequence[Any]], key: tuple[str, str], got: Any) -> Any:
    """``got`` of :func:`_fit_job` with the figure ``draw`` drew here (as the job would have)."""
    res, choice, _, page = got
    if "datasheet" not in page:  # a job without a page draws nothing
        return got
    started = time.perf_counter()
    drawn = _draw_axis(draw, key[0], key[1], res, page["unit"])
    page["seconds"]["draw"] = time.perf_counter() - started
    return res, choice, drawn, page


def _kind(unit: str) -> str | None:
    from gmwm.units import unit_system

    return unit_system(unit or None).sensor if unit else None


def _fit_job(job: _Job, progress: Callable[[str], None] | None = None
             ) -> tuple[Any, Any, list[Any], dict[str, Any]]:
    """One axis's fit (in a worker or not): (result, automatic choice or None, figure files
    drawn, page). The page always has ``seconds`` (:func:`_stopwatch`'s steps); with
    ``job.page`` also ``datasheet``, ``readings``, ``unit`` and, given ``job.n_used``,
    ``identifiability``, computed beside the fit so that they overlap the other workers' fits
    and the calling process needs no fitting kernels."""
    s = job.settings
    spent, lap = _stopwatch()
    choice = None
    if _is_auto(job.spec):
        from gmwm.automodel import choose_model

        kind = _kind(job.unit)
        say = progress or (lambda _m: None)
        say(f"choosing the model of {job.name}"
            + (f" ({kind})" if kind else " (no sensor unit: every candidate sum)"))
        choice = choose_model(
            job.data, freq=job.freq, kind=kind, levels=s.levels, robust=s.robust, eff=s.eff,
            seed=s.seed, n_starts=s.n_starts if job.explicit_starts else None,
            progress=None if progress is None else
            (lambda i, n, m: progress(f"{job.name}: candidate {i}/{n}: {m}")))
        res = choice.result
    else:
        import gmwm
        from gmwm.model import Model

        if progress is not None:
            progress(f"fitting {job.spec} to {job.name}")
        res = gmwm.fit(job.data, Model(job.spec, freq=job.freq), settings=s, freq=job.freq)
    lap("choose")
    if not job.page:
        return res, choice, [], {"seconds": spent}
    from gmwm.datasheet import datasheet, fit_readings

    page: dict[str, Any] = {
        "datasheet": datasheet(res, job.unit or None),
        "readings": fit_readings(res, job.unit or None) if job.readings else None,
        "seconds": spent, "unit": job.unit or ""}
    lap("page")
    if job.n_used is not None:
        # the verdict's costliest check (a recording plan per candidate length), done here so
        # that it runs in the workers beside the other axes' fits, with their kernels loaded
        from gmwm.verdict import MIN_SAMPLES, identifiability

        if job.n_used < MIN_SAMPLES:
            page["identifiability"] = {}
        else:
            with contextlib.suppress(Exception):  # a failed check is the verdict's to report
                page["identifiability"] = identifiability(res, job.n_used)
                if choice is not None:  # its rejection hint reads it too
                    choice = dataclasses.replace(
                        choice, identified=(job.n_used, page["identifiability"]))
        lap("identifiability")
    drawn: list[Any] = []
    if job.draw is not None:
        drawn = _draw_axis(job.draw, job.topic, job.name, res, job.unit or "")
        lap("draw")
    return res, choice, drawn, page


def _axis_warnings(res: Any, st: Any, channel: str, excluded: bool = False) -> list[str]:
    """The fit's warnings (less the non-convergence one) and, when the part used moved in this
    channel, where (and whether that motion was ``excluded`` from the estimate)."""
    from gmwm.formatting import fit_warnings, spans

    found = fit_warnings(res)
    if st is not None:
        a, b = st.used or (0, st.n)
        segs = [s for s in st.segments_in(a, b) if channel in s.channels]
        if segs:
            found.append(f"not static in {spans(st, segs, more='more ranges')} (see "
                         "Stationarity): " + ("excluded from the estimate" if excluded else
                                              "the coefficients include that motion"))
    return found


def _streamed(res: Any, channel: Any) -> Any:
    """A fit of a streamed channel's WV with what the WV does not hold: the sign of a drift (from
    the signal's first and last samples, as :func:`gmwm.fit` takes it from a signal) and the
    seconds the streamed WV took."""
    if res.settings.method != "avsm":
        res = res.with_drift_sign(channel.drift_sign)
    return dataclasses.replace(res, seconds_wv=channel.seconds)


def _reason(exc: BaseException) -> str:
    """The one-line reason of a failure."""
    text = str(exc).strip()
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.strerror or text}: {exc.filename}"
    return text.splitlines()[0] if text else type(exc).__name__


#: what makes one topic fail without stopping the others
_TOPIC_ERRORS = (GMWMError, OSError)


# -- reading ------------------------------------------------------------------------------------------
def _read(path: str | os.PathLike, topics: str | Sequence[str], *, columns: Any,
          freq: float | None) -> dict[str, Any]:
    """Topic -> Recording, or the exception that topic's reading raised. The file is read once
    (:func:`gmwm.readers.read_recordings`); only when that fails is each topic read alone, so
    that one topic with broken stamps does not stop the others."""
    from gmwm.readers import imu_topics, read_recording, read_recordings

    try:
        return dict(read_recordings(path, topics, columns=columns, freq=freq))
    except _TOPIC_ERRORS as exc:
        first = exc
    if isinstance(topics, str) and topics.strip().lower() == "all":
        names = imu_topics(path)  # a file without any IMU topic: its own error
    else:
        names = [topics] if isinstance(topics, str) else list(topics)
        if len({n.lstrip("/") for n in names}) < len(names):
            raise first  # a topic requested twice: the request is wrong, not a topic
    out: dict[str, Any] = {}
    for name in names:
        try:
            rec = read_recording(path, topic=name, columns=columns, freq=freq)
            out[rec.topic or name] = rec
        except _TOPIC_ERRORS as exc:
            out[name] = exc
    return out


# -- the calibration -------------------------------------------------------------------------------
def calibrate(source: Any, model: str | Mapping[str, str] = AUTO, *,
              topics: str | Sequence[str] | None = None, columns: Any = None,
              dataset: str | None = None, freq: float | None = None,
              time_unit: str | None = None,
              units: str | Sequence[str] | Mapping[str, Any] | None = None,
              levels: int | None = None, gaps: str = "auto", start_s: float | None = None,
              end_s: float | None = None, segment: str = "all", strict: bool = False,
              fit: Mapping[str, Any] | None = None, sheet: Any = None, check: bool = False,
              readings: bool = False, draw: Callable[..., Sequence[Any]] | None = None,
              workers: int | None = None, worker_kind: str = "process",
              require_time: str | None = "a calibration report",
              name: str | None = None, progress: Callable[[str], None] | None = None,
              while_waiting: Callable[[Mapping[str, Prepared]], None] | None = None,
              motion_share: float = MOTION_SHARE, allow_motion: bool = False,
              fit_refused: bool = True) -> CalibrationResult:
    """Calibrate the IMU(s) of ``source``: a file path, a :class:`gmwm.readers.Recording`, a
    :class:`Prepared` input, or a mapping topic -> either (several IMUs).

    Reading a path: ``topics`` None (the file's only IMU, or its columns), one topic name, a
    list of names or ``"all"`` (every IMU stream of a bag or ULog,
    :func:`gmwm.readers.imu_topics`); ``columns``, ``dataset``, ``freq``, ``time_unit`` as
    :func:`gmwm.readers.read_recording`. Then per topic: ``units`` (as :func:`units_for`; topic
    -> units for several topics given as a mapping of mappings), ``levels``, ``gaps``,
    ``start_s``/``end_s``, ``segment``, ``strict``, ``require_time`` as :func:`prepare`; per
    axis the ``model`` (as :func:`models_for`; ``"auto"``: :func:`gmwm.automodel.choose_model`
    with the sensor kind of the unit) fitted with ``fit`` (options of
    :meth:`gmwm.settings.FitSettings.of`: ``method``, ``weights``, ``seed``, ``n_starts``, ...);
    ``sheet`` a :class:`gmwm.sensor_datasheet.SensorDatasheet` to judge the axes against;
    ``check``: the identifiability check (:func:`gmwm.identify.check`) of every fit;
    ``readings``: the IEEE 952 readings computed beside each fit (a report needs them).

    Work: the automatic choices run in worker processes (:func:`executor`, at most ``workers``,
    default :func:`available_cores`; ``worker_kind="thread"``: threads instead, for a
    comparison), the given models too when there are several topics; a
    worker also computes its axis's datasheet and, with ``draw`` (a picklable
    ``draw(topic, axis, result, unit) -> files``, e.g. :class:`gmwm.report.FigureDrawer`; one
    with a ``bind(topics)`` method is bound to the topics read first), its figure. ``while_waiting(prepared)`` runs in this process while the workers fit.
    ``progress``: called with one line per step; lines starting with ``warning: `` or ``note: ``
    are for the user (prefixed by the topic when there are several).

    A topic that fails (unreadable, broken stamps, too short, not static under ``strict``) is
    kept as ``status="failed"`` with its one-line ``reason`` while the others are calibrated; the
    error itself is raised when there is only one topic, and an :class:`InputError` listing the
    reasons when every topic failed. Wrong settings (a model string, a unit, ``fit`` options) are
    errors before any fit.

    Each calibrated topic carries its :attr:`TopicCalibration.verdict`
    (:class:`gmwm.verdict.Verdict`): whether its configuration files may be written and the
    caveats their first lines must carry. ``motion_share``/``allow_motion``: the motion policy
    of :func:`prepare` (flagged motion up to that share excluded; beyond it no configuration
    unless ``allow_motion``). ``fit_refused=False``: a topic refused for motion is not fitted
    (its fits would describe the motion, and no configuration is written from them): it is
    kept as calibrated with no ``axes``, its WVs in :attr:`TopicCalibration.unfitted`, the
    reason in :attr:`TopicCalibration.not_fitted` and among its verdict's reasons."""
    from gmwm.readers.recording import Recording
    from gmwm.settings import FitSettings

    say = progress or (lambda _m: None)
    options = dict(fit or {})
    settings = FitSettings.of(**options)  # bad options before the input is read
    explicit_starts = "n_starts" in options
    label = name or (str(source) if isinstance(source, str | os.PathLike) else "the recording")
    seconds, lap = _stopwatch()
    # -- the inputs, topic -> Recording | Prepared | exception
    several = False
    if isinstance(source, str | os.PathLike):
        if not Path(source).exists():
            raise InputError(f"file not found: {source}")
        several = topics is not None and not (isinstance(topics, str)
                                              and topics.strip().lower() != "all")
        if several:
            say(f"reading {label} ("
                + ("every IMU topic" if isinstance(topics, str) else ", ".join(topics)) + ")")
            inputs: dict[str, Any] = _read(source, topics, columns=columns, freq=freq)
        else:
            from gmwm.readers import read_recording

            say(f"reading {label}")
            rec = read_recording(source, topic=topics, columns=columns, dataset=dataset,
                                 freq=freq, time_unit=time_unit)
            inputs = {rec.topic or "": rec}
    elif isinstance(source, Recording | Prepared):
        inputs = {source.topic or "": source}
    elif isinstance(source, Mapping):
        if not source:
            raise InputError("no IMU to calibrate")
        inputs, several = dict(source), True
    else:
        raise InputError(f"cannot calibrate a {type(source).__name__}: give a file, a "
                         "Recording, a Prepared input or a mapping topic -> Recording")
    if draw is not None and hasattr(draw, "bind"):  # e.g. figure names that depend on the topics
        draw = draw.bind(list(inputs))
    multi_units = isinstance(units, Mapping) and units and all(
        isinstance(v, Mapping) for v in units.values())

    def tell(topic: str, msg: str) -> None:
        if several and msg.startswith(("warning: ", "note: ")):
            kind, text = msg.split(": ", 1)
            msg = f"{kind}: {topic}: {text}"
        say(msg)

    lap("read")
    # -- preparation, per topic (a failure stays with its topic)
    prepared: dict[str, Prepared] = {}
    failed: dict[str, BaseException] = {}
    for topic, item in inputs.items():
        if isinstance(item, BaseException):
            failed[topic] = item
            tell(topic, f"warning: not calibrated: {_reason(item)}")
            continue
        if isinstance(item, Prepared):
            prepared[topic] = _streamed_motion(item, motion_share, allow_motion)
            for m in prepared[topic].messages[len(item.messages):]:
                tell(topic, m)
            continue
        say(f"checking stationarity of {topic}" if several else "checking stationarity")
        try:
            prep = prepare(item, units=units.get(topic) if multi_units else units,
                           levels=levels, gaps=gaps, start_s=start_s, end_s=end_s,
                           segment=segment, strict=strict, require_time=require_time,
                           where=f"{label} topic {topic}" if several else label,
                           motion_share=motion_share, allow_motion=allow_motion)
        except _TOPIC_ERRORS as exc:
            if not several:
                raise
            failed[topic] = exc
            tell(topic, f"warning: not calibrated: {_reason(exc)}")
            continue
        for m in prep.messages:
            tell(topic, m)
        prepared[topic] = prep
    lap("check")
    # -- settings checked against every topic before any fit
    specs = {t: models_for(model, list(p.data)) for t, p in prepared.items()}
    jobs: list[_Job] = []
    skipped = set() if fit_refused else {t for t, p in prepared.items() if p.motion_refused}
    for t, p in prepared.items():
        for c, d in p.data.items():
            spec = specs[t][c]
            if _is_auto(spec):
                if settings.method != "gmwm":
                    raise InputError(f"the automatic model choice fits GMWM candidates; with "
                                     f"`method` {settings.method} give a model")
            else:
                from gmwm.model import Model

                Model(spec, freq=p.freq)  # a wrong model string fails before any fit
            if settings.robust and not isinstance(d, np.ndarray):
                raise InputError("`robust` needs one contiguous signal, but the gaps of the "
                                 "recording leave the pooled WV of its segments: use `gaps` "
                                 "longest")
            s = settings if isinstance(d, np.ndarray) else settings.replace(levels=None)
            if t in skipped:
                continue
            jobs.append(_Job(t, c, d, spec, p.freq, p.units.get(c, ""), s, explicit_starts,
                             page=c not in p.streamed, readings=readings,
                             draw=draw if c not in p.streamed else None,
                             n_used=p.n_used if c not in p.streamed else None))
    if sheet is not None:
        _check_sheet(sheet, prepared, tell)
    # -- the fits: automatic choices in worker processes, given models too for several topics
    results = _run_jobs(jobs, several=len(prepared) > 1, workers=workers, kind=worker_kind,
                        progress=say,
                        prepared=prepared, while_waiting=while_waiting)
    lap("fits")
    # -- per topic: the axes, their datasheets, verdicts and checks
    out: dict[str, TopicCalibration] = {}
    for topic in inputs:
        if topic in failed:
            exc = failed[topic]
            out[topic] = TopicCalibration(topic, "failed", reason=_reason(exc), error=exc)
            continue
        p = prepared[topic]
        if topic in skipped:
            out[topic] = _unfitted_topic(topic, p, settings)  # its verdict line says why
            continue
        got = {j.name: results[(topic, j.name)] for j in jobs if j.topic == topic}
        bad = next((r for r in got.values() if isinstance(r, BaseException)), None)
        if bad is not None:
            if not several:
                raise bad
            out[topic] = TopicCalibration(topic, "failed", reason=_reason(bad), error=bad,
                                          freq=p.freq, timing=p.timing,
                                          stationarity=p.stationarity, gaps=p.gaps,
                                          rostopic=p.rostopic, label=p.label,
                                          messages=p.messages)
            tell(topic, f"warning: not calibrated: {_reason(bad)}")
            continue
        axes = _axes(p, got, sheet, check, say)
        known = {c: g[3]["identifiability"] for c, g in got.items()
                 if "identifiability" in g[3]}
        out[topic] = TopicCalibration(topic, "calibrated", axes, freq=p.freq,
                                      timing=p.timing, stationarity=p.stationarity,
                                      gaps=p.gaps, rostopic=p.rostopic, label=p.label,
                                      messages=p.messages, verdict=_verdict(p, axes, known))
    lap("verdict")
    spent: dict[str, float] = {}
    for r in results.values():
        if not isinstance(r, BaseException):
            for k, v in r[3]["seconds"].items():
                spent[k] = spent.get(k, 0.0) + v
    result = CalibrationResult(label, out, several, {**seconds, "axes": spent})
    if not result.calibrated:
        fails = result.failed
        if len(fails) == 1:
            raise next(iter(out.values())).error  # type: ignore[misc]
        raise InputError(f"no topic of {label} could be calibrated: "
                         + "; ".join(f"{t}: {r}" for t, r in fails.items()))
    return result


#: why a topic refused for motion has no fits (:func:`calibrate`'s ``fit_refused=False``)
NOT_FITTED = ("the axes were not fitted: refused for motion, a fit would describe the motion, not "
              "the sensor at rest")


def _unfitted_topic(topic: str, p: Prepared, settings: Any) -> TopicCalibration:
    """A topic refused for motion, not fitted: its WVs (as the fits would have used them) and
    its verdict (the refusals, then :data:`NOT_FITTED`)."""
    from gmwm.settings import prepare_wv
    from gmwm.verdict import decide

    wvs = {}
    for c, d in p.data.items():
        s = settings if isinstance(d, np.ndarray) else settings.replace(levels=None)
        wvs[c] = UnfittedAxis(prepare_wv(p.streamed[c].wv if c in p.streamed else d, s,
                                         freq=p.freq).wv, p.units.get(c, ""))
    n = p.n_used if p.n_used is not None else min(int(a.wv.n_samples) for a in wvs.values())
    verdict = decide({}, n_samples=n, refusals=(*p.refusals, NOT_FITTED), caveats=p.caveats)
    return TopicCalibration(topic, "calibrated", {}, freq=p.freq, timing=p.timing,
                            stationarity=p.stationarity, gaps=p.gaps, rostopic=p.rostopic,
                            label=p.label, messages=p.messages, verdict=verdict,
                            unfitted=wvs, not_fitted=NOT_FITTED)


def _check_sheet(sheet: Any, prepared: Mapping[str, Prepared],
                 tell: Callable[[str, str], None]) -> None:
    """A sensor datasheet against the axes' units, before any fit: an axis without a known unit
    is an error; one of a sensor type the datasheet has no section for gets a warning; none of
    a type it describes is an error."""
    from gmwm.units import parse_unit

    covered = False
    for t, p in prepared.items():
        for c, u in p.units.items():
            parsed = parse_unit(u) if u else None
            if parsed is None:
                raise InputError(f"`sheet`: give the unit of {c} with `units` (e.g. deg/s "
                                 "or m/s^2) to tell a gyroscope from an accelerometer")
            if parsed[2] not in sheet.sensors:
                tell(t, f"warning: {c}: the datasheet {sheet.where} has no {parsed[2]} section: "
                        "no verdict")
            else:
                covered = True
    if not covered:
        raise InputError(f"`sheet` {sheet.where}: no fitted column is of a sensor type it "
                         f"describes ({', '.join(sheet.sensors)})")


def _run_jobs(jobs: Sequence[_Job], *, several: bool, workers: int | None, kind: str,
              progress: Callable[[str], None], prepared: Mapping[str, Prepared],
              while_waiting: Callable[[Mapping[str, Prepared]], None] | None
              ) -> dict[tuple[str, str], Any]:
    """(topic, axis) -> (result, choice, files, page) of :func:`_fit_job`, or the exception its
    fit raised. The automatic choices (and, with ``several`` topics, every fit) go to worker
    processes when at least two can run at once; the rest run here one after the other."""
    cores = available_cores() if workers is None else max(1, int(workers))
    pooled = [j for j in jobs if several or _is_auto(j.spec)]
    n = min(len(pooled), cores)
    if n < 2:
        pooled = []
    out: dict[tuple[str, str], Any] = {}
    if pooled:
        progress(f"fitting {len(pooled)} axes in {n} parallel "
                 + ("processes" if kind == "process" else "threads"))
        # worker processes fit; this process, idle meanwhile and with the plotting library
        # already loaded for the stationarity figure, draws each axis's figure as its fit
        # arrives (the workers then never load matplotlib)
        here = {(j.topic, j.name): j.draw for j in pooled} if kind == "process" else {}
        with executor(kind, n, warm=True) as pool:
            futures: dict[tuple[str, str], Any] = {}

            def submit() -> None:
                for j in pooled:
                    futures[(j.topic, j.name)] = pool.submit(
                        _fit_job, dataclasses.replace(j, draw=None) if here else j)

            if warm_server_running() and while_waiting is not None:
                # the warm server answers the first submission once it has loaded the fitting
                # stack: submit from a thread and do this process's own work meanwhile (no fork
                # from this process, so its threads are safe)
                thread, failed = _thread(submit)
                while_waiting(prepared)
                thread.join()
                if failed:
                    raise failed[0]
            else:
                submit()
                if while_waiting is not None:
                    while_waiting(prepared)
            for key, f in futures.items():
                try:
                    out[key] = f.result()
                except _TOPIC_ERRORS as exc:
                    out[key] = exc
                    continue
                if out[key][1] is not None:
                    progress(f"{key[1]}: {out[key][1].headline()}")
                if here.get(key) is not None:
                    out[key] = _drawn_here(here[key], key, out[key])
    for j in jobs:
        if (j.topic, j.name) in out:
            continue
        try:
            # here the datasheet comes after the streamed corrections (:func:`_axes`)
            out[(j.topic, j.name)] = _fit_job(dataclasses.replace(j, page=False, draw=None),
                                              progress)
        except _TOPIC_ERRORS as exc:
            out[(j.topic, j.name)] = exc
    return out


def _excluded(p: Prepared) -> bool:
    """Whether the flagged motion of ``p``'s part used was left out of its estimate."""
    return bool(getattr(p.stationarity, "excluded", False))


def _verdict(p: Prepared, axes: Mapping[str, AxisCalibration],
             known: Mapping[str, Mapping[str, float | None]] | None = None) -> Any:
    """The configuration verdict of one topic (:func:`gmwm.verdict.decide`); ``known``:
    channel -> its identifiability at ``p.n_used`` already computed beside its fit."""
    from gmwm.units import unit_system
    from gmwm.verdict import decide

    n = p.n_used
    if n is None:  # a WV table or a streamed input: the length the WVs were computed on
        n = min((int(getattr(a.result.wv, "n_samples", 0)) for a in axes.values()), default=0)
    systems = {c: unit_system(a.units or None) for c, a in axes.items()}
    return decide({c: a.choice if a.choice is not None else a.result for c, a in axes.items()},
                  n_samples=n, kinds={c: u.sensor for c, u in systems.items()},
                  to_si={c: u.si or 1.0 for c, u in systems.items()},
                  refusals=p.refusals, caveats=p.caveats,
                  identified=known if p.n_used is not None else None)


def _axes(p: Prepared, got: Mapping[str, Any], sheet: Any, check: bool,
          progress: Callable[[str], None]) -> dict[str, AxisCalibration]:
    """The axes of one prepared topic from its fits."""
    from gmwm.datasheet import datasheet
    from gmwm.units import parse_unit

    axes = {}
    for c, (res, choice, files, page) in got.items():
        if c in p.streamed:
            res = _streamed(res, p.streamed[c])
        if choice is not None and not choice.passed:  # the rejection hint knows the motion
            from gmwm.verdict import evidence

            choice = choice.with_evidence(evidence(p.stationarity, c, _excluded(p)))
        unit = p.units.get(c, "")
        chk = None
        if check:
            from gmwm import identify

            progress(f"identifiability check of {c}")
            chk = identify.check(res)
        verdict = None
        if sheet is not None:
            parsed = parse_unit(unit) if unit else None
            if parsed is not None and parsed[2] in sheet.sensors:
                from gmwm.sensor_datasheet import judge

                verdict = judge(res, sheet, unit)
        axes[c] = AxisCalibration(res, unit, page.get("datasheet") or datasheet(res, unit or None),
                                  tuple(_axis_warnings(res, p.stationarity, c,
                                                       _excluded(p))), choice,
                                  page.get("readings"), verdict, chk, tuple(files))
    return axes


def calibrate_imus(recordings: Mapping[str, Any], model: str | Mapping[str, str] = "WN+RW", *,
                   fit_options: Mapping[str, Any] | None = None, **kw: Any
                   ) -> dict[str, TopicCalibration]:
    """The calibrated topics of :func:`calibrate` for ``recordings`` (topic -> Recording), for
    :func:`gmwm.report.write_multi_report` (kept for existing scripts; ``executor``:
    ``"process"`` or ``"thread"``)."""
    kind = kw.pop("executor", "process")
    return calibrate(dict(recordings), model, fit=fit_options, worker_kind=kind, **kw).calibrated
