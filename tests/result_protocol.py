"""The battery every estimator result must pass (the protocol of ``gmwm.results``), in the spirit
of scikit-learn's ``check_estimator``: ``check_result(res)`` raises AssertionError naming the
first broken rule. Other test modules import it for their own result types."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from gmwm.errors import InputError
from gmwm.settings import FitSettings


def check_result(res: Any) -> None:
    """Assert that ``res`` follows the result protocol (types, shapes, intervals, NaN handling,
    text, strict JSON, immutability)."""
    kind = type(res).__name__
    names = res.param_names
    assert isinstance(names, list) and all(isinstance(n, str) for n in names), kind
    assert len(set(names)) == len(names), f"{kind}: repeated parameter names"
    p = len(names)

    params = res.params
    assert isinstance(params, np.ndarray) and params.dtype == np.float64, kind
    assert params.shape == (p,), f"{kind}: params shape {params.shape}, {p} names"
    se = res.se
    assert isinstance(se, np.ndarray) and se.dtype == np.float64 and se.shape == (p,), kind
    assert np.all(np.isnan(se) | (se >= 0)), f"{kind}: negative standard error"
    assert not np.any(np.isinf(se)), f"{kind}: infinite standard error (use NaN)"

    for alpha in (0.05, 0.1):
        ci = res.conf_int(alpha)
        assert isinstance(ci, np.ndarray) and ci.shape == (p, 2), f"{kind}: conf_int shape"
        both = np.all(np.isfinite(ci), axis=1)
        assert np.all(ci[both, 0] <= ci[both, 1]), f"{kind}: interval with low > high"
        # no standard error, no interval
        assert np.all(np.isnan(ci[np.isnan(se)])), f"{kind}: interval where se is NaN"
    wide, narrow = res.conf_int(0.05), res.conf_int(0.1)
    both = np.all(np.isfinite(wide), axis=1) & np.all(np.isfinite(narrow), axis=1)
    assert np.all(wide[both, 0] <= narrow[both, 0]) and np.all(narrow[both, 1] <= wide[both, 1]), \
        f"{kind}: the 95 % interval does not contain the 90 % one"
    assert np.array_equal(res.conf_int(), wide, equal_nan=True), f"{kind}: default alpha 0.05"
    for bad in (0.0, 1.0, -0.1):
        with pytest.raises(InputError):
            res.conf_int(bad)

    text = res.summary()
    assert isinstance(text, str) and text, kind
    missing = [n for n in names if n not in text]
    assert not missing, f"{kind}: summary does not name {missing}"

    d = res.to_json_dict()
    assert isinstance(d, dict), kind
    back = json.loads(json.dumps(d, allow_nan=False))  # strict JSON: no NaN/inf
    assert isinstance(back, dict)

    assert isinstance(res.settings, FitSettings), f"{kind}: settings is not a FitSettings"

    assert dataclasses.is_dataclass(res), f"{kind}: not a dataclass"
    for name in ("params", "settings", "not_a_field"):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(res, name, None)
    arrays = {f.name: getattr(res, f.name) for f in dataclasses.fields(res)}
    arrays.update(params=res.params, se=res.se)
    for name, v in arrays.items():
        if isinstance(v, np.ndarray):
            assert not v.flags.writeable, f"{kind}.{name} is writeable"
            if v.size:
                with pytest.raises(ValueError):
                    v.flat[0] = v.flat[0]
    # the sanctioned way to change a result: a new object
    other = dataclasses.replace(res)
    assert other is not res and np.array_equal(other.params, res.params, equal_nan=True)
