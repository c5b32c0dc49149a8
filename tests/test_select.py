"""Model selection (gmwm.select) and the ``gmwm select`` command.

Hit-rate thresholds come from Monte Carlo runs of the same settings (noted at each test)."""

from __future__ import annotations

import io
import json
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import gmwm
from gmwm.cli import main
from gmwm.errors import InputError, ModelError
from gmwm.model import Model
from gmwm.select import auto_candidates, optimism, rank_models, rerank, select_model

WN_RW = Model("WN+RW")
THETA_WN_RW = WN_RW.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4})


def _signal(seed: int, T: int = 2**14) -> np.ndarray:
    return WN_RW.simulate(THETA_WN_RW, T, np.random.default_rng([3, seed]))


def _correlated_cov(wv) -> np.ndarray:
    sd = np.sqrt(2 * wv.variance**2 / wv.edof)
    lag = np.abs(np.subtract.outer(np.arange(wv.n_levels), np.arange(wv.n_levels)))
    return np.outer(sd, sd) * 0.5**lag


def _with_weights(res, omega: np.ndarray) -> SimpleNamespace:
    """The fit's estimate with another weight matrix (optimism only reads these fields)."""
    return SimpleNamespace(wv=res.wv, model=res.model, params=res.params, weights=omega,
                           method="gmwm")


@pytest.mark.parametrize("spec", ["WN+RW", "WN+AR1"])
def test_optimism_is_the_parameter_count_with_efficient_weights(spec: str) -> None:
    """Omega = V^-1 makes tr(Omega A G V) = rank(A) = p exactly (the AIC case)."""
    wv = gmwm.wvar(_signal(0))
    V = _correlated_cov(wv)
    res = _with_weights(gmwm.fit(wv, spec), np.linalg.inv(V))
    assert optimism(res, V) == pytest.approx(Model(spec).n_params, rel=1e-6)


def test_penalty_invariant_to_weight_scale() -> None:
    wv = gmwm.wvar(_signal(1))
    V = _correlated_cov(wv)
    res = gmwm.fit(wv, "WN+RW")
    a = optimism(_with_weights(res, np.diag(1 / np.diag(V))), V)
    b = optimism(_with_weights(res, np.diag(1e6 / np.diag(V))), V)
    assert b == pytest.approx(1e6 * a, rel=1e-9)   # scales with Omega, like the objective
    assert a > 2  # diagonal weights ignoring positively correlated V: more than the AIC count


def test_auto_candidates_bounded_and_complete() -> None:
    got = auto_candidates("WN+2*AR1+RW")
    assert got[0] == "WN+2*AR1+RW"
    for m in ("WN+AR1+RW", "2*AR1+RW", "WN+2*AR1", "WN+RW", "QN+WN+2*AR1+RW",
              "WN+2*AR1+RW+DR", "WN+3*AR1+RW", "WN+2*AR1+SIN+RW"):
        assert m in got
    assert len(got) == len(set(got))
    assert len(auto_candidates("QN+WN+3*AR1+2*SIN+RW+DR")) <= 31
    assert len(auto_candidates("QN+WN+AR1+GM+SIN+RW+DR")) == 31  # the largest set
    assert "WN+3*AR1+RW" not in auto_candidates("WN+3*AR1+RW")[1:]  # cap of 3 AR1
    assert "WN+2*GM" in auto_candidates("WN+GM")                      # GM base grows GM
    with pytest.raises(ModelError, match="caps"):
        auto_candidates("3*SIN+WN")


