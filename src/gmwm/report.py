"""Calibration report of an IMU: one Markdown page and one HTML page over all its axes.

First the stationarity check of the recording (``docs/METHODS.md`` §16): a warning naming the
time ranges that moved, the part of the recording used and a timeline figure with the flagged
ranges. A summary: per sensor the values the configuration files carry (continuous-time SI
densities, a flagged term's 95 % upper bound marked, the fit's estimate beside it; one unit per
column), and the fits' estimates in datasheet units in tables of their own. Per axis: the
empirical WV with the fitted model and its components (PNG), the
goodness-of-fit line (:mod:`gmwm.gof`), the datasheet coefficients with 95 % CIs
(:func:`gmwm.datasheet.datasheet`), the IEEE 952 Allan-deviation readings of the same data (bias
instability included) and the fit's warnings (a rejected model among them); for a model chosen
by the data (``axes[name]["choice"]``, :func:`gmwm.automodel.choose_model`) the candidates'
ranking with their goodness-of-fit p-values (:func:`choice_section`); with a sensor
datasheet (``axes[name]["verdict"]`` from :func:`gmwm.sensor_datasheet.judge`) also the datasheet's
WV and Allan deviation beside the measured ones and a verdict table (within / better / worse, with
the rule); at the end the Kalibr ``imu.yaml`` (:mod:`gmwm.exports`), also written alone with the
other filter configuration files asked for. Every file is written atomically.
"""

from __future__ import annotations

import contextlib
import dataclasses
import html
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gmwm import __version__
from gmwm.datasheet import fit_readings
from gmwm.errors import InputError
from gmwm.formatting import (
    datasheet_rows,
    html_table,
    interval,
    md_table,
    num,
    reading_rows,
    verdict_rows,
)

__all__ = ["FigureDrawer", "ImuSection", "choice_section", "imu_folders", "report_dir",
           "write_calibration", "write_multi_report", "write_report"]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "axis"


def _rows(ds: Mapping[str, dict]) -> list[tuple[str, str, str, str, str]]:
    """(term, quantity, value, 95 % CI, unit) rows of a datasheet dict."""
    return [(term, what.replace("_", " "), num(value), interval(ci), unit or "–")
            for term, what, value, ci, unit in datasheet_rows(ds)]


def _reading_rows(res: Any, units: str | None, readings: Mapping[str, Any] | None = None
                  ) -> list[tuple[str, str, str, str, str]]:
    """IEEE 952 readings (N, K, B) of the fit's WV (``readings``: already computed,
    :func:`gmwm.datasheet.fit_readings`), for comparison with the GMWM coefficients."""
    r = fit_readings(res, units or None) if readings is None else readings
    if r is None:
        return []
    return [(label, num(value), interval(ci), unit, where)
            for label, value, ci, unit, where in reading_rows(r, brief=True)]


def _axis_warnings(a: Mapping[str, Any]) -> list[str]:
    """The axis's warnings, with the fit's rejected-model warning (:meth:`gmwm.gof.GOFResult.warning`)
    and an automatic choice's "every candidate rejected" warning (:attr:`gmwm.automodel.Choice.
    warnings`) even if the caller's list lacks them: a page never shows "No warnings" over a
    rejected model."""
    found = [str(w) for w in a["warnings"]]
    gof = getattr(a["result"], "gof", None)
    notes = [gof.warning() if gof is not None else None]
    choice = a.get("choice")
    if choice is not None and not choice.passed:
        notes.insert(0, choice.warnings[0])
    for note in notes:
        if note is not None and note not in found:
            found.append(note)
    return found


def choice_section(choice: Any) -> tuple[list[str], str]:
    """Markdown lines and HTML of an automatic model choice (:class:`gmwm.automodel.Choice`):
    the headline, the candidates' ranking with each one's goodness-of-fit p-value, the notes."""
    headers, rows = choice.table()
    head = choice.headline()
    head = head[0].upper() + head[1:] + "."
    rule = ("Candidates ranked by the criterion (best first); the chosen model is the best-ranked "
            f"one the goodness-of-fit test does not reject at {choice.alpha:g} (docs/METHODS.md "
            "§6.1).")
    md = [head, "", rule, "", *md_table(headers, rows), "", *(f"- {n}" for n in choice.notes)]
    if choice.notes:
        md.append("")
    body = (f"<p>{html.escape(head)}</p><p>{html.escape(rule)}</p>" + html_table(headers, rows)
            + ("<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in choice.notes) + "</ul>"
               if choice.notes else ""))
    return md, body


def _objective(res: Any) -> str:
    """The fit's objective for the page ("none" for the AVSM, which minimises nothing)."""
    return "none" if not math.isfinite(res.objective) else f"{res.objective:.4g}"


def _gof_line(res: Any) -> str | None:
    line = getattr(res, "gof_line", None)
    return line() if callable(line) else None


def _verdict_rows(v: Mapping[str, Any]) -> list[tuple[str, str, str, str, str, str]]:
    """(term, datasheet, measured, 95 % CI, unit, verdict) rows of a datasheet verdict."""
    return [(term, num(ds), num(measured), interval(ci), unit, verdict)
            for term, ds, measured, ci, unit, verdict in verdict_rows(v, readable=True)]


