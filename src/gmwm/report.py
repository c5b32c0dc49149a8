"""Calibration report of an IMU: one Markdown page and one HTML page over all its axes.

First the stationarity check of the recording (``docs/METHODS.md`` §16): a warning naming the
time ranges that moved, the part of the recording used and a timeline figure with the flagged
ranges. Per axis: the empirical WV with the fitted model and its components (PNG), the
goodness-of-fit line (:mod:`gmwm.gof`), the datasheet coefficients with 95 % CIs
(:func:`gmwm.datasheet.datasheet`), the IEEE 952 Allan-deviation readings of the same data (bias
instability included) and the fit's warnings (a rejected model among them); with a sensor
datasheet (``axes[name]["verdict"]`` from :func:`gmwm.sensor_datasheet.judge`) also the datasheet's
WV and Allan deviation beside the measured ones and a verdict table (within / better / worse, with
the rule); at the end the Kalibr ``imu.yaml`` (:mod:`gmwm.exports`), also written alone with the
other filter configuration files asked for. Every file is written atomically.
"""

from __future__ import annotations

import html
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gmwm import __version__
from gmwm.cli.format import (
    datasheet_rows,
    html_table,
    interval,
    md_table,
    num,
    reading_rows,
    verdict_rows,
)
from gmwm.datasheet import allan_readings
from gmwm.errors import InputError

__all__ = ["write_report"]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "axis"


def _rows(ds: Mapping[str, dict]) -> list[tuple[str, str, str, str, str]]:
    """(term, quantity, value, 95 % CI, unit) rows of a datasheet dict."""
    return [(term, what.replace("_", " "), num(value), interval(ci), unit or "–")
            for term, what, value, ci, unit in datasheet_rows(ds)]


def _reading_rows(res: Any, units: str | None) -> list[tuple[str, str, str, str, str]]:
    """IEEE 952 readings (N, K, B) of the fit's WV, for comparison with the GMWM coefficients."""
    from gmwm.wv import AllanVariance

    try:
        r = allan_readings(AllanVariance.from_wv(res.wv), units or None)
    except InputError:
        return []
    return [(label, num(value), interval(ci), unit, where)
            for label, value, ci, unit, where in reading_rows(r, brief=True)]


def _axis_warnings(a: Mapping[str, Any]) -> list[str]:
    """The axis's warnings, with the fit's rejected-model warning (:meth:`gmwm.gof.GOFResult.warning`)
    even if the caller's list lacks it: a page never shows "No warnings" over a rejected model."""
    found = [str(w) for w in a["warnings"]]
    gof = getattr(a["result"], "gof", None)
    note = gof.warning() if gof is not None else None
    if note is not None and note not in found:
        found.append(note)
    return found


def _gof_line(res: Any) -> str | None:
    line = getattr(res, "gof_line", None)
    return line() if callable(line) else None


def _verdict_rows(v: Mapping[str, Any]) -> list[tuple[str, str, str, str, str, str]]:
    """(term, datasheet, measured, 95 % CI, unit, verdict) rows of a datasheet verdict."""
    return [(term, num(ds), num(measured), interval(ci), unit, verdict)
            for term, ds, measured, ci, unit, verdict in verdict_rows(v, readable=True)]