def test_rank_picks_generating_linear_model() -> None:
    """WN+RW at T = 2^14 among six linear candidates: 30 of 30 seeds picked WN+RW (WIC-log; WIC
    too). The default criterion is WIC-HQ (k = 2 log log T)."""
    cands = ["WN", "RW", "WN+RW", "QN+WN+RW", "WN+RW+DR", "QN+WN"]
    for seed in range(4):
        ranking = rank_models(_signal(seed), cands)
        assert ranking.best.model == "WN+RW"
        # accepted candidates first, each group by criterion
        flags = [e.rejected() for e in ranking.ranked]
        assert flags == sorted(flags)
        for group in (False, True):
            crit = [e.criterion for e in ranking.ranked if e.rejected() is group]
            assert crit == sorted(crit)
        assert ranking.criterion == "wic-hq"
        assert ranking.factor == pytest.approx(2 * np.log(np.log(2**14)))
        for e in ranking.ranked:
            assert e.criterion == pytest.approx(e.objective + ranking.factor * e.penalty)
        assert rerank(ranking, "wic-log").best.model == "WN+RW"


def test_rank_picks_ar1_over_rw() -> None:
    """WN + AR1(phi 0.995) at T = 2^14 against WN and WN+RW: 20 of 20 seeds picked WN+AR1."""
    m = Model("WN+AR1")
    th = m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995, "AR1[1].sigma2": 1e-3})
    x = m.simulate(th, 2**14, np.random.default_rng([4, 0]))
    ranking = rank_models(x, ["WN", "WN+RW", "WN+AR1"], criterion="wic-log")
    assert ranking.best.model == "WN+AR1"
    assert ranking.factor == pytest.approx(np.log(2**14))


def test_a_rejected_model_is_never_ranked_above_an_accepted_one() -> None:
    """WN + RW + AR1 (phi 0.995) at T = 2^20 ranked by WIC-log: WN+AR1 has the lower criterion
    (the log T penalty outweighs the objective drop the RW brings) but the goodness-of-fit test
    rejects it, while WN+AR1+RW passes; the accepted model ranks first, under every criterion
    and after a re-ranking or a merge."""
    from gmwm.select import merge

    m = Model("WN+AR1+RW")
    th = m.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6, "AR1[1].phi": 0.995,
                  "AR1[1].sigma2": 2e-3})
    x = m.simulate(th, 2**20, np.random.default_rng([40, 2]))
    ranking = rank_models(x, ["WN+AR1", "WN+AR1+RW", "WN+RW"], criterion="wic-log")
    by_model = {e.model: e for e in ranking.ranked}
    small, full = by_model["WN+AR1"], by_model["WN+AR1+RW"]
    assert small.rejected() and not full.rejected()
    assert ranking.best.model == full.model
    # the parsimony step keeps the AR1: the model without it is rejected too (the data show it)
    assert by_model["WN+RW"].rejected() and ranking.simplified == ()
    assert [e.rejected() for e in ranking.ranked] == [False, True, True]
    for crit in ("wic", "wic-hq", "wic-log"):
        assert rerank(ranking, crit).best.model == full.model
    parts = [rank_models(x, [s], criterion="wic-log") for s in ("WN+AR1", "WN+AR1+RW")]
    assert merge(parts).best.model == full.model
    d = ranking.to_json_dict()
    assert d["ranking"][1]["rejected"] is True and d["ranking"][0]["p_value"] >= 0.05
    assert "REJECTED" in ranking.summary().splitlines()[-1]
    # a level no candidate fails: the criterion alone orders them
    lax = rank_models(x, ["WN+AR1", "WN+AR1+RW"], criterion="wic-log", gof_alpha=1e-300)
    assert [e.criterion for e in lax.ranked] == sorted(e.criterion for e in lax.ranked)


def test_superset_with_a_zero_component_ties_and_loses() -> None:
    """WN+RW+DR with DR estimated at 0 has WN+RW's objective and a zero DR Jacobian column (no
    extra penalty): the tie goes to the smaller model under both criteria."""
    ranking = rank_models(_signal(2), ["WN+RW+DR", "WN+RW"])
    top = ranking.ranked
    if top[1].objective == pytest.approx(top[0].objective, rel=1e-7):
        assert top[0].model == "WN+RW"
    other = rerank(ranking, "wic-log")
    assert other.best.model == "WN+RW" and other.factor == pytest.approx(np.log(2**14))
    for e in other.ranked:
        assert e.criterion == pytest.approx(e.objective + other.factor * e.penalty)