@dataclass(frozen=True)
class _Figure:
    """A figure of a report page, drawn by :func:`_render` (kind, target file, data)."""

    kind: str
    path: Path
    data: tuple[Any, ...]


#: zlib level of the report's PNG figures: the same pixels as the default level 6 in about half
#: the encoding time (a report's seven figures: ~0.2 s of CPU less), files ~10 % larger
PNG_LEVEL = 2


def _draw(fig: _Figure) -> list[Path]:
    """Draw and save one report figure (in a worker process or not)."""
    from gmwm.atomic import save_figure
    from gmwm.plots import add_datasheet_line, page_layout, plot_av, plot_stationarity, plot_wv
    from gmwm.wv import AllanVariance

    if fig.kind == "stationarity":
        return save_figure(page_layout(plot_stationarity(fig.data[0])), fig.path, tight=False,
                           png_level=PNG_LEVEL)
    if fig.kind == "wv-unfitted":
        name, wv, units = fig.data
        ax = plot_wv(wv, units=units)
        ax.set_title(f"{name}: WV (not fitted)")
        return save_figure(page_layout(ax.figure), fig.path, tight=False, png_level=PNG_LEVEL)
    name, res, units, verdict = fig.data
    if fig.kind == "wv":
        ax = plot_wv(res.wv, result=res, units=units)
        ax.set_title(f"{name}: {res.model.spec}")
        if verdict is not None:
            c = verdict["curves"]
            add_datasheet_line(ax, c["scales_s"], c["wv"], verdict["label"])
    else:
        ax = plot_av(AllanVariance.from_wv(res.wv), deviation=True, units=units)
        add_datasheet_line(ax, verdict["curves"]["tau_s"], verdict["curves"]["adev"],
                           verdict["label"])
        ax.set_title(f"{name}: Allan deviation")
    return save_figure(page_layout(ax.figure), fig.path, tight=False, png_level=PNG_LEVEL)


def wv_figure_path(outdir: str | os.PathLike, name: str, prefix: str = "") -> Path:
    """The file of axis ``name``'s WV figure on a report page in ``outdir``."""
    return Path(outdir) / f"{prefix}{_slug(name)}_wv.png"


def draw_wv_figure(path: str | os.PathLike, name: str, result: Any, units: str) -> list[Path]:
    """Draw axis ``name``'s WV figure of a page without a datasheet verdict (as
    :func:`write_report` would) into ``path`` (:func:`wv_figure_path`), e.g. in the worker that
    fitted the axis; returns the files written, for :func:`write_report`'s ``drawn``."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return _draw(_Figure("wv", Path(path), (name, result, units or "", None)))


def warm_up(stationarity: Any = None, outdir: str | os.PathLike | None = None,
            fit: bool = True) -> list[Path]:
    """Prepare this process for the rest of a report page while other processes fit the axes
    (the CLI calls it then, when this process would otherwise wait): draw the stationarity
    timeline of ``stationarity`` into ``outdir`` (it needs no fit; without a timeline a small
    figure is drawn in memory instead, which loads matplotlib, its fonts and math text for
    figure workers forked from this process later), then, with ``fit``, load the fitting stack
    and the compiled kernels of the datasheet's intervals (a tiny fit and its datasheet) that
    the page needs once the fits arrive (not needed when the workers compute the datasheets).
    The timeline comes first: it has the most to gain from running while the workers are still
    starting. Returns the figure files written, for :func:`write_report`'s ``drawn``. A failure
    only loses the head start, except in drawing the timeline, which is then left to
    :func:`write_report`."""
    import io

    import numpy as np

    drawn: list[Path] = []
    st = stationarity
    if st is not None and outdir is not None and st.tested and st.timeline:
        try:
            Path(outdir).mkdir(parents=True, exist_ok=True)
            drawn = _draw(_Figure("stationarity", Path(outdir) / "stationarity.png", (st,)))
        except Exception:  # noqa: BLE001 - write_report draws it then
            drawn = []
    else:
        with contextlib.suppress(Exception):
            from gmwm.plots import new_axes

            ax = new_axes()
            ax.loglog([1e-2, 1.0, 1e2], [1e-4, 1e-6, 1e-5], label="WV")
            ax.set_xlabel(r"Scale $\tau$ [s]")
            ax.legend()
            ax.figure.savefig(io.BytesIO(), format="png", dpi=40)
    if not fit:
        return drawn
    with contextlib.suppress(Exception):  # a warm-up is an optimisation only
        import gmwm
        from gmwm.datasheet import datasheet

        rng = np.random.default_rng(0)
        x = np.cumsum(rng.standard_normal(4096)) * 1e-3 + rng.standard_normal(4096)
        datasheet(gmwm.fit(x, "WN+GM+RW", freq=100.0), "rad/s")
    return drawn


def _render(figures: Sequence[_Figure], drawn: Sequence[Path] = ()) -> list[Path]:
    """Draw the figures of a page, in worker processes when there are several and more than one
    core (a figure costs ~0.5 s of matplotlib layout and rasterising, all of it in Python);
    ``drawn``: files already drawn (:func:`warm_up`), not drawn again."""
    from gmwm.calibrate import available_cores, executor

    todo = [fig for fig in figures if fig.path not in drawn]
    n = min(len(todo), available_cores())
    if n < 2:
        paths = [_draw(fig) for fig in todo]
    else:
        with executor("process", n) as pool:
            paths = list(pool.map(_draw, todo))
    done = dict(zip([fig.path for fig in todo], paths, strict=True))
    return [f for fig in figures for f in done.get(fig.path, [fig.path])]


def _stationarity_section(st: Any, out: Path, lv: int = 2, prefix: str = ""
                          ) -> tuple[list[str], list[str], list[_Figure]]:
    """Markdown lines, HTML parts and figures (to draw) of the stationarity section (timeline
    figure ``<prefix>stationarity.png``) under a heading of level ``lv``."""

    unit = "s" if st.freq else "samples"
    intro = (f"Windowed means of every axis (and of the accelerometer norm |a|) at window lengths "
             f"{', '.join(f'{L / (st.freq or 1.0):.3g}' for L in st.windows)} {unit}, the "
             "windowed noise level and, for known units, a static ceiling; "
             f"{st.n_tests} tests at a family-wise false-alarm level of {st.alpha:g}.")
    verdict = ("**Not static**: the ranges below moved, stepped, drifted or shook beyond what a "
               "static noise model explains." if st.moving else
               "No range is flagged: the recording looks static.")
    used = f"The estimate uses {st.used_text()}."
    md = [f"{'#' * lv} Stationarity", "", verdict + " " + used, "", intro, ""]
    plain = html.escape(verdict.replace("**", ""))
    body = [f"<h{lv}>Stationarity</h{lv}>", f"<p>{plain} {html.escape(used)}</p>",
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
    files: list[_Figure] = []
    if st.tested and st.timeline:
        png = out / f"{prefix}stationarity.png"
        files.append(_Figure("stationarity", png, (st,)))
        md += [f"![Timeline of every axis, flagged ranges shaded]({png.name})", ""]
        body.append(f'<img src="{png.name}" alt="stationarity timeline" width="700">')
    return md, body, files


@dataclass(frozen=True)
class ImuSection:
    """One IMU of a report: ``axes`` as :func:`write_report` takes them, ``timing`` lines,
    ``stationarity`` (a :class:`gmwm.stationarity.StationarityReport` with its ``used`` range),
    ``rostopic`` the ROS topic written into its configuration files (None: not a ROS topic,
    e.g. a ULog stream; the files then hold a placeholder) and ``label`` a line naming the
    recording (format, rate) shown under the IMU's heading."""

    axes: Mapping[str, Mapping[str, Any]]
    timing: Sequence[str] | None = None
    stationarity: Any = None
    rostopic: str | None = None
    label: str = ""


