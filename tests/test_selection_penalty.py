"""The logic of the selection-penalty study's second qualifier (benchmarks/selection_penalty.py):
the model without a non-regular component is found among the ranked candidates, the objective
drop and penalty difference have the signs nesting implies, and the "shown" qualifier narrows
the z one."""

from __future__ import annotations

import json

import numpy as np

from conftest import load_benchmark
from gmwm.model import Model
from gmwm.select import RankedModel, rank_models
from gmwm.wv import wvar

sp = load_benchmark("selection_penalty")


def test_dropped_spec_removes_one_component():
    assert sp.dropped_spec("WN+SIN+RW", "SIN") == {"WN": 1, "RW": 1}
    assert sp.dropped_spec("WN+2*GM+RW", "GM") == {"WN": 1, "GM": 1, "RW": 1}


def test_drop_evidence_reads_the_candidates():
    def entry(spec: str, obj: float, pen: float, p: float) -> RankedModel:
        return RankedModel(spec, obj + 2 * pen, obj, pen, 0, True, p_value=p)

    entries = [entry("WN+RW", 0.5, 0.3, 0.01), entry("WN+SIN+RW", 0.2, 0.4, 0.4),
               entry("WN+SIN", 3.0, 0.3, 0.0)]
    ev = sp.drop_evidence(entries, "WN+SIN+RW")
    assert list(ev) == ["SIN"]          # WN and RW are regular: no entry
    d, p, dpen = ev["SIN"]
    assert (d, p, dpen) == (0.5 - 0.2, 0.01, 0.4 - 0.3)
    # the candidate without it missing: NaN, which never counts as shown
    d, p, dpen = sp.drop_evidence(entries[1:], "WN+SIN+RW")["SIN"]
    assert np.isnan(p) and not p < sp.ALPHA_SHOWN


def test_nested_fits_give_a_nonnegative_drop():
    model = Model("WN+RW")
    theta = model.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5})
    x = model.simulate_fast(theta, 2**11, np.random.default_rng(7))
    ranking = rank_models(wvar(x), ["WN+SIN+RW", "WN+RW"])
    d, p, dpen = sp.drop_evidence(ranking.ranked, "WN+SIN+RW")["SIN"]
    assert d >= -1e-6 * max(1.0, abs(d))    # the sinusoid at amplitude 0 is WN+RW
    assert dpen > 0 and 0 <= p <= 1


def test_cache_round_trip_and_the_rules_read_off_it():
    """Stored candidates come back with their numbers (NaN p-value as None and back), and the
    rules differ where they should: the criterion alone keeps a SIN whose removal passes the
    test, the library's parsimony step removes it, and the every-component variant also removes
    the RW when WN alone passes."""
    def entry(spec: str, obj: float, pen: float, p: float) -> RankedModel:
        return RankedModel(spec, np.nan, obj, pen, Model(spec).n_params, True, p_value=p)

    entries = [entry("WN+SIN+RW", 0.2, 0.4, 0.4), entry("WN+RW", 1.5, 0.3, 0.2),
               entry("WN", 9.0, 0.2, 0.06), entry("WN+SIN", 5.0, 0.3, np.nan)]
    back = sp.restored(json.loads(json.dumps(sp.stored(entries))))
    assert [(e.model, e.objective, e.penalty, e.n_params) for e in back] == \
        [(e.model, e.objective, e.penalty, e.n_params) for e in entries]
    assert np.isnan(back[3].p_value) and back[0].p_value == 0.4
    picks = sp.picks_of(back, 2**14)
    assert picks[("criterion only", "k=2 (wic)")] == "WN+SIN+RW"
    assert picks[(sp.LIBRARY_RULE, "k=2 (wic)")] == "WN+RW"
    assert picks[("parsimony, every component", "k=2 (wic)")] == "WN"
    rec = {"entries": sp.stored(entries), "z": [5.0, 4.0, None]}
    judged = sp.judge(sp.settings()[5], 2**14, rec)   # gyro WN+SIN+RW
    assert not judged["qualifies"] and judged["picks"] == picks
