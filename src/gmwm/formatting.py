"""Rendering shared by the ``gmwm`` commands and the calibration report (:mod:`gmwm.report`): plain,
Markdown and HTML tables, CSV and JSON text, the WV and Allan-variance tables, the IEEE 952
readings, the datasheet coefficients and verdicts, a fit as text and as JSON, and lists of flagged
time ranges.

Everything here turns results into text; nothing reads files or computes an estimate. Rows are
built once here (raw values; ``None`` where there is none) and each surface formats their cells.
"""

from __future__ import annotations

import html
import json
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from gmwm.errors import InputError

#: columns of a WV table (``gmwm wv``, ``gmwm svo -o``; read back by ``gmwm fit``)
WV_HEADERS = ("level", "scale", "scale_s", "variance", "ci_low", "ci_high", "n")
#: columns of a single-channel Allan-variance table (``gmwm av``)
AV_HEADERS = ("cluster_m", "tau_s", "allan_var", "ci_low", "ci_high", "allan_dev", "n")


# -- cells and tables ---------------------------------------------------------------------------
def fmt(v: Any) -> str:
    """A plain-text cell: '-' for None, yes/no, integers as such, floats to 6 significant
    digits."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return "nan" if not np.isfinite(v) else f"{float(v):.6g}"
    return str(v)


def num(v: Any) -> str:
    """A report cell: '–' for None, else 4 significant digits."""
    return "–" if v is None else f"{float(v):.4g}"


def interval(ci: Sequence[Any] | None) -> str:
    """A report cell of a 95 % interval: ``[low, high]``, '–' for none."""
    return "–" if not ci else f"[{num(ci[0])}, {num(ci[1])}]"


def finite_or_none(v: Any) -> float | None:
    """``float(v)``, or None where it is not a finite number (no estimate)."""
    return float(v) if v is not None and np.isfinite(v) else None


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """Right-aligned plain-text table (cells by :func:`fmt`)."""
    cells = [list(map(str, headers))] + [[fmt(v) for v in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def md_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """Markdown table lines (cells as given)."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return lines