def report_dir(outdir: str | os.PathLike) -> Path:
    """The report directory ``outdir`` (an existing file there is an error)."""
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise InputError(f"report directory {out} exists and is not a directory")
    return out


def _freq(axes: Mapping[str, Mapping[str, Any]], where: str = "the report",
          unfitted: Mapping[str, Any] | None = None) -> float:
    if not axes and unfitted:
        return float(next(iter(unfitted.values()))["wv"].freq)
    if not axes:
        raise InputError(f"{where} needs at least one axis")
    return float(next(iter(axes.values()))["result"].wv.freq)


def _unfitted_parts(out: Path, unfitted: Mapping[str, Any], why: str | None, h: str,
                    prefix: str) -> tuple[list[str], list[str], list[_Figure]]:
    """Markdown lines, HTML parts and figures of the axes of an IMU that was not fitted
    (:class:`gmwm.calibrate.UnfittedAxis`: refused for motion): per axis its WV figure, no
    model, and ``why``."""
    lv = len(h)
    why = why or "the axes were not fitted"
    note = f"{why[0].upper()}{why[1:]} (see the verdict)."
    md: list[str] = [f"**{note}**", ""]
    body: list[str] = [f"<p><strong>{html.escape(note)}</strong></p>"]
    figures: list[_Figure] = []
    for name, a in unfitted.items():
        wv = a["wv"]
        png = wv_figure_path(out, name, prefix)
        figures.append(_Figure("wv-unfitted", png, (name, wv, a["units"] or "")))
        line = (f"Not fitted: the wavelet variance of the part used, "
                f"T = {wv.n_samples} samples, J = {wv.n_levels} scales"
                + (f", in {a['units']}" if a["units"] else "") + ".")
        md += [f"{h} {name}", "", line, "", f"![WV of {name}, not fitted]({png.name})", ""]
        body += [f"<h{lv}>{html.escape(name)}</h{lv}>", f"<p>{html.escape(line)}</p>",
                 (f'<img src="{html.escape(png.name)}" alt="WV of {html.escape(name)}" '
                  'width="560">')]
    return md, body, figures


def _export(axes: Mapping[str, Mapping[str, Any]], freq: float, topic: str | None,
            inflation: Any, source: str, verdict: Any = None) -> Any:
    """The noise export of the axes with a sensor unit (None: no axis has one)."""
    from gmwm.exports import noise_export

    if not any(a["units"] for a in axes.values()):
        return None
    # the page's own datasheets and readings: computed once per axis (by the fitting workers)
    return noise_export({n: (a["units"], a["result"]) for n, a in axes.items()}, freq,
                        topic=topic, inflation=inflation, source=source,
                        datasheets={n: a.get("datasheet") for n, a in axes.items()},
                        readings={n: a.get("readings") for n, a in axes.items()},
                        caveats=() if verdict is None else verdict.caveats,
                        unidentified=None if verdict is None else verdict.unidentified)