def _stationarity_section(st: Any, out: Path) -> tuple[list[str], list[str], list[Path]]:
    """Markdown lines, HTML parts and files of the stationarity section (timeline figure)."""
    from gmwm.atomic import save_figure
    from gmwm.plots import plot_stationarity

    unit = "s" if st.freq else "samples"
    intro = (f"Windowed means of every axis (and of the accelerometer norm |a|) at window lengths "
             f"{', '.join(f'{L / (st.freq or 1.0):.3g}' for L in st.windows)} {unit}, the "
             "windowed noise level and, for known units, a static ceiling; "
             f"{st.n_tests} tests at a family-wise false-alarm level of {st.alpha:g}.")
    verdict = ("**Not static**: the ranges below moved, stepped, drifted or shook beyond what a "
               "static noise model explains." if st.moving else
               "No range is flagged: the recording looks static.")
    used = f"The estimate uses {st.used_text()}."
    md = ["## Stationarity", "", verdict + " " + used, "", intro, ""]
    plain = html.escape(verdict.replace("**", ""))
    body = ["<h2>Stationarity</h2>", f"<p>{plain} {html.escape(used)}</p>",
            f"<p>{html.escape(intro)}</p>"]
    rows = []
    for s in st.segments:
        fl = [f for f in st.flags if f.i1 > s.i0 and f.i0 < s.i1]
        best = max(fl, key=lambda f: f.stat / f.threshold)
        u = st.units.get(best.channel) or ""
        size = (f"{best.size:.3g}x median noise" if best.test == "noise"
                else f"{best.size:.3g} {u}".strip())
        a, b = st.used or (0, st.n)
        rows.append((f"{st.fmt_time(s.start_s)}-{st.fmt_time(s.end_s)}", ", ".join(s.channels),
                     ", ".join(s.tests),
                     size, f"{best.stat:.3g} / {best.threshold:.3g}",
                     f"{best.window_s:.3g}", "yes" if s.i1 > a and s.i0 < b else "no"))
    if rows:
        th = [f"range [{unit}]", "channels", "tests", "largest change", "statistic / threshold",
              f"window [{unit}]", "in the part used"]
        md += md_table(th, rows) + [""]
        body.append(html_table(th, rows))
    t = st.temperature
    if t is not None:
        line = (f"Temperature {t.range_c[0]:.3g}-{t.range_c[1]:.3g} °C"
                + (f" ({t.source})" if t.source else "") + ": the bias follows it in "
                + (", ".join(t.following) if t.following else "no axis") + ".")
        md += [line, ""]
        body.append(f"<p>{html.escape(line)}</p>")
    for n in (*st.alerts, *st.notes):
        md += [f"- {n}"]
        body.append(f"<p>{html.escape(n)}</p>")
    if st.alerts or st.notes:
        md.append("")
    files: list[Path] = []
    if st.tested and st.timeline:
        png = out / "stationarity.png"
        files += save_figure(plot_stationarity(st), png)
        md += [f"![Timeline of every axis, flagged ranges shaded]({png.name})", ""]
        body.append(f'<img src="{png.name}" alt="stationarity timeline" width="700">')
    return md, body, files


