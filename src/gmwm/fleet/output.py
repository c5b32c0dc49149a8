"""The fleet table written out: ``fleet.csv`` (per unit and coefficient), ``fleet_summary.csv``
(per coefficient), ``fleet.md``, ``fleet.json`` (for scripts) and ``fleet.html`` (the figures
embedded), all written atomically. Terms left out of the fleet fit (at the boundary, not
identifiable, ...) appear with their reason and no number."""

from __future__ import annotations

import base64
import csv
import html
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm.fleet.collect import UNIT_RULE, Recording, estimates_from_folder
from gmwm.fleet.core import Fleet, fleet_table

__all__ = ["archive", "build_and_write", "build_fleet", "write_compare", "write_fleet"]

_UNIT_COLUMNS = ("unit", "recording", "date", "temperature_c", "coefficient", "sensor",
                 "value_unit", "value", "ci95_low", "ci95_high", "status", "reason",
                 "datasheet_verdict")
#: said in fleet.json (and the notes) when the manifest gives temperatures
TEMPERATURE_NOTE = ("temperature_c: the manifest's temperature of each recording [deg C], "
                    "recorded beside its values; the fleet estimates do not model it")
#: fleets up to this many units get one named row per unit in the figures
_LABELLED_UNITS = 60
_SUMMARY_COLUMNS = ("coefficient", "sensor", "value_unit", "n_units", "typical",
                    "typical_ci95_low", "typical_ci95_high", "tau_log", "tau_log_ci95_low",
                    "tau_log_ci95_high", "spread_factor", "prediction95_low",
                    "prediction95_high", "i2", "excluded_units", "datasheet_value",
                    "datasheet_verdict")


def build_fleet(out: Path, recordings: Sequence[Recording], method: str = "pm",
                alpha: float = 0.05) -> Fleet:
    """The fleet table from the calibration folders ``OUT/units/<unit>/<recording>/``."""
    estimates, failed = [], []
    for r in recordings:
        ests, why = estimates_from_folder(out / "units" / r.unit / r.name, r)
        if why:
            failed.append((r.unit, r.name, why))
        estimates.extend(ests)
    fleet = fleet_table(estimates, method=method, alpha=alpha, failed=failed)
    fleet.notes.append(UNIT_RULE)
    return fleet


def _g(x: float | None) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.4g}"


def _temperatures(recordings: Sequence[Recording]) -> dict[tuple[str, str], float]:
    """(unit, recording) -> the manifest's temperature [deg C], for the recordings that give
    one. Recorded beside each value, not modelled: the fleet estimates ignore it."""
    return {(r.unit, r.name): r.temperature for r in recordings if r.temperature is not None}


def _unit_rows(fleet: Fleet, temps: Mapping[tuple[str, str], float] | None = None
               ) -> list[dict[str, Any]]:
    rows = []
    for v in fleet.verdicts:
        e = v.estimate
        num = e.usable
        t = (temps or {}).get((e.unit, e.recording))
        rows.append({"unit": e.unit, "recording": e.recording,
                     "date": e.date.isoformat() if e.date else "",
                     "temperature_c": "" if t is None else f"{t:g}",
                     "coefficient": e.coefficient,
                     "sensor": e.sensor, "value_unit": e.value_unit,
                     "value": _g(e.value) if num else "",
                     "ci95_low": _g(e.ci95[0]) if num and e.ci95 else "",
                     "ci95_high": _g(e.ci95[1]) if num and e.ci95 else "",
                     "status": v.status, "reason": v.reason,
                     "datasheet_verdict": e.datasheet or ""})
    return rows


def _summary_rows(fleet: Fleet) -> list[dict[str, Any]]:
    rows = []
    for c in fleet.coefficients.values():
        f = c.fit
        tci, pi = c.typical_ci, c.prediction
        rows.append({"coefficient": c.coefficient, "sensor": c.sensor,
                     "value_unit": c.value_unit, "n_units": c.n_units,
                     "typical": _g(c.typical), "typical_ci95_low": _g(tci[0]) if tci else "",
                     "typical_ci95_high": _g(tci[1]) if tci else "",
                     "tau_log": _g(f.tau) if f else "",
                     "tau_log_ci95_low": _g(f.ci_tau[0]) if f else "",
                     "tau_log_ci95_high": _g(f.ci_tau[1]) if f else "",
                     "spread_factor": _g(math.exp(f.tau)) if f else "",
                     "prediction95_low": _g(pi[0]) if pi else "",
                     "prediction95_high": _g(pi[1]) if pi else "",
                     "i2": _g(f.i2) if f else "",
                     "excluded_units": _excluded_text(c.excluded),
                     "datasheet_value": _g(c.datasheet_value),
                     "datasheet_verdict": c.datasheet_verdict or ""})
    return rows


