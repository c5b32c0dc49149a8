"""Virtual gyroscope (gmwm.virtual, exported as gmwm.svo): WCCV, SVO estimator, MBB covariance, RDVG; docs/METHODS.md §11.6 values."""

import json

import numpy as np
import pytest

import gmwm
from gmwm.errors import InputError, ModelError
from gmwm.virtual import (
    PAPER_OMEGA_LONG,
    PAPER_OMEGA_SHORT,
    _mbb_kernel,
    _mbb_time_kernel,
    equal,
    mbb_svo_draws,
    mbb_wccv,
    rdvg,
    svo,
    svo_coef,
    svo_jacobian,
    svo_weights,
)
from gmwm.wccv import unpack, wccv
from gmwm_studies.svo_study import case, true_coefs


def _naive_wccv(X: np.ndarray, J: int) -> np.ndarray:
    """Partial-sum form of docs/METHODS.md §2.1 on demeaned data (fine for short, offset-free signals)."""
    T, p = X.shape
    S = np.vstack([np.zeros(p), np.cumsum(X - X.mean(axis=0), axis=0)])
    out = []
    for j in range(1, J + 1):
        tau, m = 2**j, 2 ** (j - 1)
        W = (S[tau:] - 2 * S[tau - m:T + 1 - m] + S[:T + 1 - tau]) / tau
        out.append(W.T @ W / W.shape[0])
    return np.array(out)


def _array(T: int, p: int, rng: np.random.Generator) -> np.ndarray:
    mix = np.eye(p) + 0.3 * rng.standard_normal((p, p))
    return rng.standard_normal((T, p)) @ mix + np.cumsum(0.05 * rng.standard_normal((T, p)), axis=0)


# --- wavelet cross-covariance ---------------------------------------------------------------------
@pytest.mark.parametrize("T,J", [(4, 1), (5, 2), (17, 4), (1000, 8), (4097, 12), (10001, 12),
                                 (20000, 13)])
def test_wccv_matches_partial_sums(T, J):
    # T >= 2**13 with J >= 12 exercises phase 2 (interleaved sub-series) of the fused kernel
    X = _array(T, 3, np.random.default_rng(T))
    got = wccv(X, J).cov
    ref = _naive_wccv(X, J)
    scale = np.abs(ref).max(axis=(1, 2))[:, None, None]
    assert np.max(np.abs(got - ref) / scale) < 1e-10


def test_wccv_diagonal_is_wvar_and_combine_is_wvar_of_virtual_signal():
    rng = np.random.default_rng(3)
    X = _array(30000, 4, rng)
    W = wccv(X)
    for i in range(4):
        np.testing.assert_allclose(W.variance(i).variance, gmwm.wvar(X[:, i]).variance,
                                   rtol=1e-12)
    c = np.array([0.5, 0.2, 0.4, -0.1])
    virt = W.combine(c)
    ref = gmwm.wvar(X @ c)
    np.testing.assert_allclose(virt.variance, ref.variance, rtol=1e-10)
    np.testing.assert_allclose(virt.ci_low, ref.ci_low, rtol=1e-10)


def test_wccv_exact_under_large_offsets():
    rng = np.random.default_rng(4)
    X = _array(50000, 3, rng)
    ref = wccv(X).cov
    got = wccv(X + np.array([1e6, -3e6, 5e5])).cov
    assert np.max(np.abs(got - ref) / np.abs(ref).max(axis=(1, 2))[:, None, None]) < 1e-9


def test_wccv_unbiased_and_ci_coverage_against_theory():
    """Case-1 type array (correlated RW), p = 3: mean over 300 replicates within 4 MC SE of the
    true A_j at every level and pair; off-diagonal Gaussian CIs cover at least 90 %."""
    rng = np.random.default_rng(5)
    R = np.diag([2.0, 1.0, 1.5])
    Q = np.array([[1.0, 0.5, -0.3], [0.5, 2.0, 0.2], [-0.3, 0.2, 1.0]]) * 1e-3
    T, J, n = 4096, 9, 300
    tau = 2.0 ** np.arange(1, J + 1)
    A = R[None] / tau[:, None, None] + Q[None] * ((tau**2 + 2) / (12 * tau))[:, None, None]
    LQ = np.linalg.cholesky(Q)
    est, hit = [], []
    for _ in range(n):
        X = rng.standard_normal((T, 3)) * np.sqrt(np.diag(R))
        X += np.cumsum(rng.standard_normal((T, 3)) @ LQ.T, axis=0)
        W = wccv(X, J)
        ci = W.conf_int()
        lo, hi = ci[..., 0], ci[..., 1]
        est.append(W.cov)
        hit.append((lo <= A) & (A <= hi))
    est = np.array(est)
    z = (est.mean(axis=0) - A) / (est.std(axis=0, ddof=1) / np.sqrt(n))
    assert np.max(np.abs(z)) < 4.0
    off = ~np.eye(3, dtype=bool)
    cover = np.mean(hit, axis=0)[:, off]
    assert cover.min() >= 0.90, cover.min()


