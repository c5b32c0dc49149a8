"""The fast part of the selection study (benchmarks/bench_selection.py) and the ranking notes
(gmwm.criteria): the default criterion keeps a random walk at 3 SE that wic-log drops, does not
add components to a strong model, and a ranking says which components its top models disagree
on, with z-values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import load_benchmark
from gmwm.criteria import CRITERIA, DEFAULT, factor, near_ties, ranking_notes
from gmwm.errors import InputError
from gmwm.select import rank_models, rerank, select_model
from gmwm.wv import wvar

bs = load_benchmark("bench_selection")


def test_factors():
    assert factor("wic", 2**20) == 2.0
    assert factor("wic-hq", 2**20) == pytest.approx(2 * math.log(20 * math.log(2)))
    assert factor("wic-log", 2**20) == pytest.approx(20 * math.log(2))
    assert DEFAULT in CRITERIA
    with pytest.raises(InputError):
        factor("bic", 100)


def test_calibration_reaches_the_target_z():
    s = next(x for x in bs.settings() if x.label == "WN+RW, RW z=3")
    model, theta = s.truth(2**14)
    se = bs.expected_se(model, theta, 2**14)
    assert theta[1] / se[1] == pytest.approx(3.0, rel=0.01)
    # a random walk next to a slow AR1 cannot reach 3 SE at 2^14: said, not faked
    s = next(x for x in bs.settings() if x.label == "WN+AR1+RW, RW z=3")
    with pytest.raises(ValueError, match="saturates"):
        s.truth(2**14)


def _study(label: str, T: int, reps: int) -> dict:
    s = next(x for x in bs.settings() if x.label == label)
    model, theta = s.truth(T)
    cands = bs.candidates(model.spec)
    picks = [bs.replicate(s, T, r, model, theta, cands) for r in range(reps)]
    return bs.summarise(s, model, theta, picks)


def test_default_keeps_a_random_walk_at_3_se():
    out = _study("WN+RW, RW z=3", 2**14, 16)
    assert out[DEFAULT]["dropped"] <= 0.2
    assert out["wic-log"]["dropped"] >= 0.5          # the failure the default avoids
    assert out[DEFAULT]["rrw_rms"] < out["wic-log"]["rrw_rms"]


def test_default_on_a_strong_model_rarely_adds():
    out = _study("null: WN+RW, RW z=8", 2**14, 12)
    assert out[DEFAULT]["hit"] >= 0.75
    assert out[DEFAULT]["dropped"] == 0.0


def test_ranking_notes_name_the_disagreement():
    s = next(x for x in bs.settings() if x.label == "WN+RW, RW z=3")
    model, theta = s.truth(2**14)
    x = model.simulate_fast(theta, 2**14, np.random.default_rng(7))
    ranking = rank_models(wvar(x), ["WN", "WN+RW", "WN+RW+DR"])
    assert ranking.criterion == DEFAULT == "wic" and ranking.factor == 2.0
    assert rerank(ranking, "wic-log").factor == pytest.approx(14 * math.log(2))
    notes = ranking_notes(ranking, tol=1e9)          # every other model counted as a tie
    assert len(notes) == 2
    best = ranking.ranked[0].model
    assert best == "WN+RW"
    wn = next(n for n in notes if n.startswith("near tie: WN "))
    assert "drops RW (z = " in wn and "in WN+RW)" in wn
    dr = next(n for n in notes if "WN+RW+DR" in n)
    assert "adds DR" in dr
    # with the default tolerance WN is not a tie of WN+RW here (its RW is at ~3 SE)
    assert all(e.model != "WN" for e in near_ties(ranking))


def test_ranking_output_carries_the_notes():
    """A weak random walk (about 1.5 SE): WN and WN+RW are near ties; the ranking's text and
    JSON say so and name the RW with its z-value; select_model uses the default criterion."""
    import json

    s = next(x for x in bs.settings() if x.label == "WN+RW, RW z=3")
    model, theta = s.truth(2**14)
    theta = theta.copy()
    theta[1] /= 4.0   # RW at about 3/4 x 2 = 1.5 SE: the criteria disagree within ~2 chi2
    found = None
    for seed in range(8):
        x = model.simulate_fast(theta, 2**14, np.random.default_rng([8, seed]))
        ranking = rank_models(wvar(x), ["WN", "WN+RW"])
        if ranking.notes:
            found = ranking
            break
    assert found is not None, "no near tie in 8 replicates of a 1.5 SE random walk"
    d = json.loads(json.dumps(found.to_json_dict(), allow_nan=False))
    assert d["criterion"] == "wic" and d["notes"] == found.notes
    tie = d["near_ties"][0]
    assert {tie["model"], found.best.model} == {"WN", "WN+RW"} and tie["delta_chi2"] < 2.0
    diff = tie["differences"][0]
    assert diff["process"] == "RW" and diff["in_model"] == "WN+RW" and len(diff["z"]) == 1
    text = found.summary()
    assert "note: near tie:" in text and "RW (z = " in text
    best = select_model(wvar(x), ["WN", "WN+RW"])
    assert best.model.spec == found.best.model
