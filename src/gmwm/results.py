"""The protocol every estimator result follows, and the helpers the result classes share.

A result (:class:`gmwm.estimator.GMWMResult` for GMWM and ARMAV, :class:`gmwm.avsm.AVSMResult`,
:class:`gmwm.bootstrap.BootstrapResult`, ...) is an immutable dataclass with:

* ``params`` (p,) float array and ``param_names`` (list of p str), in canonical order;
* ``se`` (p,) standard errors, NaN where the estimator has none;
* ``conf_int(alpha=0.05)`` -> (p, 2) array of ``[low, high]`` intervals at level ``1 - alpha``
  (NaN where none);
* ``summary()`` -> plain-text table naming every parameter;
* ``to_json_dict()`` -> a dict that strict JSON accepts (non-finite numbers as None);
* ``settings``: the :class:`gmwm.settings.FitSettings` it was computed with.

Its arrays are read-only and setting an attribute raises: code that needs a changed result builds
a new one (``dataclasses.replace``). ``tests/result_protocol.py`` checks all of this.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["freeze_arrays", "json_safe", "readonly", "wald_ci"]


def readonly(a: Any, dtype: Any = float) -> np.ndarray:
    """A read-only copy of ``a`` as an array of ``dtype``."""
    out = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


def freeze_arrays(obj: Any, names: tuple[str, ...], dtype: Any = float) -> None:
    """In a frozen dataclass's ``__post_init__``: replace the fields ``names`` (None kept) by
    read-only copies."""
    for name in names:
        v = getattr(obj, name)
        if v is not None:
            object.__setattr__(obj, name, readonly(v, dtype))


def check_alpha(alpha: float) -> None:
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha}")


def wald_ci(params: np.ndarray, se: np.ndarray, alpha: float = 0.05) -> np.ndarray:
    """(p, 2) Wald intervals ``params -/+ z se``, ``z`` the normal ``1 - alpha/2`` quantile
    (NaN where the SE is)."""
    from scipy.special import ndtri

    check_alpha(alpha)
    z = ndtri(1 - alpha / 2)
    params, se = np.asarray(params, dtype=float), np.asarray(se, dtype=float)
    return np.column_stack([params - z * se, params + z * se])


def json_safe(obj: Any) -> Any:
    """``obj`` with numpy values as Python ones and non-finite numbers as None (strict JSON)."""
    from .atomic import to_jsonable

    return to_jsonable(obj)