def _verdict_lines(verdict: Any) -> tuple[list[str], list[str]]:
    """The verdict block at the top of a report (Markdown, HTML): the verdict line, then its
    caveats (what every configuration file also starts with)."""
    if verdict is None:
        return [], []
    md = [f"> **{verdict.line()}**", *([">"] if verdict.caveats else []),
          *(f"> - {c}" for c in verdict.caveats), ""]
    colour = "#D55E00" if not verdict.written else ("#E69F00" if verdict.caveats else "#009E73")
    items = "".join(f"<li>{html.escape(c)}</li>" for c in verdict.caveats)
    body = [f'<div style="border-left:4px solid {colour};padding-left:8px"><p><strong>'
            f"{html.escape(verdict.line())}</strong></p>" + (f"<ul>{items}</ul>" if items else "")
            + "</div>"]
    return md, body


_BOUND_MARK = "≤"  # a flagged term's value: its 95 % upper bound, not a measurement


def _written_cells(t: Any) -> tuple[str, str]:
    """(value written, fit estimate with its 95 % CI) cells of one
    :class:`gmwm.exports.AxisTerm` (continuous-time SI)."""
    if t.value is None:
        written = "not written" if t.estimate is not None else "–"
    else:
        written = (f"{_BOUND_MARK} " if t.flag is not None and t.value != t.estimate else "") \
            + num(t.value)
    est = "–" if t.estimate is None else (num(t.estimate) + (f" {interval(t.ci95)}"
                                                              if t.ci95 else ""))
    return written, est


def _summary_tables(axes: Mapping[str, Mapping[str, Any]], exp: Any, refused: bool = False
                    ) -> list[tuple[str, list[str], list[tuple], str]]:
    """(caption, headers, rows, legend) of the summary tables, one unit system per table: per
    sensor the values the configuration files carry (continuous-time SI densities before
    inflation, a flagged term's 95 % upper bound marked, the fit's estimate beside it; last row
    the file's key, one value per sensor), then the fits' datasheet coefficients in datasheet
    units (every axis, also those without a sensor unit). ``refused``: the verdict refused the
    configuration files (the captions say they were not written)."""
    from gmwm.exports import SENSORS, SI_UNITS
    from gmwm.units import unit_system
    from gmwm.verdict import white_equivalent

    out = []
    if exp is not None:
        for sensor in SENSORS:
            noise = exp.sensor_axes(sensor)
            if not noise:
                continue
            _, nu, ku = SI_UNITS[sensor]
            verb = "would be written" if refused else "written"
            headers = ["axis", "unit", "model", f"noise density {verb} [{nu}]",
                       "fit estimate [95% CI]", f"random walk {verb} [{ku}]",
                       "fit estimate [95% CI]", "warnings"]
            rows: list[tuple] = []
            for an in noise:
                nw, ne = _written_cells(an.noise_density)
                we = white_equivalent(axes[an.axis]["result"])
                if we is not None and we.changed:  # the file folds fast GM/AR1 terms in
                    si = unit_system(an.unit).si
                    nw += (f" (WN {num(we.white * si)} + "
                           + ", ".join(f"{t.component} {num(t.density * si)}" for t in we.folded)
                           + " in quadrature)")
                kw, ke = _written_cells(an.random_walk)
                rows.append((an.axis, an.unit, an.model, nw, ne, kw, ke,
                             len(_axis_warnings(axes[an.axis]))))
            comb = exp.combined[sensor]
            cells = []
            for term in ("noise_density", "random_walk"):
                c = comb[term]
                how = (f"axis {c.axis}" if c.axis is not None else "rms of the axes") + (
                    "" if c.inflation == 1.0 else f", x{c.inflation:g} inflation")
                cells += ["not written" if c.value is None else num(c.value),
                          "–" if c.value is None else how]
            rows.append((f"{sensor}_* keys", "SI", "–", *cells, "–"))
            legend = (f"Continuous-time densities in SI units, as the configuration files "
                      f"{'would ' if refused else ''}write them (per axis before inflation; the last row is the value of "
                      f"the files' {sensor} keys). {_BOUND_MARK}: the term is flagged (at the "
                      "boundary 0 or not identifiable at this length) and the value written "
                      "is its 95 % upper bound, not a measurement; the fit's estimate is "
                      "beside it. A noise density with terms in parentheses includes the "
                      "Gauss-Markov/AR1 terms white at the sampling rate (their "
                      "white-noise-equivalent densities added in quadrature to the WN term's).")
            what = ("the values a configuration file would carry; NONE written (see the "
                    "verdict)" if refused else "the values the configuration files carry")
            out.append((f"{sensor.capitalize()}: {what}",
                        headers, rows, legend))
    groups: dict[tuple[str, str], list[tuple]] = {}  # one table per pair of units
    for name, a in axes.items():
        ds = a["datasheet"]
        white = next((v for k, v in ds.items() if k.split("[")[0] in ("ARW", "VRW", "WN")), None)
        rw = next((v for k, v in ds.items() if k.split("[")[0] in ("RRW", "AccRW", "RW")), None)
        cell = (lambda e: "–" if e is None else f"{num(e['value'])} {interval(e.get('ci95'))}")
        units = tuple("–" if e is None else e["unit"] for e in (white, rw))
        groups.setdefault(units, []).append(
            (name, a["units"] or "–", a["result"].model.spec, cell(white), cell(rw),
             len(_axis_warnings(a))))
    si = {u[1:] for u in SI_UNITS.values()}
    for (wu, ku), rows in groups.items():
        if exp is not None and (wu, ku) in si:  # the same numbers as the SI table above
            continue
        headers = ["axis", "unit", "model", f"white noise [{wu}] [95% CI]",
                   f"random walk [{ku}] [95% CI]", "warnings"]
        caption = ("The fits' estimates" if exp is None else "In datasheet units") + (
            f" ({wu}; {ku})" if len(groups) > 1 or exp is not None else "")
        legend = ("The fits' estimates in the datasheet units of these axes (gmwm.units), for "
                  "comparison with a sensor's datasheet; the configuration files carry the SI "
                  "values above." if exp is not None else "")
        out.append((caption, headers, rows, legend))
    return out


