"""Imported by the warm server of :func:`gmwm.calibrate.start_warm_server` (multiprocessing's
forkserver preload) before it forks any worker: loads the fitting stack once
(:func:`gmwm.calibrate.preload`), so that every worker forked from the server starts warm. Not
matplotlib: the calling process draws the figures (it has it loaded for the stationarity
figure), so the workers can start ~0.3 s sooner. Nothing of it may fail or print: the server would
die, or its output would reach the user."""

from __future__ import annotations

import contextlib
import warnings

with contextlib.suppress(Exception), warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from gmwm.calibrate import preload

    preload()
