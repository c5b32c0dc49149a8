"""A fleet of IMUs calibrated in one run (``gmwm fleet``): every recording calibrated as ``gmwm
report`` would, then the fleet table (each unit's coefficients with intervals, the fleet's typical
value and between-unit spread, out-of-family units, drift over time).

Layout: :mod:`gmwm.fleet.core` (the statistics; NumPy, SciPy and statsmodels' meta-analysis),
:mod:`gmwm.fleet.collect` (inputs, unit identity, one recording's estimates from its report
folder), :mod:`gmwm.fleet.output` (CSV, Markdown, JSON and the HTML page), :mod:`gmwm.fleet.run`
(the Snakemake workflow ``gmwm/data/fleet.smk`` and the per-recording calibration). Nothing here
imports Snakemake at module level.
"""

from __future__ import annotations

from gmwm.fleet.core import (
    CoefficientSummary,
    Drift,
    Estimate,
    Fleet,
    RandomEffects,
    UnitVerdict,
    fit_drift,
    fleet_table,
    log_se,
    prediction_interval,
    q_profile_tau2,
    random_effects,
)

__all__ = ["CoefficientSummary", "Drift", "Estimate", "Fleet", "RandomEffects", "UnitVerdict",
           "fit_drift", "fleet_table", "log_se", "prediction_interval", "q_profile_tau2",
           "random_effects"]