def test_skipped_candidates_and_json() -> None:
    ranking = rank_models(_signal(0), ["WN+RW", "QN+WN+RW+DR"], levels=3)
    assert [e.model for e in ranking.skipped] == ["QN+WN+RW+DR"]
    d = json.loads(json.dumps(ranking.to_json_dict()))
    assert d["ranking"][0]["model"] == "WN+RW"
    assert set(d["ranking"][0]) >= {"model", "criterion", "objective", "n_params"}
    assert "more parameters" in d["skipped"][0]["error"] or "parameters" in d["skipped"][0]["error"]
    with pytest.raises(InputError, match="criterion"):
        rank_models(_signal(0), ["WN"], criterion="aic")


def test_select_model_returns_fit_and_drift_sign() -> None:
    m = Model("WN+DR")
    x = m.simulate(m.theta({"WN[1].sigma2": 1.0, "DR[1].omega": 0.01}), 2**13, 1)
    res = select_model(-x, ["WN", "WN+DR"])
    assert res.model.spec == "WN+DR"
    assert res.as_dict()["DR[1].omega"] == pytest.approx(-0.01, rel=0.1)
    assert not any("drift sign" in w for w in res.diagnostics.get("warnings", []))


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_cli_select_json_columns_auto_and_progress(tmp_path, capsys, monkeypatch) -> None:
    x0, x1 = _signal(0), _signal(1)
    npy = tmp_path / "x.npy"
    np.save(npy, x0)
    assert main(["select", str(npy), "WN", "WN+RW", "QN+WN+RW", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ranking"][0]["model"] == "WN+RW" and len(d["ranking"]) == 3

    csv = tmp_path / "imu.csv"
    csv.write_text("gx,gy\n" + "\n".join(f"{a:.17g},{b:.17g}" for a, b in zip(x0, x1)) + "\n")
    assert main(["select", str(csv), "WN", "WN+RW", "QN+WN+RW", "--columns", "gx,gy",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert set(d["rankings"]) == {"gx", "gy"}
    assert d["rankings"]["gx"][0]["model"] == "WN+RW"
    assert main(["select", str(npy), "WN+RW", "--auto", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["candidates"] == auto_candidates("WN+RW")
    assert d["ranking"][0]["model"] == "WN+RW"

    # progress lines only on a terminal and without --quiet
    tty = _Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    assert main(["select", str(npy), "WN", "WN+RW"]) == 0
    assert "fitting candidate 2/2: WN+RW" in tty.getvalue()
    tty2 = _Tty()
    monkeypatch.setattr(sys, "stderr", tty2)
    assert main(["select", str(npy), "WN", "WN+RW", "--quiet"]) == 0
    assert "fitting" not in tty2.getvalue()
    out = capsys.readouterr().out
    assert "rank" in out and "WN+RW" in out
    monkeypatch.undo()
    assert main(["select", str(npy), "WN+XX"]) == 1
    assert "unknown process" in capsys.readouterr().err


# -- the parsimony step (gmwm.select.order) -------------------------------------------------------
def _entry(spec: str, crit: float, p: float, n: int | None = None):
    from gmwm.select import RankedModel

    return RankedModel(spec, crit, crit, 0.0, Model(spec).n_params if n is None else n, True,
                       p_value=p)


def test_parsimony_removes_a_component_the_data_do_not_show() -> None:
    """The criterion prefers WN+SIN+AR1+RW, but WN+AR1+RW (no SIN) passes the test: the SIN goes;
    then WN+RW passes too: the AR1 goes. A removal whose model the test rejects is not made, and
    of two admissible removals the lower criterion wins."""
    from gmwm.select import order

    entries = [_entry("WN+SIN+AR1+RW", 1.0, 0.6), _entry("WN+AR1+RW", 1.5, 0.4),
               _entry("WN+SIN+RW", 1.2, 0.3), _entry("WN+RW", 2.0, 0.2),
               _entry("WN+AR1", 9.0, 0.001)]
    ranked, steps = order(entries)
    # of the two removals (SIN -> WN+AR1+RW at 1.5, AR1 -> WN+SIN+RW at 1.2) the lower criterion
    # is taken first; then the SIN of WN+SIN+RW goes (WN+RW passes); WN+RW has no SIN/GM/AR1
    assert [(s.removed_from, s.component, s.model) for s in steps] == [
        ("WN+SIN+AR1+RW", "AR1", "WN+SIN+RW"), ("WN+SIN+RW", "SIN", "WN+RW")]
    assert steps[-1].p_value == 0.2
    assert [e.model for e in ranked] == ["WN+RW", "WN+SIN+AR1+RW", "WN+SIN+RW", "WN+AR1+RW",
                                         "WN+AR1"]
    # off: the criterion alone (accepted first)
    plain, none = order(entries, parsimony=())
    assert none == [] and plain[0].model == "WN+SIN+AR1+RW"
    # the model without the SIN rejected: the SIN stays (the data show it)
    kept, steps = order([_entry("WN+SIN+RW", 1.0, 0.5), _entry("WN+RW", 3.0, 0.005)])
    assert steps == [] and kept[0].model == "WN+SIN+RW"
    # a regular component (RW) is never removed by the step, nor is an untested reduced model
    # (NaN p-value: no evidence) a reason to remove
    kept, steps = order([_entry("WN+RW", 1.0, 0.5), _entry("WN", 3.0, 0.4)])
    assert steps == [] and kept[0].model == "WN+RW"
    kept, steps = order([_entry("WN+GM", 0.5, 0.5), _entry("WN", 3.0, np.nan)])
    assert steps == [] and kept[0].model == "WN+GM"


def test_parsimony_leaves_an_all_rejected_ranking_unchanged() -> None:
    """Every candidate rejected (the rule on long real recordings): the step does nothing, the
    criterion alone orders them."""
    from gmwm.select import order

    entries = [_entry("WN+GM+RW", 1.0, 1e-40), _entry("WN+RW", 2.0, 1e-3),
               _entry("WN+2*GM+RW", 0.8, 1e-30), _entry("WN+SIN+GM+RW", 0.9, 0.004)]
    with_step, steps = order(entries)
    without, _ = order(entries, parsimony=())
    assert steps == [] and with_step == without
    assert [e.model for e in with_step] == ["WN+2*GM+RW", "WN+SIN+GM+RW", "WN+GM+RW", "WN+RW"]


def test_parsimony_removes_an_added_ar1_on_real_fits(tmp_path, capsys) -> None:
    """WN + RW data (seed found by a scan of 60: the one where WIC prefers the added AR1): WIC
    ranks WN+AR1+RW first, but WN+RW passes the test, so the AR1 is removed; select says so."""
    x = WN_RW.simulate(THETA_WN_RW, 2**13, np.random.default_rng([41, 41]))
    from gmwm.select import order

    ranking = rank_models(x, ["WN+RW", "WN+AR1+RW"], criterion="wic")
    plain, none = order(ranking.ranked, parsimony=())
    assert plain[0].model == "WN+AR1+RW" and none == []
    by_model = {e.model: e for e in ranking.ranked}
    assert by_model["WN+AR1+RW"].criterion < by_model["WN+RW"].criterion
    assert ranking.best.model == "WN+RW" and not ranking.best.rejected()
    (step,) = ranking.simplified
    assert (step.removed_from, step.component, step.model) == ("WN+AR1+RW", "AR1", "WN+RW")
    assert step.p_value == pytest.approx(by_model["WN+RW"].p_value)
    assert rerank(ranking, "wic").best.model == "WN+RW"
    assert json.loads(json.dumps(ranking.to_json_dict()))["simplified"][0]["component"] == "AR1"
    assert "parsimony: AR1 removed from WN+AR1+RW" in ranking.summary()
    npy = tmp_path / "x.npy"
    np.save(npy, x)
    assert main(["select", str(npy), "WN+RW", "WN+AR1+RW", "--criterion", "wic"]) == 0
    out = capsys.readouterr().out
    assert "parsimony: AR1 removed from WN+AR1+RW: WN+RW passes the goodness-of-fit test" in out