def _imu_section(out: Path, axes: Mapping[str, Mapping[str, Any]], exp: Any, *,
                 timing: Sequence[str] | None, stationarity: Any, lv: int = 2, prefix: str = "",
                 config_dir: str | None = None, refused: Sequence[str] = (),
                 unfitted: Mapping[str, Any] | None = None, not_fitted: str | None = None
                 ) -> tuple[list[str], list[str], list[_Figure]]:
    """Markdown lines, HTML parts and figures (to draw, :func:`_render`) of one IMU: the
    not-static warning, time base, stationarity, summary, one part per axis and the Kalibr block;
    headings of level ``lv``, figure names starting with ``prefix``; ``config_dir`` the folder of
    its configuration files when they are not beside the page; ``unfitted``/``not_fitted``: the
    axes of an IMU refused for motion and not fitted, and why (:func:`_unfitted_parts`)."""
    from gmwm.exports import kalibr_text

    h = "#" * lv
    md: list[str] = []
    body: list[str] = []
    figures: list[_Figure] = []
    st = stationarity
    if st is not None and (st.moving or st.alerts):
        lines = st.warnings(limit=10)
        md += ["> **Warning: the recording is not static.**" if st.moving else
               "> **Warning.**", *[f"> - {w}" for w in lines], ""]
        body.append('<div style="border:2px solid #D55E00;padding:.5em 1em"><strong>Warning: '
                    + ("the recording is not static." if st.moving else "") + "</strong><ul>"
                    + "".join(f"<li>{html.escape(w)}</li>" for w in lines) + "</ul></div>")
    if timing:
        md += [f"{h} Time base", "", *[f"- {t}" for t in timing], ""]
        body += [f"<h{lv}>Time base</h{lv}>",
                 "<ul>" + "".join(f"<li>{html.escape(t)}</li>" for t in timing) + "</ul>"]
    if st is not None:
        smd, sbody, sfigs = _stationarity_section(st, out, lv, prefix)
        md += smd
        body += sbody
        figures += sfigs
    md += [f"{h} Summary", ""]
    body.append(f"<h{lv}>Summary</h{lv}>")
    for caption, headers, summary, legend in _summary_tables(axes, exp, bool(refused)):
        md += [f"**{caption}**", "", *md_table(headers, summary), "",
               *([legend, ""] if legend else [])]
        body += [f"<p><strong>{html.escape(caption)}</strong></p>", html_table(headers, summary),
                 *([f"<p>{html.escape(legend)}</p>"] if legend else [])]
    if unfitted:
        umd, ubody, ufigs = _unfitted_parts(out, unfitted, not_fitted, h, prefix)
        md += umd
        body += ubody
        figures += ufigs
    for name, a in axes.items():
        res = a["result"]
        png = wv_figure_path(out, name, prefix)
        verdict = a.get("verdict")
        figures.append(_Figure("wv", png, (name, res, a["units"] or "", verdict)))
        rows = _rows(a["datasheet"])
        th = ["term", "quantity", "value", "95% CI", "unit"]
        md += [f"{h} {name}", "",
               (f"Model `{res.model.spec}`, T = {res.wv.n_samples} samples, J = {res.wv.n_levels} "
                f"scales, objective {_objective(res)}, converged "
                f"{'yes' if res.converged else 'NO'}."), "",
               f"![WV of {name} with the fitted model]({png.name})", "", *md_table(th, rows), ""]
        body += [f"<h{lv}>{html.escape(name)}</h{lv}>",
                 (f"<p>Model <code>{html.escape(res.model.spec)}</code>, T = {res.wv.n_samples} "
                  f"samples, J = {res.wv.n_levels} scales.</p>"),
                 f'<img src="{html.escape(png.name)}" alt="WV of {html.escape(name)}" width="560">',
                 html_table(th, rows)]
        choice = a.get("choice")
        if choice is not None:
            cmd, cbody = choice_section(choice)
            md += cmd
            body.append(cbody)
        if verdict is not None:
            adev_png = out / f"{prefix}{_slug(name)}_adev.png"
            figures.append(_Figure("adev", adev_png, (name, res, a["units"] or "", verdict)))
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
        readings = _reading_rows(res, a["units"], a.get("readings"))
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
    if refused:
        why = "No filter configuration file written: " + "; ".join(refused) + "."
        md += [f"{h} Noise densities", "", f"**{why}**", ""]
        body += [f"<h{lv}>Noise densities</h{lv}>", f"<p><strong>{html.escape(why)}</strong></p>"]
    elif exp is not None:
        yaml = kalibr_text(exp).rstrip("\n")
        md += [f"{h} Noise densities (Kalibr imu.yaml)", ""]
        body += [f"<h{lv}>Noise densities (Kalibr imu.yaml)</h{lv}>"]
        if config_dir is not None:
            where = f"The configuration files of this IMU are in {config_dir}/."
            md += [where.replace(f"{config_dir}/", f"`{config_dir}/`"), ""]
            body += [f"<p>{html.escape(where)}</p>"]
        md += ["```yaml", yaml, "```", ""]
        body += [f"<pre>{html.escape(yaml)}</pre>"]
    else:
        why = ("No filter configuration file (imu.yaml): no axis has a gyroscope or accelerometer "
               "unit, so neither the sensor nor the SI scale is known (give --units).")
        md += [f"{h} Noise densities", "", why, ""]
        body += [f"<h{lv}>Noise densities</h{lv}>", f"<p>{html.escape(why)}</p>"]
    return md, body, figures


