"""Calibrate the IMUs of a recording: for each stream the stationarity check, the gap policy, a
GMWM fit per axis and the datasheet coefficients, ready for :func:`gmwm.report.write_report` or
:func:`gmwm.report.write_multi_report`.

The fits of several IMUs are independent, so :func:`calibrate_imus` runs the (IMU, axis) fits
concurrently, at most one per core this process may use (``os.sched_getaffinity``). Threads by
default: a fit spends most of its time in code that releases the GIL (numba ``nogil`` kernels,
LAPACK, the C WV kernel), so threads overlap about as well as worker processes without their
start-up and the copying of each signal (``benchmarks/bench_multi_imu.py`` measures serial,
threads and processes). Each fit is deterministic for a given ``seed``, so the results do not
depend on the number of workers or their kind.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
from collections.abc import Mapping
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["available_cores", "calibrate_imus", "prepare_imu"]


def available_cores() -> int:
    """The number of cores this process may run on (its CPU affinity; at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _rostopic(rec: Any) -> str | None:
    """The ROS topic a filter subscribes to, for a bag recording (a ULog stream has none)."""
    return rec.topic if rec.topic and rec.format.startswith("ros") else None


def prepare_imu(rec: Any, *, units: Mapping[str, str | None] | None = None,
                levels: int | None = None, gaps: str = "auto", start_s: float | None = None,
                end_s: float | None = None, segment: str = "all", strict: bool = False
                ) -> dict[str, Any]:
    """The stationarity check, the part used and the fit inputs of one recording.

    ``units``: channel -> signal unit replacing the recording's (e.g. for a Vector3Stamped
    topic); ``levels``: number of WV scales (None: all); ``gaps``: the gap policy
    (:meth:`gmwm.readers.recording.Recording.gaps`); ``start_s``/``end_s``: the part to use,
    seconds since the first sample; ``segment``: ``"all"`` or ``"longest-static"`` (the longest
    stretch of that part no flagged range touches); ``strict``: a used part that moved is a
    :class:`gmwm.stationarity.NonStationaryError`. Returns ``recording`` (the part used),
    ``stationarity``, ``gaps`` (the decision), ``data`` channel -> fit input (signal or pooled
    WV), ``units``, ``freq``, ``timing`` (report lines) and ``notes`` (warnings to show)."""
    from gmwm.readers.recording import sample_range, select_samples
    from gmwm.readers.timebase import signal_for_wv
    from gmwm.stationarity import NonStationaryError, check_stationarity

    where = rec.path + (f" topic {rec.topic}" if rec.topic else "")
    tb = rec.require_time(f"a calibration report of {where}")
    u = {c: (units or {}).get(c, rec.units.get(c)) for c in rec.channels}
    st = check_stationarity(rec, units=u)
    i0, i1 = (0, rec.n) if start_s is None and end_s is None else \
        sample_range(rec, start_s, end_s)
    how = "the whole recording" if (i0, i1) == (0, rec.n) else "--start/--end"
    if segment == "longest-static":
        free, at = [], i0
        for s in st.segments:  # the stretches of the requested range no flagged segment touches
            if s.i0 > at:
                free.append((at, min(s.i0, i1)))
            at = max(at, s.i1)
        if at < i1:
            free.append((at, i1))
        free = [(a, b) for a, b in free if b > a]
        if not free or max(b - a for a, b in free) < 64:
            raise NonStationaryError(f"--segment longest-static: {where} has no static stretch "
                                     "of 64 samples or more")
        i0, i1 = max(free, key=lambda e: e[1] - e[0])
        how = "longest static segment" + ("" if how.startswith("the whole") else
                                          " within --start/--end")
    elif segment != "all":
        raise InputError(f"unknown segment choice {segment!r}; use all or longest-static")
    st = st.using(i0, i1, how)
    if strict and st.moving_in_used:
        raise NonStationaryError(f"{where} is not static in the part used and --strict is set")
    notes = [*rec.notes, *st.warnings()]
    used = select_samples(rec, i0, i1)
    decision = used.gaps(gaps)
    if decision.message:
        notes.append(decision.message)
    timing = [f"Recording ({rec.format}{', topic ' + rec.topic if rec.topic else ''}): "
              + tb.summary()]
    timing += [n for n in rec.notes if n not in timing]
    if decision.message:
        timing.append(decision.message)
    data = {c: signal_for_wv(x, decision, levels, tb.freq) for c, x in used.channels.items()}
    return {"recording": used, "stationarity": st, "gaps": decision, "data": data, "units": u,
            "freq": tb.freq, "timing": timing, "notes": notes}


#: the model string asking for the automatic choice (:func:`gmwm.automodel.choose_model`)
AUTO = "auto"


def _fit_one(data: Any, spec: str, freq: float, levels: int | None,
             options: Mapping[str, Any], unit: str | None = None) -> Any:
    """One axis's GMWM fit (runs in a worker); with ``spec`` "auto" the
    :class:`gmwm.automodel.Choice` of the axis (the sensor kind from ``unit``)."""
    import gmwm
    from gmwm.model import Model

    lv = levels if isinstance(data, np.ndarray) else None  # a pooled WV is already subset
    if spec.strip().lower() == AUTO:
        from gmwm.automodel import choose_model
        from gmwm.units import unit_system

        kind = unit_system(unit).sensor if unit else None
        opts = {k: v for k, v in options.items() if k in ("seed", "n_starts", "robust", "eff")}
        if options.get("method", "gmwm") != "gmwm":
            raise InputError("the automatic model choice fits GMWM candidates; give a model")
        return choose_model(data, freq=freq, kind=kind, levels=lv, **opts)
    return gmwm.fit(data, Model(spec, freq=freq), levels=lv, freq=freq, **dict(options))


def _choose_and_draw(data: Any, freq: float, levels: int | None, options: Mapping[str, Any],
                     unit: str | None, figure: tuple[str, str] | None
                     ) -> tuple[Any, list[Any], dict[str, Any] | None]:
    """One axis's automatic model choice (:func:`_fit_one`) and, with ``figure`` = (file,
    axis name), what a report page needs of it computed in the same worker: the WV figure
    (:func:`gmwm.report.draw_wv_figure`), the datasheet coefficients
    (:func:`gmwm.datasheet.datasheet`) and the IEEE 952 readings
    (:func:`gmwm.datasheet.fit_readings`), so that they overlap the other workers' choices and
    the calling process needs no fitting kernels. Returns (choice, files drawn, None or
    ``{"datasheet": ..., "readings": ...}``); a figure that fails is left to the report."""
    choice = _fit_one(data, AUTO, freq, levels, options, unit)
    if figure is None:
        return choice, [], None
    from gmwm.datasheet import datasheet, fit_readings
    from gmwm.report import draw_wv_figure

    page = {"datasheet": datasheet(choice.result, unit or None),
            "readings": fit_readings(choice.result, unit or None)}
    try:
        drawn = draw_wv_figure(figure[0], figure[1], choice.result, unit or "")
    except Exception:  # noqa: BLE001 - the report draws it again and reports a failure then
        drawn = []
    return choice, drawn, page


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
_WARM_MODULE = "gmwm._warmserver"
_warm_server = False


def start_warm_server() -> bool:
    """Start a process that loads the fitting stack (:func:`preload`) now, beside this one, and
    later forks the workers of ``_executor(..., warm=True)`` warm (multiprocessing's forkserver
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

    multiprocessing.get_context("forkserver").set_forkserver_preload([_WARM_MODULE])
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


def _executor(kind: str, workers: int, warm: bool = False) -> Executor:
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


def _axis_warnings(res: Any, st: Any, channel: str) -> list[str]:
    """The fit's diagnostics warnings and, when the part used moved in this channel, where."""
    found = [str(w) for w in (getattr(res, "diagnostics", None) or {}).get("warnings", [])]
    if st is not None:
        a, b = st.used or (0, st.n)
        segs = [s for s in st.segments_in(a, b) if channel in s.channels]
        if segs:
            where = ", ".join(st.span(s.start_s, s.end_s) for s in segs[:4])
            found.append(f"not static in {where}"
                         + (f" and {len(segs) - 4} more ranges" if len(segs) > 4 else "")
                         + " (see Stationarity): the coefficients include that motion")
    return found


def calibrate_imus(recordings: Mapping[str, Any], model: str | Mapping[str, str] = "WN+RW", *,
                   units: Mapping[str, Mapping[str, str | None]] | None = None,
                   levels: int | None = None, gaps: str = "auto", start_s: float | None = None,
                   end_s: float | None = None, segment: str = "all", strict: bool = False,
                   fit_options: Mapping[str, Any] | None = None, workers: int | None = None,
                   executor: str = "thread", progress: Any = None) -> dict[str, Any]:
    """Calibrate every IMU of ``recordings`` (topic -> :class:`gmwm.readers.Recording`, e.g.
    from :func:`gmwm.readers.read_recordings`); return topic -> :class:`gmwm.report.ImuSection`
    in the same order, for :func:`gmwm.report.write_multi_report`.

    ``model``: one model string for every axis, or channel -> model string; ``units``: topic ->
    (channel -> unit) replacing the file's; ``levels``, ``gaps``, ``start_s``, ``end_s``,
    ``segment``, ``strict``: as :func:`prepare_imu`, for every IMU; ``fit_options``: passed to
    :func:`gmwm.fit` (``method``, ``weights``, ``seed``, ``n_starts``, ...). ``workers``: fits run
    at once (None: :func:`available_cores`; 1: one after the other); ``executor``: ``"thread"``
    (default) or ``"process"``. ``progress``: called with a one-line message per step.

    Each ``ImuSection.axes[channel]`` holds ``result``, ``units``, ``warnings`` and
    ``datasheet`` (what :func:`gmwm.report.write_report` needs; a caller may add ``verdict``);
    ``timing`` lists the time base, the gap decision and the recording's notes. Those notes, the
    stationarity warnings and the gap decision also go to ``progress`` as ``warning: ...``."""
    from gmwm.datasheet import datasheet
    from gmwm.model import Model
    from gmwm.report import ImuSection

    if not recordings:
        raise InputError("no IMU to calibrate")
    say = progress or (lambda _msg: None)
    prepared: dict[str, dict[str, Any]] = {}
    jobs: list[tuple[str, str, Any, str, float, str | None]] = []
    for topic, rec in recordings.items():
        say(f"checking stationarity of {topic}")
        prep = prepare_imu(rec, units=(units or {}).get(topic), levels=levels, gaps=gaps,
                           start_s=start_s, end_s=end_s, segment=segment, strict=strict)
        for note in prep["notes"]:
            say(f"warning: {topic}: {note}")
        prepared[topic] = prep
        for c, d in prep["data"].items():
            spec = model if isinstance(model, str) else model.get(c)
            if spec is None:
                raise InputError(f"no model given for channel {c} of {topic}")
            if spec.strip().lower() != AUTO:
                Model(spec, freq=prep["freq"])  # a wrong model string fails before any fit
            jobs.append((topic, c, d, spec, prep["freq"], prep["units"].get(c)))
    n = min(len(jobs), available_cores() if workers is None else max(1, int(workers)))
    opts = dict(fit_options or {})
    results: dict[tuple[str, str], Any] = {}
    if n <= 1:
        for topic, c, d, spec, freq, unit in jobs:
            say(f"fitting {spec} to {c} of {topic}")
            results[(topic, c)] = _fit_one(d, spec, freq, levels, opts, unit)
    else:
        say(f"fitting {len(jobs)} axes in {n} parallel {executor}s")
        with _executor(executor, n, warm=True) as pool:
            futures = {(t, c): pool.submit(_fit_one, d, spec, freq, levels, opts, unit)
                       for t, c, d, spec, freq, unit in jobs}
            results = {k: f.result() for k, f in futures.items()}
    out: dict[str, Any] = {}
    for topic, prep in prepared.items():
        rec, st = prep["recording"], prep["stationarity"]
        axes = {}
        for c in prep["data"]:
            res = results[(topic, c)]
            choice = None
            if hasattr(res, "ranking"):  # an automatic choice: its fit, its ranking
                choice, res = res, res.result
            unit = prep["units"].get(c)
            axes[c] = {"result": res, "units": unit or "",
                       "warnings": _axis_warnings(res, st, c),
                       "datasheet": datasheet(res, unit or None), "choice": choice}
        label = f"{rec.format}, {rec.n} samples"
        out[topic] = ImuSection(axes, tuple(prep["timing"]), st, _rostopic(rec), label)
    return out