def test_wccv_input_errors():
    with pytest.raises(InputError, match="2-D"):
        wccv(np.zeros(100))
    with pytest.raises(InputError, match="at least 2"):
        wccv(np.zeros((100, 1)))
    X = np.random.default_rng(0).standard_normal((100, 3))
    X[7, 2] = np.nan
    with pytest.raises(InputError, match="sample 7, column 2"):
        wccv(X)
    with pytest.raises(InputError, match="more signals than samples"):
        wccv(np.zeros((3, 6)))
    with pytest.raises(InputError, match="levels"):
        wccv(np.ones((100, 2)), levels=9)


# --- docs/METHODS.md §11.6 reference values --------------------------------------------------------------------
def test_true_coefficients_match_spec_6_4():
    c1, c2 = true_coefs("case1"), true_coefs("case2")
    ref = {
        ("case1", "svo_w1"): [0.5497, 0.1255, -0.0119, -0.0007, 0.3455, -0.0081],
        ("case1", "svo_w2"): [0.0922, 0.1308, 0.1900, 0.2431, 0.2419, 0.1019],
        ("case1", "rdvg"): [0.5600, 0.1196, -0.0145, -0.0039, 0.3480, -0.0092],
        ("case2", "svo_w1"): [0.0437, 0.2669, 0.0786, 0.5103, 0.1114, -0.0108],
        ("case2", "svo_w2"): [0.0929, 0.1316, 0.1898, 0.2432, 0.2408, 0.1017],
    }
    for (name, method), values in ref.items():
        got = (c1 if name == "case1" else c2)[method]
        np.testing.assert_array_equal(np.round(got, 4), values, err_msg=f"{name} {method}")
        assert got.sum() == pytest.approx(1.0, abs=1e-12)


def test_true_wv_ratios_match_spec_6_4():
    A = case("case1").wccv(2.0 ** np.arange(1, 20))
    c = true_coefs("case1")
    nu = {k: np.einsum("i,jik,k->j", v, A, v) for k, v in c.items()}
    r1 = (nu["svo_w1"] / nu["equal"])[[0, 9, 18]]
    r2 = (nu["svo_w2"] / nu["equal"])[[0, 9, 18]]
    np.testing.assert_array_equal(np.round(r1, 2), [3.35, 3.14, 0.24])
    assert round(r1[2], 3) == 0.235
    np.testing.assert_array_equal(np.round(r2, 2), [0.86, 0.88, 1.15])


# --- SVO estimator --------------------------------------------------------------------------------
def test_svo_weights_presets():
    np.testing.assert_allclose(svo_weights("long", 19), np.array(PAPER_OMEGA_LONG) / 0.998)
    np.testing.assert_allclose(svo_weights("short", 19), np.array(PAPER_OMEGA_SHORT) / 1.002)
    short16 = svo_weights("short", 16)
    np.testing.assert_allclose(short16 * sum(PAPER_OMEGA_SHORT[:16]), PAPER_OMEGA_SHORT[:16])
    long21 = svo_weights("long", 21)
    assert long21[:9].sum() == 0 and long21[-1] == long21.max()
    assert svo_weights([0, 2, 2], 3).tolist() == [0, 0.5, 0.5]
    for bad, msg in (([1, 2], "3 levels"), ([1, -1, 1], "non-negative"), ([0, 0, 0], "no mass"),
                     ("medium", "unknown weights")):
        with pytest.raises(InputError, match=msg):
            svo_weights(bad, 3)


def test_svo_solution_minimises_weighted_variance():
    rng = np.random.default_rng(6)
    W = wccv(_array(8192, 4, rng))
    om = svo_weights("short", W.n_levels)
    c = svo_coef(W.cov, om)
    A = np.einsum("j,jik->ik", om, W.cov)
    best = c @ A @ c
    for _ in range(50):
        d = rng.standard_normal(4)
        d -= d.mean()                      # stay on c'1 = 1
        v = c + 0.05 * d
        assert v @ A @ v > best
    assert c.sum() == pytest.approx(1.0)