def html_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """HTML table (cells as given, escaped)."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def csv_text(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """CSV with floats written exactly (``repr``), so a table read back gives the same numbers."""
    lines = [",".join(headers)] + [",".join(repr(float(v)) if isinstance(v, float | np.floating) else str(v)
                                            for v in r) for r in rows]
    return "\n".join(lines) + "\n"


def json_text(obj: Any) -> str:
    """Strict JSON (non-finite numbers as null), indented, with a final newline."""
    from gmwm.atomic import to_jsonable

    return json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n"


def seconds(s: float | None) -> str:
    return "-" if s is None else f"{s:.3f} s"


# -- wavelet and Allan variance -----------------------------------------------------------------
def wv_rows(wv: Any) -> list[tuple]:
    """Rows of :data:`WV_HEADERS` of a :class:`gmwm.wv.WaveletVariance`."""
    return [(int(lv), float(s), float(s) / wv.freq, v, lo, hi, int(n))
            for lv, s, v, lo, hi, n in zip(wv.levels, wv.scales, wv.variance, wv.ci_low,
                                           wv.ci_high, wv.n, strict=True)]


def av_rows(av: Any) -> list[tuple]:
    """Rows of :data:`AV_HEADERS` of a :class:`gmwm.wv.AllanVariance`."""
    return [(int(m), float(m) / av.freq, v, lo, hi, np.sqrt(v), int(k))
            for m, v, lo, hi, k in zip(av.clusters, av.avar, av.ci_low, av.ci_high, av.n,
                                       strict=True)]


def _same_levels(items: Mapping[str, Any], what: str) -> Any:
    ref = next(iter(items.values()))
    for name, v in items.items():
        if not np.array_equal(v.n, ref.n):
            raise InputError(f"channel {name} has a different length or number of levels: write "
                             f"the {what} tables of such channels separately")
    return ref


def wv_channel_table(wvs: Mapping[str, Any]) -> tuple[list[str], list[list]]:
    """One CSV table over channels: level, scale, scale_s, n, then variance/ci_low/ci_high per
    channel (``variance[gx]``, ...), as ``gmwm fit`` reads multi-channel WV tables."""
    ref = _same_levels(wvs, "WV")
    fields = ("variance", "ci_low", "ci_high")
    headers = ["level", "scale", "scale_s", "n"] + [f"{f}[{c}]" for c in wvs for f in fields]
    rows = []
    for i, (lv, s) in enumerate(zip(ref.levels, ref.scales, strict=True)):
        row = [int(lv), float(s), float(s) / ref.freq, int(ref.n[i])]
        for wv in wvs.values():
            row += [float(getattr(wv, f)[i]) for f in fields]
        rows.append(row)
    return headers, rows


def av_channel_table(avs: Mapping[str, Any]) -> tuple[list[str], list[list]]:
    """One CSV table over channels: cluster_m, tau_s, n, then allan_var/ci_low/ci_high/allan_dev
    per channel."""
    ref = _same_levels(avs, "AV")
    fields = ("allan_var", "ci_low", "ci_high", "allan_dev")
    headers = ["cluster_m", "tau_s", "n"] + [f"{f}[{c}]" for c in avs for f in fields]
    rows = []
    for i, m in enumerate(ref.clusters):
        row: list[Any] = [int(m), float(ref.tau[i]), int(ref.n[i])]
        for av in avs.values():
            row += [float(av.avar[i]), float(av.ci_low[i]), float(av.ci_high[i]),
                    float(av.adev[i])]
        rows.append(row)
    return headers, rows


def wv_channel_text(wvs: Mapping[str, Any], values: Callable[[Any], Any], what: str) -> str:
    """Text table: level, scale, scale_s, then one ``what`` column per channel."""
    longest = max(wvs.values(), key=lambda w: len(w.levels))
    rows = []
    for i, lv in enumerate(longest.levels):
        s = float(longest.scales[i])
        row: list[Any] = [int(lv), s, s / longest.freq]
        for w in wvs.values():
            v = values(w)
            row.append(float(v[i]) if i < len(v) else None)
        rows.append(row)
    return f"{what} per channel:\n" + table(["level", "scale", "scale_s", *wvs], rows)


def av_channel_text(avs: Mapping[str, Any]) -> str:
    """Text table: cluster_m, tau_s, then the Allan deviation per channel."""
    ref = next(iter(avs.values()))
    rows = [[int(m), float(t), *(float(a.adev[i]) if i < a.adev.size else None
                                 for a in avs.values())]
            for i, (m, t) in enumerate(zip(ref.clusters, ref.tau, strict=True))]
    return table(["cluster_m", "tau_s", *avs], rows)


# -- IEEE 952 readings, datasheet coefficients and verdicts -------------------------------------
def reading_rows(readings: Mapping[str, dict], brief: bool = False) -> list[tuple]:
    """(reading, value, ci95 or None, unit, where read) for N, K and B of one channel's
    :func:`gmwm.datasheet.allan_readings`; ``brief``: the shorter 'where' of the report."""
    rows = []
    for key in ("N", "K", "B"):
        e = readings[key]
        if key == "B":
            where = f"AD minimum at {'' if brief else 'tau = '}{e['tau_s']:.4g} s"
            if e["at_end"]:
                where += (" (last scale: upper bound)" if brief else
                          " (last scale: floor not reached, upper bound)")
        elif e.get("value") is None:
            where = e.get("note", "")
        elif brief:
            where = f"slope line over {e['tau_range_s'][0]:.4g}-{e['tau_range_s'][1]:.4g} s"
        else:
            lo_t, hi_t = e["tau_range_s"]
            where = (f"slope {'-' if key == 'N' else '+'}1/2 over tau {lo_t:.4g}-{hi_t:.4g} s, "
                     f"read at {e['read_at_tau_s']:g} s"
                     + (" (extrapolated)" if e["extrapolated"] else ""))
        rows.append((f"{key} ({e['name']})", e.get("value"), e.get("ci95"), e["unit"], where))
    return rows


def readings_text(readings: Mapping[str, Mapping[str, dict]], single: bool) -> str:
    """The IEEE 952 readings of every channel as one text table (no column 'column' if
    ``single``)."""
    headers = ([] if single else ["column"]) + ["reading", "value", "ci95_low", "ci95_high",
                                                 "unit", "from"]
    rows = [([] if single else [col]) + [label, value, *(ci or [None, None]), unit, where]
            for col, r in readings.items()
            for label, value, ci, unit, where in reading_rows(r)]
    return "IEEE 952 Allan-deviation readings:\n" + table(headers, rows)


def datasheet_rows(ds: Mapping[str, dict]) -> list[tuple]:
    """(term, quantity, value, ci95 or None, unit) per coefficient of a
    :func:`gmwm.datasheet.datasheet` dict (terms with several quantities give several rows)."""
    rows = []
    for term, e in ds.items():
        parts = [("", e)] if "value" in e else list(e.items())
        for what, v in parts:
            rows.append((term, what, v["value"], v.get("ci95"), v["unit"]))
    return rows


def verdict_rows(v: Mapping[str, Any], readable: bool = False) -> list[tuple]:
    """(term, datasheet, measured, ci95 or None, unit, verdict) per row of a datasheet verdict
    (:func:`gmwm.sensor_datasheet.judge`); the term names its quantity, if any (``readable``:
    with spaces for underscores, as the report writes it)."""
    def term(r: Mapping[str, Any]) -> str:
        q = r["quantity"].replace("_", " ") if readable and r["quantity"] else r["quantity"]
        return r["term"] + (f" {q}" if q else "")

    return [(term(r), r["datasheet"], r["measured"], r.get("ci95"), r["unit"], r["verdict"])
            for r in v["rows"]]


def verdict_text(v: Mapping[str, Any]) -> str:
    """A datasheet verdict as text: the table, the notes and the rule."""
    rows = [(term, ds, measured, *(ci or [None, None]), unit, verdict)
            for term, ds, measured, ci, unit, verdict in verdict_rows(v)]
    lines = [f"against the {v['sensor']} section of the datasheet {v['part']}"
             + (f" ({v['source']})" if v["source"] else "") + ":",
             table(["term", "datasheet", "measured", "ci95_low", "ci95_high", "unit", "verdict"],
                   rows)]
    lines += [f"  {r['term']}: {r['note']}" for r in v["rows"] if r.get("note")]
    lines.append(f"  rule: {v['rule']}")
    return "\n".join(lines)


# -- a fit --------------------------------------------------------------------------------------
def fit_warnings(res: Any) -> list[str]:
    """The fit's warnings, less the non-convergence one of a fit that did not converge (the
    command reports that with its own line and exit status 3)."""
    return [str(w) for w in res.warnings if res.converged or "converge" not in w.lower()]


def fit_json(res: Any, *, source: str, units: str, datasheet: dict, check: Any = None,
             verdict: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """``gmwm fit --json`` of one fit: the result's ``to_json_dict()`` with the command's keys
    (``command``, ``input``, ``units``, ``datasheet``; ``check``: the identifiability report;
    ``datasheet_verdict`` without its curves) and the warnings of :func:`fit_warnings`."""
    obj = {"command": "fit", "input": source, **res.to_json_dict(),
           "warnings": fit_warnings(res), "units": units or None, "datasheet": datasheet}
    if check is not None:
        obj["check"] = check.to_json_dict()
    if verdict is not None:
        obj["datasheet_verdict"] = {k: v for k, v in verdict.items() if k != "curves"}
    return obj


def fit_text(res: Any, *, source: str, name: str | None, units: str, datasheet: dict,
             check: Any = None, verdict: Mapping[str, Any] | None = None) -> str:
    """``gmwm fit`` of one fit as text: the estimates with standard errors and 95 % intervals
    (``res.conf_int``; '-' where there is none), the datasheet coefficients, the objective,
    convergence and timings, the goodness-of-fit line, the identifiability check and the
    datasheet verdict."""
    s = res.settings
    avsm = s.method == "avsm"  # AVSM minimises nothing and has no test of fit
    how = "AVSM" if avsm else f"{s.method.upper()} ({s.weights_kind} weights)"
    what = source if name is None else f"{name} of {source}"
    lines = [(f"{how} fit of {res.model.spec} to {what}: T = {res.wv.n_samples} samples, "
              f"J = {res.wv.n_levels} scales, freq = {res.wv.freq:g} Hz")]
    rows = [(n, float(p), finite_or_none(se), finite_or_none(lo), finite_or_none(hi))
            for n, p, se, (lo, hi) in zip(res.param_names, res.params, res.se, res.conf_int(0.05),
                                          strict=True)]
    lines.append(table(["parameter", "estimate", "se", "ci95_low", "ci95_high"], rows))
    ds_rows = datasheet_rows(datasheet)
    if ds_rows:
        lines.append(f"datasheet coefficients (signal in {units or 'signal units'}):")
        lines.append(table(["term", "quantity", "value", "ci95_low", "ci95_high", "unit"],
                           [(t, q, v, *(ci or [None, None]), u) for t, q, v, ci, u in ds_rows]))
    lines.append(f"objective {fmt(None if avsm else res.objective)}, converged "
                 f"{'yes' if res.converged else 'NO'}; WV {seconds(res.seconds_wv)}, "
                 f"fit {seconds(res.seconds_fit)}")
    if not avsm:
        lines.append(res.gof_line())
    if check is not None:
        lines.append(check.summary())
    if verdict is not None:
        lines.append(verdict_text(verdict))
    return "\n".join(lines)


# -- stationarity -------------------------------------------------------------------------------
def spans(st: Any, segments: Sequence[Any], limit: int = 4, more: str = "more") -> str:
    """The time ranges of flagged ``segments`` of a :class:`gmwm.stationarity.StationarityReport`,
    the first ``limit`` of them, then 'and N more'."""
    text = ", ".join(st.span(s.start_s, s.end_s) for s in segments[:limit])
    return text + (f" and {len(segments) - limit} {more}" if len(segments) > limit else "")