def _page(title: str, body: list[str]) -> str:
    style = ("body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;"
             "padding:.2em .6em;text-align:right}th{background:#f4f4f4}pre{background:#f8f8f8;"
             "padding:1em}")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}"
            f"</title><style>{style}</style></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")


_INTRO = ("Coefficients are continuous-time datasheet values with 95 % intervals inside the "
          "parameter space (a coefficient not distinguishable from zero has an interval from 0); "
          "per-sample parameters are in the JSON output.")


def write_report(outdir: str | os.PathLike, axes: Mapping[str, Mapping[str, Any]], *, source: str,
                 title: str, timing: Sequence[str] | None = None, stationarity: Any = None,
                 topic: str | None = None, targets: str | Sequence[str] = ("kalibr",),
                 inflation: Any = None, drawn: Sequence[str | os.PathLike] = (),
                 verdict: Any = None, unfitted: Mapping[str, Any] | None = None,
                 not_fitted: str | None = None) -> list[Path]:
    """Write ``report.md``, ``report.html``, the filter configuration files of ``targets``
    (:func:`gmwm.exports.parse_targets`; default the Kalibr ``imu.yaml``) and one
    ``<axis>_wv.png`` per axis to ``outdir``; return the paths.

    ``axes[name]`` holds ``result`` (a GMWM fit), ``units`` (signal unit; deg/s or rad/s mark a
    gyroscope, m/s^2 or g an accelerometer), ``warnings`` (list of str), ``datasheet`` and
    optionally ``verdict`` (a sensor datasheet's judgement, :func:`gmwm.sensor_datasheet.judge`;
    adds ``<axis>_adev.png`` and the verdict table) and ``choice`` (the
    :class:`gmwm.automodel.Choice` that chose the model: its ranking, :func:`choice_section`).
    ``timing``: lines on the recording's time base (rate source, jitter, gaps, gap policy).
    ``stationarity``: a :class:`gmwm.stationarity.StationarityReport` (its ``used`` range set):
    a warning at the top when it flags the part used, a section with the timeline figure.
    ``topic``: the IMU's ROS topic (written as ``rostopic``); ``inflation``: e.g.
    ``"noise=2,walk=10"`` (:func:`gmwm.exports.parse_inflation`). Without any gyroscope or
    accelerometer unit no configuration file is written and the report says why.
    ``drawn``: figure files already written for this page (:func:`warm_up`), not drawn again.
    ``verdict``: a :class:`gmwm.verdict.Verdict`: its line and caveats open the page, the
    caveats open every configuration file, and a verdict that refuses them leaves them unwritten
    (the report is written, saying why). ``unfitted``: axis -> its
    :class:`gmwm.calibrate.UnfittedAxis` when the IMU was refused for motion and not fitted
    (``axes`` empty; the page shows their WVs and ``not_fitted``, the reason). Several IMUs on
    one page: :func:`write_multi_report`.
    """
    from gmwm.atomic import write_text_atomic
    from gmwm.exports import parse_targets, write_exports

    out = report_dir(outdir)
    out.mkdir(parents=True, exist_ok=True)
    freq = _freq(axes, unfitted=unfitted)
    # the configuration files' inputs are checked before any file is written
    names = parse_targets(targets)
    exp = _export(axes, freq, topic, inflation, source, verdict)
    vmd, vbody = _verdict_lines(verdict)
    n_axes = len(axes) or len(unfitted or {})
    md = [f"# {title}", "", *vmd,
          (f"Input `{source}`, sampling frequency {freq:g} Hz, {n_axes} axes; "
           f"GMWM fits by gmwm {__version__}. " + _INTRO), ""]
    body: list[str] = [f"<h1>{html.escape(title)}</h1>", *vbody,
                       (f"<p>Input <code>{html.escape(source)}</code>, sampling frequency {freq:g} "
                        f"Hz, {n_axes} axes; GMWM fits by gmwm {html.escape(__version__)}.</p>")]
    smd, sbody, figures = _imu_section(
        out, axes, exp, timing=timing, stationarity=stationarity,
        refused=() if verdict is None or verdict.written else verdict.reasons,
        unfitted=unfitted, not_fitted=not_fitted)
    written = _render(figures, [Path(p) for p in drawn])
    md += smd
    body += sbody
    written.append(write_text_atomic(out / "report.md", "\n".join(md)))
    written.append(write_text_atomic(out / "report.html", _page(title, body)))
    if exp is not None and names and (verdict is None or verdict.written):
        written += write_exports(exp, out, names)
    return written


