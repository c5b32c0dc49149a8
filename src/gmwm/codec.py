"""Lossless result files: a :class:`gmwm.estimator.GMWMResult` as strict JSON, every float64 exact.

:func:`result_to_dict` / :func:`result_from_dict` convert, :func:`write_result` /
:func:`read_result` write (atomically) and read a file. Floats are stored by Python's ``repr``
(which round-trips every float64); non-finite values as ``"NaN"``/``"Infinity"`` so the file is
strict JSON.
"""

from __future__ import annotations

import json
import os
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.atomic import write_text_atomic
from gmwm.errors import InputError
from gmwm.readers.tables import existing_file

__all__ = ["RESULT_FORMAT", "read_result", "result_from_dict", "result_to_dict", "write_result"]

RESULT_FORMAT = "gmwm-result/2"  # 2: fields by name, non-finite scalars as {"__float__"}
_NONFINITE = {"NaN": np.nan, "Infinity": np.inf, "-Infinity": -np.inf}


def _enc_float(v: float) -> float | str:
    """A float as JSON: itself (Python's repr round-trips every float64) or "NaN"/"Infinity"."""
    v = float(v)
    if np.isfinite(v):
        return v
    return "NaN" if np.isnan(v) else ("Infinity" if v > 0 else "-Infinity")


def _dec_float(v: float | str) -> float:
    return _NONFINITE[v] if isinstance(v, str) else float(v)


def _enc_array(a: Any) -> dict[str, Any]:
    a = np.asarray(a)
    flat = a.reshape(-1).tolist()
    if a.dtype.kind in "fc":
        flat = [_enc_float(v) for v in flat]
    return {"__ndarray__": a.dtype.str, "shape": list(a.shape), "data": flat}


def _dec_array(d: dict[str, Any]) -> np.ndarray:
    dtype = np.dtype(d["__ndarray__"])
    data = [_dec_float(v) for v in d["data"]] if dtype.kind in "fc" else d["data"]
    return np.array(data, dtype=dtype).reshape(d["shape"])


def _enc_tree(obj: Any) -> Any:
    """settings/diagnostics: dicts (str keys), lists/tuples (read back as lists), arrays, scalars."""
    if isinstance(obj, dict):
        return {str(k): _enc_tree(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_enc_tree(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _enc_array(obj)
    if hasattr(obj, "to_tree"):  # FitSettings: its options by name (read back by the result)
        return _enc_tree(obj.to_tree())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return {"__float__": _enc_float(obj)}
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    raise InputError(f"cannot store a {type(obj).__name__} in a result file")


def _dec_tree(obj: Any) -> Any:
    if isinstance(obj, dict):
        if "__ndarray__" in obj:
            return _dec_array(obj)
        if "__float__" in obj:
            return _dec_float(obj["__float__"])
        return {k: _dec_tree(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_dec_tree(v) for v in obj]
    return obj


def result_to_dict(result: Any) -> dict[str, Any]:
    """Lossless JSON-able dict of a :class:`gmwm.estimator.GMWMResult` (read back by
    :func:`result_from_dict`): the model as spec and frequency, every other field of the result
    and of its WV by name. Every float64 is stored exactly; non-finite values as "NaN"/"Infinity"
    (strict JSON). Unlike :meth:`GMWMResult.to_json_dict` (a readable summary), nothing is
    dropped."""
    out = {"format": RESULT_FORMAT, "model": result.model.spec,
           "model_freq": float(result.model.freq),
           "wv": {f.name: _enc_tree(getattr(result.wv, f.name))
                  for f in dataclass_fields(result.wv)}}
    for f in dataclass_fields(result):
        if f.name not in out:
            out[f.name] = _enc_tree(getattr(result, f.name))
    return out


def result_from_dict(d: dict[str, Any]) -> Any:
    """The :class:`gmwm.estimator.GMWMResult` stored by :func:`result_to_dict` (same arrays, bit
    for bit; tuples in settings/diagnostics come back as lists)."""
    from gmwm.estimator import GMWMResult
    from gmwm.model import Model
    from gmwm.wv import WaveletVariance

    if not isinstance(d, dict) or d.get("format") != RESULT_FORMAT:
        got = d.get("format") if isinstance(d, dict) else type(d).__name__
        raise InputError(f"not a gmwm result ({RESULT_FORMAT!r} expected, got {got!r})")
    try:
        wv = WaveletVariance(**{k: _dec_tree(v) for k, v in d["wv"].items()})
        # a field missing from the file (one added later, e.g. gof) takes its default
        rest = {f.name: _dec_tree(d[f.name]) for f in dataclass_fields(GMWMResult)
                if f.name not in ("model", "wv") and f.name in d}
        return GMWMResult(model=Model(d["model"], freq=float(d["model_freq"])), wv=wv, **rest)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"damaged gmwm result: {type(exc).__name__} {exc}") from None


def write_result(path: str | os.PathLike, result: Any) -> Path:
    """Write a GMWMResult losslessly as JSON (:func:`result_to_dict`), atomically."""
    text = json.dumps(result_to_dict(result), allow_nan=False)
    return write_text_atomic(path, text + "\n")


def read_result(path: str | os.PathLike) -> Any:
    """Read a GMWMResult written by :func:`write_result`."""
    p = existing_file(path)
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{p} is not a JSON gmwm result ({exc})") from None
    try:
        return result_from_dict(d)
    except InputError as exc:
        raise InputError(f"{p}: {exc}") from None