def test_svo_recovers_c0_on_case1_arrays():
    """Case 1 at T = 2**17 (J = 16, omega_2 anchored at level 1): mean of 4 arrays within
    4 SE (SE from the replicates' spread) of c0 computed from the true WCCV."""
    cs = case("case1")
    T, J = 2**17, 16
    om = svo_weights("short", J)
    c0 = svo_coef(cs.wccv(2.0 ** np.arange(1, J + 1)), om)
    est = np.array([svo(cs.simulate(T, np.random.default_rng(100 + r)), om, n_boot=0).coef
                    for r in range(4)])
    se = est.std(axis=0, ddof=1) / 2
    assert np.all(np.abs(est.mean(axis=0) - c0) < 4 * se + 1e-4)
    assert np.max(np.abs(est - c0)) < 0.01


def test_jacobian_matches_finite_differences():
    W = wccv(_array(4096, 3, np.random.default_rng(7)))
    om = svo_weights("equal", W.n_levels)
    G = svo_jacobian(W.cov, om)

    def coef(C):
        y = np.linalg.solve(np.einsum("j,jik->ik", om, C), np.ones(3))
        return y / y.sum()

    for j, i, k in [(0, 0, 0), (3, 0, 2), (5, 2, 1)]:
        C = W.cov.copy()
        h = 1e-6 * W.cov[j, i, i]
        C[j, i, k] += h
        np.testing.assert_allclose((coef(C) - coef(W.cov)) / h, G[:, j, i, k], rtol=1e-4,
                                   atol=1e-6 * np.abs(G[:, j, i, k]).max())


def test_collinear_signals_raise_model_error():
    x = _array(2048, 2, np.random.default_rng(8))
    X = np.column_stack([x, x[:, 0]])
    with pytest.raises(ModelError, match="collinear"):
        svo(X, "equal", n_boot=0)


