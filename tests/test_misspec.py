"""Misspecification study ([Vibration], Table 5, Fig. 6): nested fits on cached WVs, table, figure."""

from __future__ import annotations

import numpy as np
import pytest

from gmwm.errors import ModelError
from gmwm_studies import misspec as ms
from gmwm_studies import montecarlo as gs

SETTINGS = {"method": "gmwm", "weights": "ci", "n_starts": 2, "reweight": 0}
FITS = {"model1": "AR1+RW", "model2": "AR1+RW+2*SIN"}

pytestmark = pytest.mark.slow  # every test uses `fits`: 8 replicates x 2 models at T = 2**17


@pytest.fixture(scope="module")
def fits():
    # T = 2**17 (J = 16): the RW (gamma2 = 8.7e-10) is raised x 64 so that it dominates the top
    # levels as at the paper's T = 2.9e6; AR1 and SINs keep Table 5 values.
    truth = {**ms.TABLE5, "RW[1].gamma2": 64 * ms.TABLE5["RW[1].gamma2"]}
    chunk = gs.simulate_wv_chunk("AR1+RW+2*SIN", truth, 2**17, range(8), study="misspec_test",
                                 base_seed=11)
    return {k: ms.fit_model_chunk(chunk, spec, k, SETTINGS) for k, spec in FITS.items()}


def test_true_model_recovers_table5_basic_parameters(fits):
    tab = ms.misspec_table(fits).set_index(["model", "parameter"])
    for name in ("AR1[1].phi", "AR1[1].sigma2", "SIN[1].alpha", "SIN[1].beta",
                 "SIN[2].alpha", "SIN[2].beta"):
        row = tab.loc[("model2", name)]
        # bias within 4 Monte Carlo SEs (8 replicates) and below 10 % of the truth
        assert abs(row["bias"]) <= 4 * row["mc_se_bias"] + 1e-12, name
        assert abs(row["rel_bias"]) < 0.1, name
    assert tab.loc[("model2", "AR1[1].phi"), "share_not_converged"] == 0.0


def test_misspecified_model_is_biased_on_the_ar1(fits):
    tab = ms.misspec_table(fits, ms.BASIC_PARAMS).set_index(["model", "parameter"])
    assert set(tab.index.get_level_values("parameter")) == set(ms.BASIC_PARAMS)
    # Model 1 puts the fast sinusoid's power (alpha1^2 / 2 = 0.052) into the AR1 innovation
    s1 = tab.loc[("model1", "AR1[1].sigma2")]
    assert s1["rel_bias"] > 0.5 and abs(s1["std_bias"]) > 5
    assert s1["rmse_ratio"] > 10
    assert s1["sd_ratio"] == pytest.approx(s1["sd"] / tab.loc[("model2", "AR1[1].sigma2"), "sd"])
    assert tab.loc[("model2", "AR1[1].phi"), "sd_ratio"] == pytest.approx(1.0)


def test_nested_check_and_figure(fits):
    with pytest.raises(ModelError, match="lacks"):
        ms.restrict_truth(ms.TABLE5, "AR1+RW+WN")
    fig = ms.plot_fig6(fits, labels={"model1": "Model 1", "model2": "Model 2"})
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == [r"$\phi$", r"$\varsigma^2$", r"$\gamma^2$"]
    assert np.isclose(fig.axes[0].lines[-1].get_ydata()[0], ms.TABLE5["AR1[1].phi"])
