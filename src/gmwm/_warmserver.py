"""Imported by the warm server of :func:`gmwm.calibrate.start_warm_server` (multiprocessing's
forkserver preload) before it forks any worker: loads the fitting stack once
(:func:`gmwm.calibrate.preload`) and matplotlib with a page figure's code paths, so that every
worker forked from the server starts warm. Nothing of it may fail or print: the server would
die, or its output would reach the user."""

from __future__ import annotations

import contextlib
import warnings

with contextlib.suppress(Exception), warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from gmwm.calibrate import preload

    preload()

    # the workers draw their axes' figures: matplotlib, its fonts and the page figure's code
    # paths loaded once here, not in every worker's first figure
    import io

    from gmwm.plots import new_axes, page_layout

    _ax = new_axes()
    _ax.loglog([1e-2, 1.0, 1e2], [1e-4, 1e-6, 1e-5], label="WV")
    _ax.set_xlabel("Scale τ [s]")
    _ax.legend()
    page_layout(_ax.figure).savefig(io.BytesIO(), format="png", dpi=40)
