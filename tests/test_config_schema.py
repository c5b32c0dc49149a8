"""The pipeline's configs (config/config.yaml, and with config/quick.yaml over it, as
`--configfile config/quick.yaml` merges them) against workflow/schemas/config.schema.yaml, and the
issue-39 cost settings the full profile relies on (Simulation 1's per-variant MLE cap, the SVO
coverage schemes, the Simulation 3 coverage size)."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

pytest.importorskip("snakemake")
from snakemake.exceptions import WorkflowError
from snakemake.utils import update_config, validate

from gmwm.errors import InputError
from gmwm_studies.sim1 import variant_replicate_caps

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = str(ROOT / "workflow" / "schemas" / "config.schema.yaml")


def _load(name: str) -> dict:
    return yaml.safe_load((ROOT / "config" / name).read_text())


def _configs() -> dict[str, dict]:
    full = _load("config.yaml")
    quick = copy.deepcopy(full)
    update_config(quick, _load("quick.yaml"))
    for cfg in (full, quick):
        validate(cfg, SCHEMA)  # fills the defaults, as the Snakefile does
    return {"full": full, "quick": quick}


def _mle_caps(study: dict) -> dict[int, int]:
    """workflow/rules/sim1.smk's sim1_mle_caps."""
    cap = study["mle"]["replicates"]
    caps = cap if isinstance(cap, list) else [cap] * len(study["n_samples"])
    return {int(T): min(int(c), study["replicates"]) for T, c in zip(study["n_samples"], caps,
                                                                     strict=True)}


def test_both_profiles_validate_and_keep_the_cost_settings():
    cfg = _configs()
    full, quick = cfg["full"]["studies"], cfg["quick"]["studies"]
    # Simulation 1: statsmodels' start on the first 100 replicates, the others on all 500
    sim1 = full["sim1"]
    assert variant_replicate_caps(sim1["mle"]["variant_replicates"], list(sim1["mle"]["variants"]),
                                  _mle_caps(sim1)) == {"mle_sm": dict.fromkeys(sim1["n_samples"],
                                                                              100)}
    assert _mle_caps(sim1) == dict.fromkeys(sim1["n_samples"], 500)
    q = quick["sim1"]
    assert variant_replicate_caps(q["mle"]["variant_replicates"], list(q["mle"]["variants"]),
                                  _mle_caps(q)) == {"mle_sm": {10000: 3, 20000: 3}}
    # SVO coverage: both MBB schemes, the time-axis one on the first 200 replications (full) / 30
    assert cfg["full"]["svo"]["coverage"]["schemes"] == ["paper", "time"]
    assert cfg["full"]["svo"]["coverage"]["scheme_replicates"] == {"time": 200}
    assert cfg["quick"]["svo"]["coverage"]["schemes"] == ["paper", "time"]
    assert cfg["quick"]["svo"]["coverage"]["scheme_replicates"] == {"time": 30}
    # Simulation 3 bootstrap coverage: R = 60, B = 100
    assert full["sim3_coverage"]["replicates"] == 60
    assert full["sim3_coverage"]["bootstrap"]["B"] == 100


@pytest.mark.parametrize("bad", [{"mle_sm": -1}, {"mle_sm": "100"}, {"sm": 100},
                                 {"mle_sm": []}])
def test_schema_refuses_a_malformed_variant_cap(bad):
    cfg = _configs()["full"]
    cfg["studies"]["sim1"]["mle"]["variant_replicates"] = bad
    with pytest.raises(WorkflowError):
        validate(cfg, SCHEMA)


@pytest.mark.parametrize("bad", [{"rdvg": 200}, {"time": 0}, {"time": "200"}, {"time": 2.5}])
def test_schema_refuses_a_malformed_svo_scheme_cap(bad):
    cfg = _configs()["full"]
    cfg["svo"]["coverage"]["scheme_replicates"] = bad
    with pytest.raises(WorkflowError):
        validate(cfg, SCHEMA)


def test_a_cap_above_the_mle_cap_is_an_error():
    sim1 = _configs()["full"]["studies"]["sim1"]
    with pytest.raises(InputError, match="MLE cap \\(500\\)"):
        variant_replicate_caps({"mle_sm": 501}, list(sim1["mle"]["variants"]), _mle_caps(sim1))