def _excluded_text(excluded: Sequence[tuple[str, str]], shown: int = 5) -> str:
    """The units left out of a coefficient's fit, grouped by reason: 'reason: n units (a, b,
    ...)' (the full list is in fleet.csv and fleet.json)."""
    by: dict[str, list[str]] = {}
    for u, r in excluded:
        by.setdefault(r, []).append(u)
    return "; ".join(f"{r}: {len(us)} unit{'s' if len(us) > 1 else ''} ("
                     + ", ".join(us[:shown]) + (", ..." if len(us) > shown else "") + ")"
                     for r, us in by.items())


def _csv(rows: list[dict[str, Any]], columns: Sequence[str]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def _md_table(rows: list[dict[str, Any]], columns: Sequence[str]) -> str:
    if not rows:
        return "(none)\n"
    head = "| " + " | ".join(columns) + " |\n|" + "---|" * len(columns) + "\n"
    return head + "".join("| " + " | ".join(str(r[c]).replace("|", "/") for c in columns)
                          + " |\n" for r in rows)


_METHOD = ("Random-effects model on the log scale ({method}; tau: between-unit standard deviation "
           "of log(value), units typically differ by the factor exp(tau); tau's 95 % interval "
           "by the Q-profile method); a unit's standard error from its own 95 % interval. Out "
           "of family: the unit's 95 % interval lies outside the fleet's 95 % prediction "
           "interval for a new unit (computed without that unit for fleets up to 500 units); "
           "it is a 95 % band, so in a large fleet a few ordinary units (up to about 5 % when "
           "their own intervals are narrow) fall outside it by chance: the reason says how far. "
           "Each unit enters with its latest recording; drift: weighted least squares of "
           "log(value) on the date, per year.")


def _sections(fleet: Fleet) -> dict[str, Any]:
    method = {"pm": "Paule-Mandel", "dl": "DerSimonian-Laird"}.get(fleet.method, fleet.method)
    drift_rows = [{"unit": d.unit, "coefficient": d.coefficient, "recordings": d.n,
                   "from": d.first.isoformat(), "to": d.last.isoformat(),
                   "percent_per_year": f"{d.percent_per_year[0]:+.3g}",
                   "ci95": f"[{d.percent_per_year[1]:+.3g}, {d.percent_per_year[2]:+.3g}]",
                   "drifts": "yes" if d.flagged else "no"} for d in fleet.drifts]
    return {"method": _METHOD.format(method=method),
            "out": [{"unit": v.estimate.unit, "recording": v.estimate.recording,
                     "reason": v.reason} for v in fleet.out_of_family],
            "drift": drift_rows,
            "failed": [{"unit": u, "recording": r, "reason": why} for u, r, why in fleet.failed]}


def _markdown(fleet: Fleet, title: str, temps: Mapping[tuple[str, str], float]) -> str:
    s = _sections(fleet)
    units = fleet.units
    lines = [f"# {title}\n",
             (f"{len(units)} units, {len(fleet.failed)} recordings failed, "
              f"{len({v.estimate.unit for v in fleet.out_of_family})} units out of family, "
              f"{sum(d.flagged for d in fleet.drifts)} drifting coefficients.\n"),
             s["method"] + "\n", "## Fleet, per coefficient\n",
             _md_table(_summary_rows(fleet), _SUMMARY_COLUMNS),
             "\n## Out-of-family units\n", _md_table(s["out"], ("unit", "recording", "reason")),
             "\n## Drift per year (units with recordings on several dates)\n",
             _md_table(s["drift"], ("unit", "coefficient", "recordings", "from", "to",
                                    "percent_per_year", "ci95", "drifts")),
             "\n## Recordings that failed\n",
             _md_table(s["failed"], ("unit", "recording", "reason")),
             "\n## Units, per coefficient\n", _md_table(_unit_rows(fleet, temps), _UNIT_COLUMNS),
             "\n" + "\n".join(f"- {n}" for n in fleet.notes) + "\n"]
    return "\n".join(lines)


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _figures(fleet: Fleet) -> list[tuple[str, str]]:
    """(caption, base64 PNG): per coefficient the units sorted with their intervals over the
    fleet's prediction band; per drifting unit its dated values and fitted line."""
    from matplotlib.figure import Figure

    out = []
    by_coef: dict[str, list[Any]] = {}
    for v in fleet.verdicts:
        if v.estimate.usable:
            by_coef.setdefault(v.estimate.coefficient, []).append(v)
    for coef, vs in by_coef.items():
        c = fleet.coefficients[coef]
        vs = sorted(vs, key=lambda v: v.estimate.value)
        many = len(vs) > _LABELLED_UNITS  # a large fleet: one point per unit, no names
        fig = Figure(figsize=(7, 0.8 + 0.22 * min(len(vs), _LABELLED_UNITS)))
        ax = fig.subplots()
        pi = c.prediction
        if pi is not None:
            ax.axvspan(pi[0], pi[1], color="tab:blue", alpha=0.12,
                       label="fleet 95 % prediction interval")
            ax.axvline(c.typical, color="tab:blue", lw=1, label="fleet typical value")
        for i, v in enumerate(vs):
            e = v.estimate
            col = "tab:red" if v.status == "out of family" else "black"
            ax.errorbar([e.value], [i], xerr=[[e.value - e.ci95[0]], [e.ci95[1] - e.value]],
                        fmt="o", ms=1.5 if many else 3, lw=0.5 if many else 1, color=col,
                        capsize=0 if many else 2)
        if many:
            ax.set_yticks([])
            ax.set_ylabel(f"{len(vs)} units, sorted")
        else:
            ax.set_yticks(range(len(vs)), [v.estimate.unit for v in vs], fontsize=7)
        ax.set_xscale("log")
        # the units set the range: a band wider than them (few units) runs off the axes
        lo = min(v.estimate.ci95[0] for v in vs)
        hi = max(v.estimate.ci95[1] for v in vs)
        if c.typical is not None:
            lo, hi = min(lo, c.typical), max(hi, c.typical)
        ax.set_xlim(lo / 2.0, hi * 2.0)
        ax.set_xlabel(f"{coef} [{c.value_unit}]" if c.value_unit else coef)
        if pi is not None:
            ax.legend(fontsize=7, loc="best")
        out.append((f"{coef}: each unit with its 95 % interval (red: out of family)", _png(fig)))
    for d in fleet.drifts:
        if not d.flagged:
            continue
        import datetime as _dt

        fig = Figure(figsize=(6, 3))
        ax = fig.subplots()
        dates = [_dt.date.fromisoformat(p[0]) for p in d.points]
        vals = [p[1] for p in d.points]
        ax.errorbar(dates, vals, yerr=[[v - p[2] for v, p in zip(vals, d.points, strict=True)],
                                       [p[3] - v for v, p in zip(vals, d.points, strict=True)]],
                    fmt="o", color="black", capsize=2)
        t = [(x - d.first).days / 365.25 for x in dates]
        ax.plot(dates, [math.exp(d.intercept + d.slope * x) for x in t], color="tab:red")
        ax.set_yscale("log")
        pct = d.percent_per_year
        ax.set_title(f"{d.unit} {d.coefficient}: {pct[0]:+.3g} %/year "
                     f"[{pct[1]:+.3g}, {pct[2]:+.3g}]", fontsize=9)
        fig.autofmt_xdate()
        out.append((f"drift of {d.unit} {d.coefficient}", _png(fig)))
    return out


def _html_table(rows: list[dict[str, Any]], columns: Sequence[str]) -> str:
    if not rows:
        return "<p>(none)</p>"
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r[c]))}</td>" for c in columns)
                   + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _html(fleet: Fleet, title: str) -> str:
    s = _sections(fleet)
    figs = "".join(f"<figure><img src='data:image/png;base64,{b}'><figcaption>"
                   f"{html.escape(c)}</figcaption></figure>" for c, b in _figures(fleet))
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>{html.escape(title)}</title><style>body{{font-family:sans-serif;"
            "max-width:1100px;margin:auto}table{border-collapse:collapse;font-size:12px}"
            "td,th{border:1px solid #ccc;padding:2px 5px}figure{display:inline-block}"
            "</style></head><body>"
            f"<h1>{html.escape(title)}</h1><p>{html.escape(s['method'])}</p>"
            "<h2>Fleet, per coefficient</h2>" + _html_table(_summary_rows(fleet), _SUMMARY_COLUMNS)
            + "<h2>Out-of-family units</h2>" + _html_table(s["out"], ("unit", "recording",
                                                                       "reason"))
            + "<h2>Drift per year</h2>" + _html_table(s["drift"], (
                "unit", "coefficient", "recordings", "from", "to", "percent_per_year", "ci95",
                "drifts"))
            + "<h2>Recordings that failed</h2>" + _html_table(s["failed"], ("unit", "recording",
                                                                           "reason"))
            + "<h2>Figures</h2>" + figs
            + "<h2>Units, per coefficient</h2>" + _html_table(_unit_rows(fleet), _UNIT_COLUMNS)
            + "<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in fleet.notes) + "</ul>"
            + "</body></html>\n")


def write_fleet(out: Path, fleet: Fleet, *, settings: dict[str, Any] | None = None,
                title: str = "Fleet calibration", recordings: Sequence[Recording] = ()
                ) -> list[Path]:
    """Write the fleet table's files into ``out`` (atomically; fleet.json last, as the
    workflow's marker); return their paths. ``recordings``: their manifest temperatures
    [deg C] are carried beside each value (``temperature_c``; recorded only, not modelled)."""
    temps = _temperatures(recordings)
    if temps and TEMPERATURE_NOTE not in fleet.notes:
        fleet.notes.append(TEMPERATURE_NOTE)
    files = [write_text_atomic(out / "fleet.csv", _csv(_unit_rows(fleet, temps), _UNIT_COLUMNS)),
             write_text_atomic(out / "fleet_summary.csv",
                               _csv(_summary_rows(fleet), _SUMMARY_COLUMNS)),
             write_text_atomic(out / "fleet.md", _markdown(fleet, title, temps)),
             write_text_atomic(out / "fleet.html", _html(fleet, title))]
    obj = fleet.to_json_dict() | {"settings": settings or {}}
    for row in obj.get("units", []):
        row["temperature_c"] = temps.get((row["unit"], row["recording"]))
    files.append(write_json_atomic(out / "fleet.json", obj))
    return files


def _versions() -> dict[str, str | None]:
    import importlib.metadata as md
    import platform

    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in ("gmwm", "numpy", "scipy", "statsmodels", "snakemake", "matplotlib"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            out[name] = None
    return out


def archive(out: Path, config: dict[str, Any] | None, settings: dict[str, Any]) -> Path:
    """Archive this table in ``OUT/archive/<UTC time>/``: fleet.json, the settings, every input's
    path and content hash, the package versions (``gmwm fleet --compare`` reads it)."""
    import datetime as _dt

    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%S.%fZ")
    dest = out / "archive" / stamp
    write_json_atomic(dest / "settings.json", settings)
    write_json_atomic(dest / "inputs.json",
                      {k: {"path": r["path"], "sha256": r["sha256"], "date": r["date"]}
                       for k, r in (config or {}).get("recordings", {}).items()})
    write_json_atomic(dest / "versions.json", _versions())
    write_text_atomic(dest / "fleet.json", (out / "fleet.json").read_text(encoding="utf-8"))
    return dest


def build_and_write(out: Path, recordings: Sequence[Recording], settings: Any,
                    config: dict[str, Any] | None = None) -> list[Path]:
    """:func:`build_fleet`, :func:`write_fleet` and :func:`archive` (the workflow's table
    job)."""
    fleet = build_fleet(out, recordings, settings.method_re)
    files = write_fleet(out, fleet, settings=settings.to_json(), recordings=recordings)
    archive(out, config, settings.to_json())
    return files


_COMPARE_COLUMNS = ("unit", "coefficient", "value_unit", "old_recording", "old_value",
                    "old_ci95", "new_recording", "new_value", "new_ci95", "ratio", "z", "moved")


def write_compare(out: Path, rows: list[dict[str, Any]], against: str) -> list[Path]:
    """``compare.csv``, ``compare.md`` and ``compare.json``: every unit and coefficient
    estimated in both runs, ``moved`` where the change exceeds its 95 % interval."""
    def fmt(r: dict[str, Any]) -> dict[str, Any]:
        return {c: (f"[{_g(r[c][0])}, {_g(r[c][1])}]" if c.endswith("ci95") else
                    _g(r[c]) if isinstance(r[c], float) else
                    ("yes" if r[c] else "no") if c == "moved" else r[c]) for c in _COMPARE_COLUMNS}

    moved = [fmt(r) for r in rows if r["moved"]]
    md = (f"# Fleet compared with {against}\n\n"
          "Moved: the log ratio new/old exceeds 1.96 standard errors (each run's own 95 % "
          "interval); recordings shared by both runs are not compared.\n\n"
          f"## Moved ({len(moved)} of {len(rows)} compared)\n\n"
          + _md_table(moved, _COMPARE_COLUMNS)
          + "\n## All compared\n\n" + _md_table([fmt(r) for r in rows], _COMPARE_COLUMNS))
    return [write_text_atomic(out / "compare.csv", _csv([fmt(r) for r in rows],
                                                         _COMPARE_COLUMNS)),
            write_text_atomic(out / "compare.md", md),
            write_json_atomic(out / "compare.json", {"against": against, "rows": rows})]
