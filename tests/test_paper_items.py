"""gmwm_studies.paper_items: Lemma 1's determinants, the STIM-300 and SVO items (issue 42)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gmwm.errors import InputError
from gmwm_studies import paper_items as pi

REPORTS = Path(__file__).resolve().parents[1] / "reports"


def test_jacobian_rows_follow_the_lemmas_formula_and_only_entry_11_differs():
    a = 2 * math.log(2) / math.pi
    for c in (1.0, 0.5):
        jp, jf = pi.jacobian_lemma1(1.5, c), pi.jacobian_lemma1(0.75, c)
        # the printed matrix's rows 2-5: 3/16, 1/4, a, 4/3, 8 ... as the formula
        assert jf[1] == pytest.approx(c * np.array([3 / 16, 1 / 4, a, 4 / 3, 8]))
        assert jf[4] == pytest.approx(c * np.array([3 / 1024, 1 / 32, a, 32 / 3, 512]))
        diff = jp != jf
        assert diff[0, 0] and diff.sum() == 1


def test_determinants_match_the_papers_closed_form_under_each_reading():
    lem = pi.lemma1()
    unit = math.log(2) / (1024 * math.pi)
    # the paper's printed 84357 is the determinant of the printed (typo) matrix
    assert lem["det_printed"] / unit == pytest.approx(84357, abs=1e-6)
    assert lem["det_formula"] / unit == pytest.approx(19845, abs=1e-6)
    assert lem["det_printed"] == pytest.approx(18.176, abs=1e-3)
    assert lem["det_formula"] == pytest.approx(4.2759, abs=1e-4)
    assert lem["det_formula_wv"] == pytest.approx(lem["det_formula"] / 32)


def _stim_table(path: Path, rise: bool) -> Path:
    rows = []
    for est in ("gmwm_cf", "armav", "armav_ols", "avsm"):
        for T, k in ((100, 1.0), (400, 0.5)):
            for param, sym in (("WN[1].sigma2", "N"), ("RW[1].gamma2", "K")):
                sd = k * (2.0 if est == "armav_ols" else 1.0)
                if rise and est == "armav" and sym == "K" and T == 400:
                    sd = 1.5  # the SD grows with T in one cell
                bias = {"gmwm_cf": -0.1, "armav": -0.2, "armav_ols": 0.05, "avsm": 1.0}[est] * k
                rows.append({"sensor": "gyroscope", "estimator": est, "n_samples": T,
                             "parameter": param, "symbol": sym, "bias": bias, "sd": sd, "rel_sd": sd,
                             "mc_se_bias": sd / 10,
                             "rmse": math.hypot(bias, sd)})
    pd.DataFrame(rows).to_csv(path, index=False)
    return path


def test_sample_size_counts_cells_where_sd_and_rmse_fall(tmp_path):
    items = pi.stim300_items({"gyro": _stim_table(tmp_path / "a.csv", False)}, None, (100, 400))
    ss = items["sample_size"]
    assert (ss["cells"], ss["sd_falls"], ss["rmse_falls"]) == (6, 6, 6)  # avsm not counted
    assert ss["abs_bias_falls"] == 6 and ss["abs_bias_grows_beyond_2se"] == 0
    items = pi.stim300_items({"gyro": _stim_table(tmp_path / "b.csv", True)}, None, (100, 400))
    ss = items["sample_size"]
    assert (ss["sd_falls"], ss["rmse_falls"], ss["both_fall"]) == (5, 5, 5)
    bias = items["bias"]
    assert bias["armav_larger"] == 4 and bias["armav_ols_larger"] == 0
    assert bias["gyro.K.T100"]["abs_bias_armav"] == pytest.approx(0.2)
    assert items["cor1"]["cells"] == 4 and items["fig1"]["cells"] == 4


def test_stim300_items_refuses_a_missing_cell_and_bad_lengths(tmp_path):
    path = _stim_table(tmp_path / "a.csv", False)
    with pytest.raises(InputError, match="0 rows"):
        pi.stim300_items({"gyro": path}, None, (100, 800))
    with pytest.raises(InputError, match="short, long"):
        pi.stim300_items({"gyro": path}, None, (400, 100))


def test_svo_theorems_z_of_the_mean_against_c0(tmp_path):
    cov = pd.DataFrame({"mbb": ["paper", "paper", "time", "time"], "gyro": [1, 2, 1, 2],
                        "c0": [0.5, 0.5, 0.5, 0.5], "mean_coef": [0.501, 0.499] * 2,
                        "sd_coef": [0.01, 0.01] * 2, "replicates": [100] * 4})
    coefs = pd.DataFrame({"method": ["svo_w1", "svo_w1", "equal", "equal"], "gyro": [1, 2, 1, 2],
                          "mean": [0.52, 0.48, 0.5, 0.5], "sd": [0.1, 0.1, 1e-17, 1e-17],
                          "true": [0.5, 0.5, 0.5, 0.5]})
    cov.to_csv(tmp_path / "cov.csv", index=False)
    coefs.to_csv(tmp_path / "coef.csv", index=False)
    th = pi.svo_theorems(tmp_path / "cov.csv", tmp_path / "coef.csv", 25)
    assert th["replications"]["max_abs_z"] == pytest.approx(1.0)  # 0.001 / (0.01 / 10)
    assert th["arrays"]["svo_w1"]["max_abs_z"] == pytest.approx(1.0)  # 0.02 / (0.1 / 5)
    assert "equal" not in th["arrays"]


def test_committed_items_are_what_the_committed_tables_give():
    # the JSON REPRODUCTION.md links must be the computation over the tables beside it
    path = REPORTS / "paper_items" / "paper_items.json"
    if not (REPORTS / "stim300_gyro" / "replicates").is_dir() or not path.is_file():
        pytest.skip("committed STIM-300 / paper_items reports absent")
    got = pi.compute_items(
        {s: REPORTS / "stim300" / f"stim300_{s}_bias_sd_rmse.csv" for s in ("gyro", "accel")},
        {(sensor, T): REPORTS / f"stim300_{s}" / "replicates" / f"estimates_T{T}.csv"
         for s, sensor in (("gyro", "gyroscope"), ("accel", "accelerometer"))
         for T in pi.LONG_SHORT},
        REPORTS / "svo" / "case1" / "coverage.csv", REPORTS / "svo" / "case1" / "coefficients.csv",
        50)
    committed = json.loads(path.read_text(encoding="utf-8"))
    assert _close(json.loads(json.dumps(got)), committed)


def _close(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-300)
    return a == b


def test_paired_bias_difference_on_the_same_replicates(tmp_path):
    from gmwm_studies.replicates import write_replicates
    rng = np.random.default_rng(7)
    n, truth = 200, 1e-3
    g = truth * (1 + 0.05 * rng.standard_normal(n))
    rows = [{"replicate": i, "estimator": e, "T": 1000, "J": 8, "WN[1].sigma2": v, "converged": 1,
             "at_boundary": ""} for e, vals in (("gmwm_cf", g), ("armav", g * 1.01))
            for i, v in enumerate(vals)]
    rows[-1]["converged"] = 0  # a failed ARMAV fit drops that replicate from the pairs
    csv = tmp_path / "estimates_T1000.csv"
    write_replicates(pd.DataFrame(rows), {"truth": {"WN[1].sigma2": truth}, "freq": 100.0},
                     csv, tmp_path / "truth_T1000.json")
    got = pi._paired_bias({("gyroscope", 1000): csv}, "gyroscope", 1000, "WN[1].sigma2", "armav")
    assert got["n_paired"] == n - 1
    # the ARMAV's estimates are 1 % above the GMWM's on every replicate: a positive difference,
    # far beyond its paired SE (the spread of 1 % of a 5 %-noisy estimate)
    assert got["bias_diff"] > 0 and got["bias_diff"] / got["mc_se_diff"] > 50