def imu_folders(topics: Sequence[str]) -> dict[str, str]:
    """The configuration folder name of each IMU of a multi-IMU report: the topic with every run
    of characters other than letters, digits, ``_.-`` replaced by ``_`` (``/imu0/data`` ->
    ``imu0_data``, ``sensor_gyro:1`` -> ``sensor_gyro_1``); a name already taken gets ``-2``,
    ``-3``, ..."""
    out: dict[str, str] = {}
    for t in topics:
        base = _slug(t) if _slug(t) != "axis" else "imu"
        name, k = base, 1
        while name in out.values():
            k += 1
            name = f"{base}-{k}"
        out[t] = name
    return out


def write_multi_report(outdir: str | os.PathLike, imus: Mapping[str, Any], *,
                       source: str, title: str, targets: str | Sequence[str] = ("kalibr",),
                       inflation: Any = None, drawn: Sequence[str | os.PathLike] = ()
                       ) -> list[Path]:
    """One page (``report.md``, ``report.html``) over several IMUs of one recording, and one set
    of filter configuration files per IMU; return the paths.

    ``imus[topic]``: a :class:`gmwm.calibrate.TopicCalibration` (or an :class:`ImuSection`).
    The page has an overview table, then a section per IMU (its warning, time base,
    stationarity, summary, axes and Kalibr block, as :func:`write_report` writes them one
    heading level down); figure names start with the IMU's folder name
    (``imu0_data_gx_wv.png``, ``imu0_data_stationarity.png``). The configuration files of
    ``targets`` go to ``<outdir>/<folder>/`` (:func:`imu_folders`), each carrying its
    ``rostopic``. A topic that failed (``status="failed"``) is listed in the overview and in its
    own section with its reason, with no configuration file. A single IMU gives exactly
    :func:`write_report`'s layout (files beside the page). Every IMU's export is checked before
    any file is written."""
    from gmwm.atomic import write_text_atomic
    from gmwm.exports import parse_targets, write_exports

    if not imus:
        raise InputError("the report needs at least one IMU")
    done = {t: sec for t, sec in imus.items() if getattr(sec, "ok", True)}
    if not done:
        raise InputError("the report needs at least one calibrated IMU")
    if len(imus) == 1:
        sec = next(iter(imus.values()))
        return write_report(outdir, sec.axes, source=source, title=title, timing=sec.timing,
                            stationarity=sec.stationarity, topic=sec.rostopic, targets=targets,
                            inflation=inflation, drawn=drawn,
                            verdict=getattr(sec, "verdict", None),
                            unfitted=getattr(sec, "unfitted", None),
                            not_fitted=getattr(sec, "not_fitted", None))
    out = report_dir(outdir)
    names = parse_targets(targets)
    folders = imu_folders(list(imus))
    freqs = {t: _freq(sec.axes, f"IMU {t}", getattr(sec, "unfitted", None))
             for t, sec in done.items()}
    verdicts = {t: getattr(sec, "verdict", None) for t, sec in done.items()}
    exps = {t: _export(sec.axes, freqs[t], sec.rostopic, inflation, f"{source} ({t})",
                       verdicts[t])
            for t, sec in done.items()}
    writes = {t: exps[t] is not None and bool(names) and (verdicts[t] is None
                                                          or verdicts[t].written) for t in done}
    out.mkdir(parents=True, exist_ok=True)
    overview = [(t, sec.label or "–", f"{freqs[t]:g}",
                 len(sec.axes) or len(getattr(sec, "unfitted", None) or {}),
                 sum(len(_axis_warnings(a)) for a in sec.axes.values()),
                 "not static" if sec.stationarity is not None and sec.stationarity.moving
                 else "static" if sec.stationarity is not None else "not checked",
                 f"{folders[t]}/" if writes[t] else "NOT written"
                 if (exps[t] is not None or getattr(sec, "not_fitted", None)) and names else "–")
                if t in done else
                (t, f"FAILED: {sec.reason}", "–", 0, "–", "–", "–")
                for t, sec in imus.items()]
    oh = ["IMU", "recording", "rate [Hz]", "axes", "warnings", "stationarity",
          "configuration files"]
    failed = [t for t in imus if t not in done]
    fail_line = ("" if not failed else
                 f" {len(failed)} of them could not be calibrated ({', '.join(failed)}): see "
                 "their sections.")
    md = [f"# {title}", "",
          (f"Input `{source}`, {len(imus)} IMUs; GMWM fits by gmwm {__version__}. " + _INTRO
           + " Each IMU has its own section and its own folder of filter configuration files."
           + fail_line), "", *md_table(oh, overview), ""]
    body = [f"<h1>{html.escape(title)}</h1>",
            (f"<p>Input <code>{html.escape(source)}</code>, {len(imus)} IMUs; GMWM fits by gmwm "
             f"{html.escape(__version__)}. Each IMU has its own section and its own folder of "
             f"filter configuration files.{html.escape(fail_line)}</p>"),
            html_table(oh, overview)]
    figures: list[_Figure] = []  # every IMU's, drawn by one pool of workers
    for t, sec in imus.items():
        md += [f"## IMU {t}", ""]
        body.append(f"<h2>IMU {html.escape(t)}</h2>")
        if t not in done:
            why = (f"Not calibrated: {sec.reason}. No configuration file is written for this "
                   "IMU.")
            md += [f"> **{why}**", ""]
            body.append(f'<p style="color:#D55E00"><strong>{html.escape(why)}</strong></p>')
            continue
        line = (f"{sec.label + ', ' if sec.label else ''}sampling frequency {freqs[t]:g} Hz, "
                f"{len(sec.axes) or len(getattr(sec, 'unfitted', None) or {})} axes"
                + (f", ROS topic {sec.rostopic}" if sec.rostopic else "")
                + ".")
        md += [line, ""]
        body.append(f"<p>{html.escape(line)}</p>")
        vmd, vbody = _verdict_lines(verdicts[t])
        md += vmd
        body += vbody
        smd, sbody, files = _imu_section(
            out, sec.axes, exps[t], timing=sec.timing, stationarity=sec.stationarity, lv=3,
            prefix=folders[t] + "_", config_dir=folders[t] if writes[t] else None,
            refused=() if verdicts[t] is None or verdicts[t].written else verdicts[t].reasons,
            unfitted=getattr(sec, "unfitted", None), not_fitted=getattr(sec, "not_fitted", None))
        md += smd
        body += sbody
        figures += files
    written = _render(figures, [Path(p) for p in drawn])
    written.append(write_text_atomic(out / "report.md", "\n".join(md)))
    written.append(write_text_atomic(out / "report.html", _page(title, body)))
    for t, exp in exps.items():
        if writes[t]:
            written += write_exports(exp, out / folders[t], names)
    return written