def write_report(outdir: str | os.PathLike, axes: Mapping[str, Mapping[str, Any]], *, source: str,
                 title: str, timing: list[str] | None = None, stationarity: Any = None,
                 topic: str | None = None, targets: str | Sequence[str] = ("kalibr",),
                 inflation: Any = None) -> list[Path]:
    """Write ``report.md``, ``report.html``, the filter configuration files of ``targets``
    (:func:`gmwm.exports.parse_targets`; default the Kalibr ``imu.yaml``) and one
    ``<axis>_wv.png`` per axis to ``outdir``; return the paths.

    ``axes[name]`` holds ``result`` (a GMWM fit), ``units`` (signal unit; deg/s or rad/s mark a
    gyroscope, m/s^2 or g an accelerometer), ``warnings`` (list of str), ``datasheet`` and
    optionally ``verdict`` (a sensor datasheet's judgement, :func:`gmwm.sensor_datasheet.judge`;
    adds ``<axis>_adev.png`` and the verdict table).
    ``timing``: lines on the recording's time base (rate source, jitter, gaps, gap policy).
    ``stationarity``: a :class:`gmwm.stationarity.StationarityReport` (its ``used`` range set):
    a warning at the top when it flags the part used, a section with the timeline figure.
    ``topic``: the IMU's ROS topic (written as ``rostopic``); ``inflation``: e.g.
    ``"noise=2,walk=10"`` (:func:`gmwm.exports.parse_inflation`). Without any gyroscope or
    accelerometer unit no configuration file is written and the report says why.
    """
    from gmwm.atomic import save_figure, write_text_atomic
    from gmwm.exports import kalibr_text, noise_export, parse_targets, write_exports
    from gmwm.plots import add_datasheet_line, plot_av, plot_wv
    from gmwm.wv import AllanVariance

    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise InputError(f"report directory {out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    if not axes:
        raise InputError("the report needs at least one axis")
    freq = float(next(iter(axes.values()))["result"].wv.freq)
    # the configuration files' inputs are checked before any file is written
    names = parse_targets(targets)
    exp = None
    if any(a["units"] for a in axes.values()):
        exp = noise_export({n: (a["units"], a["result"]) for n, a in axes.items()}, freq,
                           topic=topic, inflation=inflation, source=source)
    written: list[Path] = []
    md = [f"# {title}", "",
          (f"Input `{source}`, sampling frequency {freq:g} Hz, {len(axes)} axes; "
           f"GMWM fits by gmwm {__version__}. Coefficients are continuous-time datasheet values "
           "with 95 % intervals inside the parameter space (a coefficient not distinguishable "
           "from zero has an interval from 0); per-sample parameters are in the JSON output."),
          ""]
    body: list[str] = [f"<h1>{html.escape(title)}</h1>",
                       (f"<p>Input <code>{html.escape(source)}</code>, sampling frequency {freq:g} "
                        f"Hz, {len(axes)} axes; GMWM fits by gmwm {html.escape(__version__)}.</p>")]
    st = stationarity
    if st is not None and (st.moving or st.alerts):
        lines = st.warnings(limit=10)
        md += ["> **Warning: the recording is not static.**" if st.moving else
               "> **Warning.**", *[f"> - {w}" for w in lines], ""]
        body.append('<div style="border:2px solid #D55E00;padding:.5em 1em"><strong>Warning: '
                    + ("the recording is not static." if st.moving else "") + "</strong><ul>"
                    + "".join(f"<li>{html.escape(w)}</li>" for w in lines) + "</ul></div>")
    if timing:
        md += ["## Time base", "", *[f"- {t}" for t in timing], ""]
        body += ["<h2>Time base</h2>",
                 "<ul>" + "".join(f"<li>{html.escape(t)}</li>" for t in timing) + "</ul>"]
    if st is not None:
        smd, sbody, sfiles = _stationarity_section(st, out)
        md += smd
        body += sbody
        written += sfiles
    summary = []
    for name, a in axes.items():
        res = a["result"]
        ds = a["datasheet"]
        white = next((v for k, v in ds.items() if k.split("[")[0] in ("ARW", "VRW", "WN")), None)
        rw = next((v for k, v in ds.items() if k.split("[")[0] in ("RRW", "AccRW", "RW")), None)
        summary.append((name, a["units"] or "–", res.model.spec,
                        "–" if white is None else f"{num(white['value'])} {white['unit']}",
                        "–" if rw is None else f"{num(rw['value'])} {rw['unit']}",
                        len(_axis_warnings(a))))
    headers = ["axis", "unit", "model", "white noise", "random walk", "warnings"]
    md += ["## Summary", "", *md_table(headers, summary), ""]
    body += ["<h2>Summary</h2>", html_table(headers, summary)]
    for name, a in axes.items():
        res = a["result"]
        png = out / f"{_slug(name)}_wv.png"
        ax = plot_wv(res.wv, result=res, units=a["units"] or "")
        ax.set_title(f"{name}: {res.model.spec}")
        verdict = a.get("verdict")
        if verdict is not None:
            c = verdict["curves"]
            add_datasheet_line(ax, c["scales_s"], c["wv"], verdict["label"])
        written += save_figure(ax.figure, png)
        rows = _rows(a["datasheet"])
        th = ["term", "quantity", "value", "95% CI", "unit"]
        md += [f"## {name}", "",
               (f"Model `{res.model.spec}`, T = {res.wv.n_samples} samples, J = {res.wv.n_levels} "
                f"scales, objective {float(getattr(res, 'objective', float('nan'))):.4g}, converged "
                f"{'yes' if getattr(res, 'converged', True) else 'NO'}."), "",
               f"![WV of {name} with the fitted model]({png.name})", "", *md_table(th, rows), ""]
        body += [f"<h2>{html.escape(name)}</h2>",
                 (f"<p>Model <code>{html.escape(res.model.spec)}</code>, T = {res.wv.n_samples} "
                  f"samples, J = {res.wv.n_levels} scales.</p>"),
                 f'<img src="{html.escape(png.name)}" alt="WV of {html.escape(name)}" width="560">',
                 html_table(th, rows)]
        if verdict is not None:
            adev_png = out / f"{_slug(name)}_adev.png"
            ax = plot_av(AllanVariance.from_wv(res.wv), deviation=True, units=a["units"] or "")
            add_datasheet_line(ax, verdict["curves"]["tau_s"], verdict["curves"]["adev"],
                               verdict["label"])
            ax.set_title(f"{name}: Allan deviation")
            written += save_figure(ax.figure, adev_png)
            vh = ["term", "datasheet", "measured", "95% CI", "unit", "verdict"]
            vrows = _verdict_rows(verdict)
            src = f" ({verdict['source']})" if verdict["source"] else ""
            head = f"Against the {verdict['sensor']} section of the datasheet {verdict['part']}{src}:"
            notes = [f"{r['term']}: {r['note']}" for r in verdict["rows"] if r.get("note")]
            rule = f"Rule: {verdict['rule']}."
            md += [head, "", f"![Allan deviation of {name} and the datasheet's]({adev_png.name})",
                   "", *md_table(vh, vrows), "", *(f"- {n}" for n in notes), f"- {rule}", ""]
            body += [f"<p>{html.escape(head)}</p>",
                     (f'<img src="{html.escape(adev_png.name)}" alt="Allan deviation of '
                      f'{html.escape(name)}" width="560">'), html_table(vh, vrows),
                     "<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in [*notes, rule])
                     + "</ul>"]
        readings = _reading_rows(res, a["units"])
        if readings:
            rh = ["IEEE 952 reading", "value", "95% CI", "unit", "from"]
            md += ["Allan-deviation readings of the same data (slope method, for comparison):", "",
                   *md_table(rh, readings), ""]
            body += [("<p>Allan-deviation readings of the same data (slope method, for "
                      "comparison):</p>"), html_table(rh, readings)]
        gof = _gof_line(res)
        if gof is not None:  # after the figure and table, before the warnings
            md += [gof[0].upper() + gof[1:] + ".", ""]
            body += [f"<p>{html.escape(gof[0].upper() + gof[1:])}.</p>"]
        warns = _axis_warnings(a)
        if warns:
            md += ["Warnings:", "", *(f"- {w}" for w in warns), ""]
            body += ["<p>Warnings:</p><ul>"
                     + "".join(f"<li>{html.escape(w)}</li>" for w in warns) + "</ul>"]
        else:
            md += ["No warnings.", ""]
            body += ["<p>No warnings.</p>"]
    if exp is not None:
        yaml = kalibr_text(exp).rstrip("\n")
        md += ["## Noise densities (Kalibr imu.yaml)", "", "```yaml", yaml, "```", ""]
        body += ["<h2>Noise densities (Kalibr imu.yaml)</h2>", f"<pre>{html.escape(yaml)}</pre>"]
    else:
        why = ("No filter configuration file (imu.yaml): no axis has a gyroscope or accelerometer "
               "unit, so neither the sensor nor the SI scale is known (give --units).")
        md += ["## Noise densities", "", why, ""]
        body += ["<h2>Noise densities</h2>", f"<p>{html.escape(why)}</p>"]
    style = ("body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;"
             "padding:.2em .6em;text-align:right}th{background:#f4f4f4}pre{background:#f8f8f8;"
             "padding:1em}")
    page = (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}"
            f"</title><style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
    written.append(write_text_atomic(out / "report.md", "\n".join(md)))
    written.append(write_text_atomic(out / "report.html", page))
    if exp is not None and names:
        written += write_exports(exp, out, names)
    return written
