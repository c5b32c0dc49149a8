"""The studies' cheaper paths give the numbers of the full ones: fits of cached WVs rebuilt with
the eta_3 interval (``montecarlo.STUDY_WV_CI``) equal fits of the same WVs with the library's
default (mixture) interval, for every estimator kind the studies run."""

import numpy as np
import pytest

from gmwm.model import Model
from gmwm.wv import WaveletVariance, wvar
from gmwm_studies import stim300
from gmwm_studies.montecarlo import (
    STUDY_WV_CI,
    estimator_settings,
    fit_chunk,
    replicate_seed,
    simulate_wv_chunk,
)

T = 1 << 14
CASES = {
    # (model, truth, estimator settings, STIM-300 kind)
    "gmwm_ci": ("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01},
                {"method": "gmwm", "weights": "ci-eta3", "n_starts": 2}, False),
    "gmwm_mixture_weights": ("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99,
                                        "AR1[1].sigma2": 0.01},
                             {"method": "gmwm", "weights": "ci-mixture", "n_starts": 2}, False),
    "gmwm_eff": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4},
                 {"method": "gmwm", "weights": "efficient", "n_starts": 2}, False),
    "stim_gmwm_cf": ("QN+WN+RW", {"QN[1].Q2": 0.1, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5},
                     {"method": "gmwm", "weights": "ci-eta3", "n_starts": 1, "reweight": 2}, True),
    "stim_armav": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5},
                   {"method": "armav", "n_starts": 1}, True),
    "stim_avsm": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5},
                  {"method": "avsm", "min_edof": 2, "slope_tol": 0.1}, True),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_eta3_rebuilt_wv_fits_equal_mixture_ones(case):
    model_spec, truth, settings, is_stim = CASES[case]
    chunk = simulate_wv_chunk(model_spec, truth, T, [0, 1], study="cost", base_seed=5)
    if is_stim:
        ds = stim300.fit_chunk(chunk, settings, case, freq=1.0)
    else:
        ds = fit_chunk(chunk, settings, case)
    model = Model(model_spec)
    for i, rep in enumerate(chunk.replicates):
        wv = WaveletVariance.from_table(chunk.scales, chunk.variances[i], n_samples=T,
                                        ci="mixture")
        seed = replicate_seed("cost", T, int(rep), 5, stream=1)
        if is_stim:
            params, se, conv, obj, _ = stim300.fit_wv(wv, model, settings, seed)
        else:
            from gmwm import fit

            res = fit(wv, model, settings=estimator_settings(settings), seed=seed)
            params, se, conv, obj = res.params, res.se, res.converged, res.objective
        canon = model.canonical(np.asarray(params))
        np.testing.assert_array_equal(ds["estimate"].values[i], canon)
        assert bool(ds["converged"].values[i]) == bool(conv)
        np.testing.assert_array_equal(ds["objective"].values[i], obj)
        if np.array_equal(canon, params):  # SEs in the fit's order
            np.testing.assert_array_equal(ds["se"].values[i], se)


def test_cached_variances_do_not_depend_on_the_interval():
    x = np.random.default_rng(1).standard_normal(T).cumsum()
    assert STUDY_WV_CI == "eta3"
    np.testing.assert_array_equal(wvar(x, ci="eta3").variance, wvar(x).variance)


def test_fused_chunk_is_the_wv_of_the_fused_signal():
    from gmwm_studies.montecarlo import simulate_replicate
    from gmwm_studies.seeds import replicate_rng

    spec, truth = "WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1,
                                "RW[1].gamma2": 1e-5}
    kw = {"study": "cost", "base_seed": 3, "levels": 10}
    fused = simulate_wv_chunk(spec, truth, 50_000, [0, 4], simulator="fused", **kw)
    fast = simulate_wv_chunk(spec, truth, 50_000, [0, 4], simulator="fast", **kw)
    for name in ("levels", "scales", "n"):
        np.testing.assert_array_equal(getattr(fused, name), getattr(fast, name))
    model = Model(spec)
    for i, rep in enumerate([0, 4]):
        x = simulate_replicate(model, model.theta(truth), 50_000,
                               replicate_rng("cost", 50_000, rep, 3), "fused")
        np.testing.assert_array_equal(fused.variances[i], wvar(x, levels=10).variance)
    assert not np.array_equal(fused.variances, fast.variances)  # another stream
    assert np.all(fused.seconds_wv == 0) and np.all(fused.seconds_simulate > 0)