# --- moving-block bootstrap -----------------------------------------------------------------------
def test_mbb_identity_draw_reproduces_estimate():
    """Blocks tiling the trimmed times in order and refill stretches starting at 0 give back
    exactly the original coefficients, hence gamma_hat."""
    T, p, J, block = 3001, 3, 10, 7
    X = _array(T, p, np.random.default_rng(9))
    MJ = T - 2**J + 1
    B = -(-MJ // block)
    starts = (np.arange(B) * block)[None].astype(np.int64)
    out = np.zeros((1, J * p * (p + 1) // 2))
    n = T - (1 << np.arange(1, J + 1)) + 1
    _mbb_kernel(X, J, True, np.zeros(p), 1.0 / n, starts, block, MJ - (B - 1) * block,
                np.zeros((1, J), np.int64), out)
    got = unpack(out.reshape(1, J, -1), p)[0]
    ref = wccv(X, J).cov
    assert np.max(np.abs(got - ref)) < 1e-13 * np.abs(ref).max()


def test_projected_draws_equal_jacobian_times_full_draws():
    X = _array(3000, 3, np.random.default_rng(10))
    W = wccv(X, 10)
    om = svo_weights("short", 10)
    full = mbb_wccv(X, 10, n_boot=40, block=20, rng=5)
    dfull = np.einsum("ajik,hjik->ha", svo_jacobian(W.cov, om), full - W.cov)
    dproj = mbb_svo_draws(X, W.cov, om, 40, 20, np.random.default_rng(5))
    assert np.max(np.abs(dfull - dproj)) < 1e-10 * np.abs(dfull).max()


def test_time_scheme_identity_draw_and_projection():
    """Time-axis MBB: blocks tiling 0..T-1 in order give back gamma_hat; the projected draws equal
    G times the full draws; an unknown scheme is an input error."""
    T, p, J, block = 3001, 3, 10, 7
    X = _array(T, p, np.random.default_rng(15))
    B = -(-T // block)
    starts = (np.arange(B) * block)[None].astype(np.int64)
    sums = np.zeros((1, J, p * (p + 1) // 2))
    counts = np.zeros((1, J), np.int64)
    _mbb_time_kernel(X, J, True, np.zeros(p), starts, block, T - (B - 1) * block, sums, counts)
    ref = wccv(X, J)
    np.testing.assert_array_equal(counts[0], ref.n)
    got = unpack(sums[0] / counts[0][:, None], p)
    assert np.max(np.abs(got - ref.cov)) < 1e-13 * np.abs(ref.cov).max()
    om = svo_weights("long", J)
    full = mbb_wccv(X, J, n_boot=30, block=25, rng=3, scheme="time")
    dfull = np.einsum("ajik,hjik->ha", svo_jacobian(ref.cov, om), full - ref.cov)
    dproj = mbb_svo_draws(X, ref.cov, om, 30, 25, np.random.default_rng(3), "time")
    assert np.max(np.abs(dfull - dproj)) < 1e-10 * np.abs(dfull).max()
    with pytest.raises(InputError, match="unknown MBB scheme"):
        svo(X, "short", levels=J, n_boot=10, mbb="other")


def test_mbb_se_close_to_empirical_sd():
    """p = 3 signals (WN + correlated AR1, phi = 0.9), T = 2**14, J = 8 (refill stretches are
    short, D_j <= 256), blocks of 20 T^(1/3) = 508 samples (~2 x the largest scale): mean MBB SE
    within [0.8, 1.25] x the SD of c_hat over 150 arrays (measured 0.91-1.00; blocks of 76 give
    0.75-0.83: blocks must be long against the weighted scales)."""
    rng = np.random.default_rng(11)
    T, J, n = 2**14, 8, 150
    L = np.linalg.cholesky(np.array([[1.0, 0.4, 0.1], [0.4, 1.0, -0.2], [0.1, -0.2, 1.0]]))
    from scipy.signal import lfilter
    coefs, ses = [], []
    for r in range(n):
        X = rng.standard_normal((T, 3)) * np.array([1.0, 2.0, 1.5])
        X += lfilter([1.0], [1.0, -0.9], rng.standard_normal((T, 3)) @ L.T, axis=0)
        res = svo(X, "equal", levels=J, n_boot=200, block_const=20.0, seed=r)
        coefs.append(res.coef)
        ses.append(res.se)
    ratio = np.mean(ses, axis=0) / np.std(coefs, axis=0, ddof=1)
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


# --- result object and RDVG -----------------------------------------------------------------------
def test_normal_quantile_is_scipy_stats_norm_ppf_bit_for_bit():
    """virtual, wccv and svo_study take z_{1-alpha/2} from scipy.special.ndtri (scipy.stats is
    ~0.5 s of import): the same numbers as norm.ppf on a grid of levels, and so the same
    intervals as before."""
    from scipy.special import ndtri
    from scipy.stats import norm

    q = np.concatenate([1.0 - np.geomspace(1e-12, 0.5, 400) / 2.0, np.linspace(0.5, 1.0, 401)[1:-1],
                        [0.975, 0.995, 0.95, 0.9, 0.5 + 0.9 / 2.0]])
    np.testing.assert_array_equal(ndtri(q), norm.ppf(q))
    X = _array(2000, 3, np.random.default_rng(3))
    res = svo(X, "equal", levels=6, n_boot=20, seed=1)
    for alpha in (0.01, 0.05, 0.1, 0.3):
        h = norm.ppf(1.0 - alpha / 2.0) * res.se
        np.testing.assert_array_equal(res.conf_int(alpha), np.column_stack([res.coef - h,
                                                                            res.coef + h]))


def test_result_api():
    X = _array(5000, 3, np.random.default_rng(12))
    res = gmwm.svo(X, weights="short", n_boot=50, names=["a", "b", "c"], freq=10.0)
    assert res.coef.shape == (3,) and res.se.shape == (3,) and np.all(res.se > 0)
    ci = res.conf_int(0.1)
    assert ci.shape == (3, 2) and np.all(ci[:, 0] < res.coef) and np.all(res.coef < ci[:, 1])
    assert np.all(res.conf_int(0.01)[:, 1] > ci[:, 1])
    wv = res.wv()
    assert wv.freq == 10.0 and wv.n_levels == res.wccv.n_levels
    s = res.summary()
    assert "a" in s and "95% CI" in s and "WV ratio" in s
    json.dumps(res.to_json_dict(), allow_nan=False)
    again = gmwm.svo(X, weights="short", n_boot=50, names=["a", "b", "c"], freq=10.0)
    np.testing.assert_array_equal(again.cov, res.cov)   # seeded
    no_ci = svo(res.wccv, "short")
    np.testing.assert_allclose(no_ci.coef, res.coef)
    assert np.all(np.isnan(no_ci.se))
    eq = equal(X)
    np.testing.assert_allclose(eq.coef, 1 / 3)


def _check_protocol(res, n_params: int) -> None:
    """The library's result protocol: params / param_names / se / conf_int / summary /
    to_json_dict, immutable with read-only arrays."""
    import dataclasses

    params, se = res.params, res.se
    assert params.shape == (n_params,) and se.shape == (n_params,)
    assert isinstance(res.param_names, list) and len(res.param_names) == n_params
    assert all(isinstance(n, str) for n in res.param_names)
    ci = res.conf_int()
    assert isinstance(ci, np.ndarray) and ci.shape == (n_params, 2)
    assert res.conf_int(alpha=0.05).shape == (n_params, 2)
    assert np.array_equal(np.isnan(ci).any(axis=1), np.isnan(se))
    assert isinstance(res.summary(), str) and res.summary()
    d = res.to_json_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    with pytest.raises(ValueError, match="read-only"):
        params[0] = 1.0
    field = dataclasses.fields(res)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(res, field, None)


def test_svo_result_protocol():
    X = _array(4096, 3, np.random.default_rng(15))
    boot = svo(X, n_boot=20, names=["a", "b", "c"])
    _check_protocol(boot, 3)
    assert boot.param_names == ["a", "b", "c"]
    np.testing.assert_array_equal(boot.params, boot.coef)
    assert np.all(np.isfinite(boot.conf_int()))
    assert np.all(boot.conf_int(0.01)[:, 1] > boot.conf_int(0.1)[:, 1])
    with pytest.raises(ValueError, match="read-only"):
        boot.cov[0, 0] = 0.0
    for res in (equal(X), rdvg(X)):             # no bootstrap: se and intervals NaN, JSON null
        _check_protocol(res, 3)
        assert np.all(np.isnan(res.conf_int())) and res.to_json_dict()["se"] == [None] * 3
    with pytest.raises(ValueError, match="read-only"):
        rdvg(X).extra["Q"][0, 0] = 0.0
    # the WCCV's intervals end in a (low, high) axis as well
    ci = boot.wccv.conf_int()
    assert ci.shape == (*boot.wccv.cov.shape, 2) and np.all(ci[..., 0] < ci[..., 1])


def test_rdvg_recovers_q_based_coefficients():
    """RW-dominated Case 1 (Q x 1e4) at T = 2**16: RDVG within 0.03 of Q^-1 1 / (1'Q^-1 1)."""
    cs = case("case1")
    Q = cs.rw * 1e4
    rng = np.random.default_rng(13)
    X = rng.standard_normal((2**16, 6)) * np.sqrt(np.diag(cs.R))
    X += np.cumsum(rng.standard_normal((2**16, 6)) @ np.linalg.cholesky(Q).T, axis=0)
    res = rdvg(X)
    y = np.linalg.solve(Q, np.ones(6))
    assert np.max(np.abs(res.coef - y / y.sum())) < 0.03
    assert res.extra["q_positive_definite"]


# --- CLI ------------------------------------------------------------------------------------------
def test_cli_svo(tmp_path, capsys):
    from gmwm.cli import main

    X = _array(4096, 3, np.random.default_rng(14))
    path = tmp_path / "arr.npy"
    np.save(path, X)
    out_csv = tmp_path / "v.csv"
    assert main(["svo", str(path), "--columns", "0,1,2", "--freq", "10", "--n-boot", "20",
                 "-o", str(out_csv), "--plot", str(tmp_path / "v.png"), "-q"]) == 0
    text = capsys.readouterr().out
    assert "95% CI" in text and (tmp_path / "v.png").stat().st_size > 0
    table = np.genfromtxt(out_csv, delimiter=",", names=True)
    np.testing.assert_allclose(table["variance"],
                               svo(X, "short", freq=10.0, n_boot=0).wv().variance, rtol=1e-12)
    for argv, msg in ((["--columns", "0", ], "at least 2"),
                      (["--columns", "0,1", "--weights", "nope"], "not 'short', 'long'"),
                      (["--columns", "0,1", "-o", str(tmp_path / "x.txt")], "use a .csv")):
        code = main(["svo", str(path), *argv, "-q"])
        err = capsys.readouterr().err
        assert code != 0 and msg in err and "Traceback" not in err and err.count("\n") == 1


# --- study helpers --------------------------------------------------------------------------------
def test_study_chunks_merge_and_wilson():
    """Coverage chunks merge to the same numbers in any order; Wilson interval of 19/20 is
    (0.7639, 0.9911) (textbook value)."""
    from gmwm_studies.svo_study import coverage_chunk, coverage_table, merge, wilson

    lo, hi = wilson(19, 20)
    assert (round(lo, 4), round(hi, 4)) == (0.7639, 0.9911)
    args = ("case1", 2**12, 10, 20, 5.0, 0.05, 3, ("paper", "time"))
    a = coverage_chunk(args[0], [0, 1], *args[1:])
    b = coverage_chunk(args[0], [2], *args[1:])
    ab = coverage_chunk(args[0], [0, 1, 2], *args[1:])
    for m in (merge([a, b]), merge([b, a])):
        order = np.argsort(m["replicates"])
        np.testing.assert_allclose(m["coef"][order], ab["coef"])
        np.testing.assert_allclose(m["se"][:, order], ab["se"])
    rows = coverage_table(merge([a, b]))
    assert len(rows) == 12 and {r["mbb"] for r in rows} == {"paper", "time"}


def test_coverage_with_the_paper_scheme_only():
    """The full profile runs the paper's MBB alone: its SEs are those of the two-scheme run bit for
    bit (each scheme has its own draw stream), and the table and figure hold that scheme only."""
    import matplotlib.pyplot as plt

    from gmwm_studies.svo_study import (
        coverage_chunk,
        coverage_replicate_table,
        coverage_table,
        figure_coverage,
    )

    args = ("case1", [0, 1], 2**12, 10, 20, 5.0, 0.05, 3)
    both = coverage_chunk(*args, ("paper", "time"))
    paper = coverage_chunk(*args, ("paper",))
    assert paper["se"].shape == (1, 2, 6) and list(paper["schemes"]) == ["paper"]
    np.testing.assert_array_equal(paper["se"][0], both["se"][0])
    np.testing.assert_array_equal(paper["coef"], both["coef"])
    rows = coverage_table(paper)
    assert len(rows) == 6 and {r["mbb"] for r in rows} == {"paper"}
    per_rep = coverage_replicate_table(paper, 0.05)
    assert len(per_rep) == 12 and {r["mbb"] for r in per_rep} == {"paper"}
    assert all(np.isfinite(r["coverage"]) and np.isfinite(r["mean_se"]) for r in rows)
    fig = figure_coverage(rows)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert [x for x in labels if x.startswith("MBB")] == [
        "MBB paper, n = 2: coverage (Wilson 95 %)"]
    plt.close(fig)


def test_capped_time_scheme_leaves_the_paper_numbers_bit_for_bit():
    """scheme_replicates {time: 2}: the paper scheme's arrays equal those of a paper-only run bit
    for bit (merged across chunks too); time cells exist for r < 2 only (NaN, not counted, no
    replicate rows beyond), its table rows over its own 2 replications, both drawn with their n."""
    import matplotlib.pyplot as plt

    from gmwm_studies.svo_study import (
        coverage_chunk,
        coverage_replicate_table,
        coverage_table,
        figure_coverage,
        merge,
    )

    args = ("case1", 2**12, 10, 20, 5.0, 0.05, 3)
    caps = {"time": 2}
    chunks = ([3], [0, 1, 2])  # merged out of order, as chunk files may come
    capped = merge([coverage_chunk(args[0], c, *args[1:], ("paper", "time"), caps)
                    for c in chunks])
    paper = merge([coverage_chunk(args[0], c, *args[1:], ("paper",)) for c in chunks])
    order = np.argsort(capped["replicates"])
    both = coverage_chunk(args[0], [0, 1], *args[1:], ("paper", "time"))
    for k in ("se", "hit"):
        np.testing.assert_array_equal(capped[k][0], paper[k][0])
    np.testing.assert_array_equal(capped["coef"], paper["coef"])
    time_se = capped["se"][1][order]
    assert np.isfinite(time_se[:2]).all() and np.isnan(time_se[2:]).all()
    assert np.isnan(capped["hit"][1][order][2:]).all()
    np.testing.assert_array_equal(time_se[:2], both["se"][1])  # = the uncapped time SEs
    rows = coverage_table(capped)
    ref = coverage_table(paper)
    assert [r for r in rows if r["mbb"] == "paper"] == ref
    t = [r for r in rows if r["mbb"] == "time"]
    assert len(t) == 6 and {r["replicates"] for r in t} == {2}
    c = paper["coef"][order][:2]
    np.testing.assert_allclose([r["sd_coef"] for r in t], c.std(axis=0, ddof=1), rtol=1e-12)
    np.testing.assert_allclose([r["mean_se"] for r in t], both["se"][1].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose([r["coverage"] for r in t], both["hit"][1].mean(axis=0))
    per_rep = coverage_replicate_table(capped, 0.05)
    assert sorted({(r["mbb"], r["replicate"]) for r in per_rep}) == [
        ("paper", 0), ("paper", 1), ("paper", 2), ("paper", 3), ("time", 0), ("time", 1)]
    fig = figure_coverage(rows)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert [x for x in labels if x.startswith("MBB")] == [
        "MBB paper, n = 4: coverage (Wilson 95 %)", "MBB time, n = 2: coverage (Wilson 95 %)"]
    assert [x for x in labels if x.startswith("MC band")] == [
        "MC band at 0.95 (n = 4)", "MC band at 0.95 (n = 2)"]
    plt.close(fig)


@pytest.mark.parametrize("caps", [{"rdvg": 2}, {"time": 0}, {"time": 2.5}, {"time": True}])
def test_scheme_caps_refuse_bad_entries(caps):
    from gmwm_studies.svo_study import scheme_caps

    with pytest.raises(InputError, match="scheme_replicates"):
        scheme_caps(caps, ("paper", "time"))


def test_svo_reuses_a_given_wccv_bit_for_bit():
    # coverage runs both MBB schemes on one array: the WCCV of the first fit is passed to the
    # second; the result must be the one computed from scratch
    X = case("case1").simulate(2**14, np.random.default_rng(5))
    first = svo(X, "short", levels=10, n_boot=50, seed=1, mbb="paper")
    again = svo(X, "short", levels=10, n_boot=50, seed=2, mbb="time")
    reuse = svo(X, "short", levels=10, n_boot=50, seed=2, mbb="time", wccv_of_x=first.wccv)
    assert np.array_equal(again.coef, reuse.coef)
    assert np.array_equal(again.cov, reuse.cov)
    with pytest.raises(InputError, match="wccv_of_x"):
        svo(X[:-8], "short", levels=10, n_boot=50, wccv_of_x=first.wccv)


def test_svo_schemes_equal_separate_fits_bit_for_bit():
    # the coverage study fits both MBB schemes in one pass over the array: each result must be
    # the separate svo() fit with the same seed, bit for bit (also with a repeated scheme)
    from gmwm.virtual import _run_mbb, _run_mbb_schemes, svo_schemes

    X = case("case1").simulate(2**14, np.random.default_rng(6))
    kw = {"levels": 10, "n_boot": 40, "block": 37}
    plan = [(3, "paper"), (4, "time"), (3, "paper")]
    fits = svo_schemes(X, "short", seeds=[s for s, _ in plan], mbb=[m for _, m in plan], **kw)
    for fit, (seed, m) in zip(fits, plan, strict=True):
        one = svo(X, "short", seed=seed, mbb=m, **kw)
        assert np.array_equal(fit.coef, one.coef) and np.array_equal(fit.cov, one.cov)
        assert fit.extra == {"mbb": m}
    assert not np.array_equal(fits[0].cov, fits[1].cov)
    J = 8
    wf = 1.0 / (X.shape[0] - 2.0 ** np.arange(1, J + 1) + 1)
    both = _run_mbb_schemes(X, J, True, np.zeros(6), wf, 15, 50,
                            [("time", np.random.default_rng(1)), ("paper", np.random.default_rng(2))])
    for got, (m, seed) in zip(both, [("time", 1), ("paper", 2)], strict=True):
        ref = _run_mbb(X, J, True, np.zeros(6), wf, 15, 50, np.random.default_rng(seed), m)
        assert np.array_equal(got, ref)
    with pytest.raises(InputError, match="one seed per MBB scheme"):
        svo_schemes(X, "short", seeds=[1], mbb=["paper", "time"], **kw)


def test_simulate_recursions_match_numpy_and_lfilter_bit_for_bit():
    # Case.simulate adds its random walk and AR1 components with Numba loops; they must give the
    # arrays of X += cumsum(...) and X += lfilter(...) (the original formulation) exactly
    import math

    from scipy.linalg import cholesky
    from scipy.signal import lfilter

    for name in ("case1", "case2"):
        cs = case(name)
        T, p = 3000, cs.p
        got = cs.simulate(T, np.random.default_rng(11))
        rng = np.random.default_rng(11)
        X = rng.standard_normal((T, p)) * np.sqrt(np.diag(cs.R))[None]
        if cs.rw is not None:
            X += np.cumsum(rng.standard_normal((T, p)) @ cholesky(cs.rw), axis=0)
        for phi, P in cs.ar1:
            L = cholesky(P)
            eta = rng.standard_normal((T, p)) @ L
            b0 = (rng.standard_normal(p) @ L) / math.sqrt(1.0 - phi * phi)
            X += lfilter([1.0], [1.0, -phi], eta, axis=0, zi=(phi * b0)[None, :])[0]
        assert np.array_equal(got, X), name


def test_input_correlation_figures_data():
    """[SVO] Figs 1 and 6: |corr| of Q (Case 1) and P_1..P_3 (Case 2) from App. C; the
    diagonals are the values printed in the text (eq. (12), Sec. V-B p_i)."""
    from gmwm_studies.svo_study import (
        INPUT_MATRICES,
        abs_correlation,
        figure_inputs,
        input_table,
    )

    assert list(INPUT_MATRICES["case1"]) == ["Q"]
    assert list(INPUT_MATRICES["case2"]) == ["P1", "P2", "P3"]
    np.testing.assert_allclose(np.diag(INPUT_MATRICES["case1"]["Q"]),
                               np.array([0.255, 0.472, 3.489, 2.092, 0.555, 2.501]) * 1e-13,
                               atol=6e-17)
    np.testing.assert_allclose(np.diag(INPUT_MATRICES["case2"]["P1"]),
                               np.array([0.401, 1.178, 1.966, 1.310, 1.928, 1.434]) * 1e-11,
                               atol=6e-15)
    r = abs_correlation(INPUT_MATRICES["case1"]["Q"])
    np.testing.assert_allclose(np.diag(r), 1.0)
    assert (r >= 0).all() and (r <= 1).all() and np.allclose(r, r.T)
    # the strongest pair of Q: gyros 1 and 5, -0.240055 / sqrt(0.255058 * 0.555127)
    assert r[0, 4] == pytest.approx(0.240055 / np.sqrt(0.255058 * 0.555127))
    rows = input_table("case2")
    assert len(rows) == 3 * 21 and {x["matrix"] for x in rows} == {"P1", "P2", "P3"}
    assert all(x["min_eigenvalue"] > 0 for x in rows)  # valid covariances
    one = next(x for x in rows if x["matrix"] == "P2" and (x["gyro_i"], x["gyro_k"]) == (2, 3))
    assert one["correlation"] == pytest.approx(2.264650 / np.sqrt(5.607230 * 7.499051))
    with pytest.raises(InputError, match="positive definite"):
        abs_correlation(np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(InputError, match="unknown SVO case"):
        input_table("case9")
    fig = figure_inputs("case2")
    assert [ax.get_title() for ax in fig.axes[:3]] == ["|corr| of P1", "|corr| of P2",
                                                       "|corr| of P3"]
    np.testing.assert_allclose(fig.axes[1].images[0].get_array(),
                               abs_correlation(INPUT_MATRICES["case2"]["P2"]))


def test_report_tables_coefficient_range_and_fig3_numbers():
    from gmwm_studies.svo_study import METHODS, coef_table, gmwm_table

    rng = np.random.default_rng(0)
    coef = rng.normal(size=(7, len(METHODS), 6))
    par = np.exp(rng.normal(size=(7, 3, len(METHODS), 2)))
    rows = coef_table({"coef": coef}, "case1", 19)
    row = next(x for x in rows if x["method"] == "rdvg" and x["gyro"] == 3)
    b = METHODS.index("rdvg")
    assert row["min"] == coef[:, b, 2].min() and row["max"] == coef[:, b, 2].max()
    g = gmwm_table({"gmwm": par})
    assert len(g) == 2 * len(METHODS)
    eq = next(x for x in g if x["method"] == "equal" and x["parameter"] == "gamma2")
    assert eq["median_to_equal"] == pytest.approx(1.0) and eq["n_signals"] == 21
    w1 = next(x for x in g if x["method"] == "svo_w1" and x["parameter"] == "sigma2")
    v = par[:, :, METHODS.index("svo_w1"), 0].ravel()
    assert w1["median"] == pytest.approx(np.median(v))
    assert w1["q25"] <= w1["median"] <= w1["q75"] <= w1["max"] == v.max()
    for name in ("sigma2", "gamma2"):
        assert sum(x["share_lowest"] for x in g if x["parameter"] == name) == pytest.approx(1.0)


def test_wv_table_population_ratios():
    """true_ratio_to_equal: the methods' population coefficients on the true WCCV (Case 1:
    docs/METHODS.md §11.6's 0.235 for omega_1 at j = 19, and RDVG with the true Q just below it, as [SVO]
    Fig. 2 says); Case 2 has no population RDVG."""
    from gmwm_studies.svo_study import wv_table

    res = {"wv": np.ones((2, 3, 4, 19))}
    rows = {(r["method"], r["level"]): r for r in wv_table(res, 10.0, "case1")}
    assert round(rows[("svo_w1", 19)]["true_ratio_to_equal"], 3) == 0.235
    assert rows[("rdvg", 19)]["true_ratio_to_equal"] < rows[("svo_w1", 19)]["true_ratio_to_equal"]
    assert rows[("equal", 7)]["true_ratio_to_equal"] == pytest.approx(1.0)
    assert round(rows[("svo_w2", 1)]["true_ratio_to_equal"], 2) == 0.86
    case2 = {(r["method"], r["level"]): r for r in wv_table(res, 10.0, "case2")}
    assert np.isnan(case2[("rdvg", 19)]["true_ratio_to_equal"])
    assert "true_ratio_to_equal" not in wv_table(res, 10.0)[0]


def test_train_fit_shortcuts_keep_the_estimates_bit_for_bit():
    """svo_train's virtual-signal fits take the eta_3 interval and se_cov="gaussian" (cheaper):
    the stored WV and WN+RW estimates equal those of the default mixture interval and
    model-based covariance exactly."""
    from gmwm_studies.svo_study import _wn_rw_fit, method_coefs

    cs = case("case1")
    coefs, _ = method_coefs(cs.simulate(2**14, np.random.default_rng(1)), 12)
    W = wccv(cs.simulate(2**14, np.random.default_rng(2)), 12)
    for c in coefs.values():
        fast, ref = W.combine(c, ci="eta3"), W.combine(c)
        assert np.array_equal(fast.variance, ref.variance)
        d = gmwm.fit(ref, "WN+RW", n_starts=1).as_dict()
        assert _wn_rw_fit(fast) == (d["WN[1].sigma2"], d["RW[1].gamma2"])
