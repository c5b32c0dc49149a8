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


def _held(res: Any, p: int) -> np.ndarray:
    """Parameters of components a fit holds at the boundary 0 (``diagnostics["at_boundary"]``):
    no standard error, but an interval (from 0 for the scale, the domain for a shape)."""
    held = np.zeros(p, bool)
    at = (getattr(res, "diagnostics", None) or {}).get("at_boundary", []) or []
    model = getattr(res, "model", None)
    if model is not None:
        for c in model.components:
            if c.name in at:
                held[c.slice] = True
    return held


def _model_of(res: Any) -> Any:
    model = getattr(res, "model", None)
    return model if model is not None else getattr(getattr(res, "estimate", None), "model", None)


def check_result(res: Any) -> None:
    """Assert that ``res`` follows the result protocol (types, shapes, intervals inside the
    parameter space, NaN handling, text, strict JSON, immutability; for GMWM results the
    goodness-of-fit test on every surface)."""
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

    held = _held(res, p)
    model = _model_of(res)
    for alpha in (0.05, 0.1):
        ci = res.conf_int(alpha)
        assert isinstance(ci, np.ndarray) and ci.shape == (p, 2), f"{kind}: conf_int shape"
        both = np.all(np.isfinite(ci), axis=1)
        assert np.all(ci[both, 0] <= ci[both, 1]), f"{kind}: interval with low > high"
        # no standard error, no interval (except a component held at the boundary 0)
        assert np.all(np.isnan(ci[np.isnan(se) & ~held])), f"{kind}: interval where se is NaN"
        if held.any():
            assert np.all(~np.isnan(ci[held])), f"{kind}: no interval for a boundary component"
            assert np.all((ci[held, 0] <= params[held]) & (params[held] <= ci[held, 1])), \
                f"{kind}: a boundary component's interval does not contain its estimate"
        if model is not None:  # no interval leaves the parameter space
            from gmwm.intervals import param_domains

            dom = param_domains(model, params)
            with np.errstate(invalid="ignore"):
                outside = (ci[:, 0] < dom[:, 0]) | (ci[:, 1] > dom[:, 1])
            assert not outside.any(), \
                f"{kind}: interval outside the domain for {list(np.array(names)[outside])}"
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

    if hasattr(res, "gof"):  # GMWM results: the goodness-of-fit test
        _check_gof(res, text, back)

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


def _check_gof(res: Any, text: str, d: dict[str, Any]) -> None:
    """``res.gof`` (None: not computed) on every surface: summary line, JSON ``"gof"``, and a
    rejected model as a warning in ``res.warnings`` and the summary."""
    kind = type(res).__name__
    g = res.gof
    assert "gof" in d and "ci95" in d, f"{kind}: to_json_dict lacks gof/ci95"
    assert list(d["ci95"]) == res.param_names, f"{kind}: ci95 names"
    assert "goodness of fit" in text, f"{kind}: summary has no goodness-of-fit line"
    if g is None:
        assert d["gof"] is None
        return
    assert isinstance(g.df, int) and g.df >= 0, f"{kind}: gof df"
    assert np.isnan(g.p_value) or 0.0 <= g.p_value <= 1.0, f"{kind}: gof p-value"
    assert np.isnan(g.statistic) or g.statistic >= 0, f"{kind}: gof statistic"
    assert g.residuals.shape == (res.wv.n_levels,), f"{kind}: one residual per scale"
    assert d["gof"]["df"] == g.df and len(d["gof"]["residuals"]) == res.wv.n_levels
    assert g.line() in text, f"{kind}: summary lacks the gof line"
    if g.rejected():
        w = g.warning()
        assert w in res.warnings, f"{kind}: rejected model without a warning"
        assert w in text and w in d["warnings"], f"{kind}: rejected-model warning not shown"