def figure_prefixes(topics: Sequence[str]) -> dict[str, str]:
    """Topic -> the prefix of its figure files on a report page of ``topics`` ('' for one)."""
    if len(topics) <= 1:
        return dict.fromkeys(topics, "")
    return {t: f + "_" for t, f in imu_folders(topics).items()}


@dataclass(frozen=True)
class FigureDrawer:
    """Draws an axis's WV figure of a page without a datasheet verdict into ``outdir`` as
    :func:`write_report` names it, in the worker that fitted the axis
    (:func:`gmwm.calibrate.calibrate`'s ``draw``; picklable). ``prefixes``: topic -> figure-name
    prefix (:func:`figure_prefixes`; a topic not listed: none)."""

    outdir: str
    prefixes: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def bind(self, topics: Sequence[str]) -> FigureDrawer:
        """This drawer with the figure-name prefixes of a page over ``topics``."""
        return dataclasses.replace(self, prefixes=figure_prefixes(topics))

    def __call__(self, topic: str, name: str, result: Any, units: str) -> list[Path]:
        path = wv_figure_path(self.outdir, name, self.prefixes.get(topic, ""))
        return draw_wv_figure(path, name, result, units)


def write_calibration(outdir: str | os.PathLike, result: Any, *, title: str | None = None,
                      targets: str | Sequence[str] = ("kalibr",), inflation: Any = None,
                      drawn: Sequence[str | os.PathLike] = (), rostopic: str | None = None
                      ) -> list[Path]:
    """Write the report and the configuration files of a :class:`gmwm.calibrate.
    CalibrationResult`: one topic as :func:`write_report` (files beside the page), several as
    :func:`write_multi_report` (a section and a configuration folder per topic, failed topics
    listed with their reason). ``title`` defaults to "Calibration report: <file name>";
    ``drawn``: figure files already written (:func:`warm_up`, :class:`FigureDrawer`);
    ``rostopic``: the ROS topic the configuration files name, for one topic (default: the
    recording's, when it is a ROS topic; else a placeholder the files say is one)."""
    title = title or f"Calibration report: {Path(result.source).name}"
    topics = result.topics
    drawn = [*drawn, *(f for s in topics.values() for a in s.axes.values()
                       for f in getattr(a, "figures", ()))]
    if len(topics) == 1:
        sec = next(iter(topics.values()))
        return write_report(outdir, sec.axes, source=result.source, title=title,
                            timing=sec.timing, stationarity=sec.stationarity,
                            topic=rostopic or sec.rostopic, targets=targets,
                            inflation=inflation, drawn=drawn,
                            verdict=getattr(sec, "verdict", None),
                            unfitted=getattr(sec, "unfitted", None),
                            not_fitted=getattr(sec, "not_fitted", None))
    return write_multi_report(outdir, topics, source=result.source, title=title,
                              targets=targets, inflation=inflation, drawn=drawn)
