"""Figures in one paper-like style: log-log wavelet (and Allan) variance with CI band, model and
component lines, the virtual gyroscope's WV. The studies' figures (:mod:`gmwm_studies.figures`)
use the same style.

Every function takes ``ax=None`` (a new figure is made when None) and returns the Axes (or the Figure
for multi-panel plots). Figures are built with :class:`matplotlib.figure.Figure`, not ``pyplot``, so
nothing here touches the global backend or figure registry; save with :func:`gmwm.atomic.save_figure`.
Colours: the Okabe-Ito colour-blind-safe palette.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

__all__ = [
    "PALETTE",
    "STYLE",
    "add_datasheet_line",
    "channel_grid",
    "new_axes",
    "page_layout",
    "plot_av",
    "plot_model_wv",
    "plot_plan",
    "plot_stationarity",
    "plot_virtual_wv",
    "plot_wv",
    "power_of_ten_label",
    "style",
    "subplots",
    "variance_label",
]

#: Okabe & Ito (2008) colour-blind-safe palette, black first.
PALETTE = (
    "#000000",  # black
    "#0072B2",  # blue
    "#D55E00",  # vermillion
    "#009E73",  # bluish green
    "#E69F00",  # orange
    "#CC79A7",  # reddish purple
    "#56B4E9",  # sky blue
    "#F0E442",  # yellow
)
EMPIRICAL_COLOR = PALETTE[1]
MODEL_COLOR = PALETTE[0]
COMPONENT_COLORS = PALETTE[2:]

#: rcParams of the project style (serif text, light grid, no top/right spines, colour-blind palette).
STYLE: dict[str, Any] = {
    "font.family": "serif",
    "font.size": 9,
    "axes.labelsize": 9,
    "axes.titlesize": 10,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "axes.grid.which": "major",
    "grid.color": "#DDDDDD",
    "grid.linewidth": 0.5,
    "grid.linestyle": "-",
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.linewidth": 0.6,
    "axes.prop_cycle": mpl.cycler(color=list(PALETTE[1:]) + [PALETTE[0]]),
    "lines.linewidth": 1.2,
    "lines.markersize": 3.5,
    "legend.frameon": False,
    "figure.figsize": (5.0, 3.4),
    "figure.dpi": 100,
    "savefig.dpi": 200,
    "savefig.bbox": "tight",
    "mathtext.fontset": "dejavuserif",
}


@contextmanager
def style() -> Iterator[None]:
    """Context in which matplotlib uses the project style (:data:`STYLE`)."""
    with mpl.rc_context(STYLE):
        yield


def new_axes(ax: Axes | None = None, figsize: tuple[float, float] | None = None) -> Axes:
    """``ax`` itself, or the Axes of a new styled Figure (no pyplot involved)."""
    if ax is not None:
        return ax
    with style():
        fig = Figure(figsize=figsize or STYLE["figure.figsize"], layout="constrained")
        return fig.add_subplot()


def subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float] | None = None,
             **kwargs: Any) -> tuple[Figure, Any]:
    """A styled Figure and its Axes grid (like ``pyplot.subplots``, without pyplot), for composing
    several of the plots here into one figure by passing ``ax=``."""
    with style():
        fig = Figure(figsize=figsize or STYLE["figure.figsize"], layout="constrained")
        return fig, fig.subplots(nrows, ncols, **kwargs)


def variance_label(quantity: str, units: str = "") -> str:
    """Axis label such as ``Wavelet variance [(deg/s)²]``; the unit is squared, bracketed if compound."""
    if not units:
        return quantity
    u = units.strip()
    squared = f"({u})²" if any(c in u for c in "/*· ") else f"{u}²"
    return f"{quantity} [{squared}]"


def scale_label(freq: float, what: str = "Scale") -> str:
    """Axis label of the scale: in samples when ``freq`` is 1, else in seconds."""
    return f"{what} τ [samples]" if freq == 1.0 else f"{what} τ [s]"


def positive(y: np.ndarray) -> np.ndarray:
    """``y`` as float with non-positive values masked (NaN), so log axes skip exact zeros."""
    y = np.asarray(y, dtype=float).copy()
    y[~(y > 0)] = np.nan
    return y


def model_theta(model: Any, theta: Any, result: Any) -> tuple[Any, np.ndarray | None]:
    """The model and parameters to draw: the result's, else ``model`` (a Model or spec string)
    at ``theta``; (None, None) when no model is given."""
    if result is not None:
        return result.model, np.asarray(result.params, dtype=float)
    if model is None:
        return None, None
    if isinstance(model, str):
        from gmwm.model import Model

        model = Model(model)
    if theta is None:
        raise ValueError("plotting a model needs theta (or a fit result)")
    if isinstance(theta, Mapping):
        theta = model.theta(dict(theta))
    return model, np.asarray(theta, dtype=float)


def draw_model(
    ax: Axes,
    x: np.ndarray,
    scales: np.ndarray,
    model: Any,
    theta: np.ndarray,
    components: bool,
    label: str = "Model",
) -> None:
    """Draw the model's WV at ``scales`` (and each component dashed with ``components``)."""
    ax.plot(x, positive(model.wv(theta, scales)), color=MODEL_COLOR, lw=1.5, label=label, zorder=4)
    if not components:
        return
    comps = model.component_wv(theta, scales)
    if len(comps) < 2:  # a single component is the model line itself
        return
    for i, (name, y) in enumerate(comps.items()):
        if not np.any(np.asarray(y, dtype=float) > 0):  # estimated at 0: nothing to draw or name
            continue
        ax.plot(
            x,
            positive(y),
            ls="--",
            lw=1.0,
            color=COMPONENT_COLORS[i % len(COMPONENT_COLORS)],
            label=name,
            gid="component",
            zorder=3,
        )


def _draw_estimate(
    ax: Axes,
    x: np.ndarray,
    y: np.ndarray,
    lo: np.ndarray | None,
    hi: np.ndarray | None,
    label: str,
    ci_label: str,
) -> None:
    if lo is not None and hi is not None:
        ax.fill_between(
            x, lo, hi, color=EMPIRICAL_COLOR, alpha=0.2, lw=0, label=ci_label, gid="ci_band"
        )
    ax.plot(x, y, "o-", color=EMPIRICAL_COLOR, ms=3.5, lw=0.8, label=label, zorder=5)


def plot_wv(
    wv: Any,
    *,
    model: Any = None,
    theta: Any = None,
    result: Any = None,
    components: bool = True,
    ax: Axes | None = None,
    units: str = "",
    label: str | None = None,
    residuals: bool = True,
) -> Axes:
    """Empirical wavelet variance (points, shaded CI band) with the model WV and its components.

    ``wv`` is a ``gmwm.wv.WaveletVariance``; x is the scale tau_j in seconds (samples when
    ``wv.freq == 1``), log-log. The model comes from ``result`` (a GMWM fit) or ``model`` + ``theta``
    (array or ``{name: value}``); ``components`` adds one dashed line per component. ``units`` is the
    signal unit (e.g. ``"deg/s"``); the y axis is in its square. With ``residuals`` and a result
    carrying a goodness-of-fit test (``result.gof``, :mod:`gmwm.gof`), the scales where the model
    misses (standardised residual ``|u_j| > 2``) are ringed and labelled with ``u_j``, and the
    legend's title gives the test's p-value.
    """
    model, theta = model_theta(model, theta, result)
    ax = new_axes(ax)
    scales = np.asarray(wv.scales, dtype=float)
    freq = float(getattr(wv, "freq", 1.0))
    x = scales / freq
    level = 100 * (1 - float(getattr(wv, "alpha", 0.05)))
    with style():
        _draw_estimate(
            ax, x, np.asarray(wv.variance, float), np.asarray(wv.ci_low, float),
            np.asarray(wv.ci_high, float), label or "Empirical WV", f"{level:g}% CI",
        )
        if model is not None:
            draw_model(ax, x, scales, model, theta, components)
        finish_loglog(ax, scale_label(freq), variance_label("Wavelet variance", units))
        if model is not None and components:
            # components that vanish at some scales (SIN) would squash the data into a strip
            data = np.concatenate([np.asarray(wv.ci_low, float), np.asarray(wv.variance, float)])
            floor = np.nanmin(positive(data)) / 100.0
            if np.isfinite(floor) and ax.get_ylim()[0] < floor:
                ax.set_ylim(bottom=floor)
        gof = getattr(result, "gof", None) if residuals else None
        if gof is not None:
            _draw_misses(ax, x, np.asarray(wv.variance, float), gof)
    return ax


#: standardised residuals beyond this are marked on the WV plot (about 5 % of scales under the model)
RESIDUAL_MARK = 2.0


def _draw_misses(ax: Axes, x: np.ndarray, y: np.ndarray, gof: Any) -> None:
    """Ring the WV points whose standardised residual exceeds :data:`RESIDUAL_MARK` in size,
    label them with it, and title the legend with the test's p-value."""
    u = np.asarray(gof.residuals, dtype=float)
    miss = np.isfinite(u) & (np.abs(u) > RESIDUAL_MARK) & (y > 0)
    if miss.any():
        ax.plot(x[miss], y[miss], ls="none", marker="o", ms=8, mfc="none", mec=MODEL_COLOR,
                mew=1.2, zorder=6, gid="gof_miss",
                label=f"model misses (|residual| > {RESIDUAL_MARK:g} SD)")
        for xi, yi, ui in zip(x[miss], y[miss], u[miss], strict=True):
            ax.annotate(f"{ui:+.1f}", (xi, yi), xytext=(0, 7), textcoords="offset points",
                        ha="center", fontsize=7, color=MODEL_COLOR, gid="gof_miss_label")
    if gof.df > 0 and np.isfinite(gof.p_value):
        p = f"{gof.p_value:.2g}" if gof.p_value >= 1e-300 else "< 1e-300"
        title = f"goodness of fit: p = {p}" + (" (rejected)" if gof.rejected() else "")
        ax.legend(loc="best", title=title, title_fontsize=STYLE["legend.fontsize"])


def plot_av(av: Any, *, ax: Axes | None = None, units: str = "", label: str | None = None,
            deviation: bool = False, readings: Mapping[str, Any] | None = None) -> Axes:
    """Allan variance (or, with ``deviation``, the Allan deviation) with its CI band, log-log against
    the cluster time m / freq.

    ``av`` is a ``gmwm.wv.AllanVariance`` (``avar``, ``ci_low``, ``ci_high``, ``clusters`` in samples,
    ``freq``); objects with ``variance`` and ``scales`` (halved to cluster lengths) work too.
    ``readings`` (from :func:`gmwm.datasheet.allan_readings`, deviation plot only) adds the IEEE 952
    lines: slope -1/2 through N at 1 s, slope +1/2 through K at 3 s, and the bias-instability floor.
    """
    ax = new_axes(ax)
    freq = float(getattr(av, "freq", 1.0))
    m = _clusters(av)
    values = np.asarray(_av_values(av), float)
    lo, hi = np.asarray(av.ci_low, float), np.asarray(av.ci_high, float)
    if deviation:
        values, lo, hi = np.sqrt(values), np.sqrt(lo), np.sqrt(hi)
    what = "Allan deviation" if deviation else "Allan variance"
    with style():
        _draw_estimate(
            ax, m / freq, values, lo, hi, label or what,
            f"{100 * (1 - float(getattr(av, 'alpha', 0.05))):g}% CI",
        )
        if deviation and readings:
            _draw_readings(ax, m / freq, values, readings)
        ylabel = (f"{what} [{units}]" if units else what) if deviation else variance_label(what, units)
        finish_loglog(ax, scale_label(freq, "Cluster time"), ylabel)
    return ax


def _draw_readings(ax: Axes, tau: np.ndarray, adev: np.ndarray, readings: Mapping[str, Any]) -> None:
    """IEEE 952 lines in signal units: N tau^-1/2, K (tau/3)^1/2, floor 0.6643 B (dotted)."""
    t = np.geomspace(tau.min(), tau.max(), 50)
    for key, slope, at, color in (("N", -0.5, 1.0, PALETTE[2]), ("K", 0.5, 3.0, PALETTE[3])):
        r = readings.get(key) or {}
        if r.get("value") is None or not r.get("tau_range_s"):
            continue
        # the line through the points the reading used, in signal units
        lo_t, hi_t = r["tau_range_s"]
        sel = (tau >= lo_t) & (tau <= hi_t)
        if not sel.any():
            continue
        c = float(np.exp(np.mean(np.log(adev[sel]) - slope * np.log(tau[sel]))))
        ax.plot(t, c * t ** slope, ls=":", lw=1.0, color=color, gid=f"reading_{key}",
                label=f"{key}: slope {slope:+g} (read at {at:g} s)")
    b = readings.get("B") or {}
    if b.get("tau_s") is not None:
        i = int(np.argmin(np.abs(tau - b["tau_s"])))
        ax.axhline(adev[i], ls=":", lw=1.0, color=PALETTE[4], gid="reading_B",
                   label="B: 0.664 B floor (AD minimum)")


def _av_values(av: Any) -> np.ndarray:
    return av.avar if getattr(av, "avar", None) is not None else av.variance


def _clusters(av: Any) -> np.ndarray:
    for name in ("clusters", "cluster", "m"):
        if getattr(av, name, None) is not None:
            return np.asarray(getattr(av, name), dtype=float)
    return np.asarray(av.scales, dtype=float) / 2.0


def channel_grid(n: int, ncols: int = 3, panel: tuple[float, float] = (3.6, 2.7)
                 ) -> tuple[Figure, list[Axes]]:
    """A styled Figure with ``n`` panels (one per channel of an IMU), row-major, ``ncols`` wide;
    unused grid cells are hidden. Returns the Figure and the ``n`` Axes."""
    ncols = max(1, min(ncols, n))
    nrows = -(-n // ncols)
    fig, axes = subplots(nrows, ncols, squeeze=False,
                         figsize=(panel[0] * ncols + 0.3, panel[1] * nrows + 0.2) if n > 1 else None)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def plot_model_wv(
    model: Any,
    theta: Any,
    scales: Sequence[float],
    *,
    freq: float = 1.0,
    components: bool = True,
    ax: Axes | None = None,
    units: str = "",
) -> Axes:
    """Theoretical WV of ``model`` at ``theta`` on ``scales`` (samples), total and per component."""
    model, theta = model_theta(model, theta, None)
    ax = new_axes(ax)
    scales = np.asarray(scales, dtype=float)
    with style():
        draw_model(ax, scales / freq, scales, model, theta, components, label="Model WV (total)")
        finish_loglog(ax, scale_label(freq), variance_label("Wavelet variance", units))
    return ax


def plot_virtual_wv(result: Any, ax: Axes | None = None, units: str = "") -> Axes:
    """WV of every input signal (thin lines) and of the virtual signal (thick, with its CI band) of
    a :class:`gmwm.virtual.SVOResult` against the scale in seconds (``freq`` of the WCCV); returns
    the Axes."""
    W = result.wccv
    ax = new_axes(ax)
    x = W.scales / W.freq
    with style():
        for k, name in enumerate(W.names):
            ax.loglog(x, np.einsum("jii->ji", W.cov)[:, k], lw=0.9, alpha=0.8,
                      color=PALETTE[(k % (len(PALETTE) - 2)) + 2], label=name)
        wv = result.wv()
        ax.fill_between(x, wv.ci_low, wv.ci_high, color=PALETTE[0], alpha=0.2, lw=0)
        ax.loglog(x, wv.variance, lw=2.2, color=PALETTE[0], marker="o", ms=3,
                  label=f"virtual ({result.method})")
        ax.set_xlabel("Scale τ [samples]" if W.freq == 1.0 else "Scale τ [s]")
        ax.set_ylabel(variance_label("Wavelet variance", units))
        ax.legend(fontsize="small", ncol=2)
    return ax


def finish_loglog(ax: Axes, xlabel: str, ylabel: str) -> None:
    """Log-log axes with the given labels."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="major", color=STYLE["grid.color"], lw=0.5)
    ax.legend(loc="best")


_SYMBOL = {"sigma2": r"\sigma^2", "Q2": "Q^2", "gamma2": r"\gamma^2", "omega": r"\omega",
           "phi": r"\phi", "alpha": r"\alpha", "beta": r"\beta"}


def param_label(name: str, names: Sequence[str] = ()) -> str:
    """A canonical parameter name (``'AR1[2].sigma2'``) in the papers' notation as math text:
    WN sigma^2, QN Q^2, RW gamma^2, DR omega, AR1 (phi, varsigma^2), GM (beta, sigma^2_GM),
    SIN (alpha, beta). The component index is a subscript when ``names`` (all parameters of the
    figure) hold several components of that type. Unknown names are returned unchanged."""
    try:
        comp, par = name.split(".")
        kind, idx = comp.rstrip("]").split("[")
    except ValueError:
        return name
    sym = r"\varsigma^2" if (kind == "AR1" and par == "sigma2") else _SYMBOL.get(par)
    if sym is None:
        return name
    several = any(n.startswith(f"{kind}[") and not n.startswith(f"{kind}[1]") for n in names)
    sub = [idx] if several else []
    if kind == "GM" and par == "sigma2":
        sub.insert(0, "GM")
    if not sub:
        return f"${sym}$"
    base, sup = (sym[:-2], "^2") if sym.endswith("^2") else (sym, "")
    return f"${base}_{{{','.join(sub)}}}{sup}$"


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def power_of_ten_label(value: float, _pos: Any = None) -> str:
    """Tick label ``10⁻³`` of a log axis's decade ``value`` in plain Unicode (no math text: the
    math-text parser is about a fifth of a page figure's drawing time); "" between decades."""
    if not value > 0:
        return ""
    e = float(np.log10(value))
    k = round(e)
    return "10" + str(k).translate(_SUPERSCRIPT) if abs(e - k) < 1e-9 else ""


#: margins of a report page figure, inches (left, right, bottom, top): room for decade tick
#: labels and a rotated axis label on the left, the axis label below and a title above
PAGE_MARGINS = (0.78, 0.15, 0.48, 0.3)


def page_layout(fig: Figure, hspace: float = 0.12) -> Figure:
    """Give ``fig`` (a report page figure from this module) fixed margins (:data:`PAGE_MARGINS`,
    ``hspace`` inches between stacked panels) instead of constrained layout, major ticks only
    on its log axes, with plain decade labels (:func:`power_of_ten_label`). Saving it then
    draws it once instead of twice (constrained layout measures every text first): about a
    third of its drawing time. Returns ``fig``."""
    from matplotlib.ticker import FuncFormatter, NullLocator

    axes = fig.get_axes()
    for ax in axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() == "log":
                axis.set_minor_locator(NullLocator())
                axis.set_major_formatter(FuncFormatter(power_of_ten_label))
    fig.set_layout_engine(None)
    w, h = fig.get_size_inches()
    left, right, bottom, top = PAGE_MARGINS
    rows = max(1, len(axes))
    panel = (h - bottom - top - hspace * (rows - 1)) / rows
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        hspace=hspace / panel if rows > 1 and panel > 0 else 0.2)
    return fig


#: shading of the stationarity timeline: flagged by this channel / by another channel / unused
FLAG_COLOR = PALETTE[2]
UNUSED_COLOR = "#BBBBBB"


def plot_stationarity(report: Any, *, channels: Sequence[str] | None = None,
                      panel_height: float = 1.05, width: float = 7.0) -> Figure:
    """Timeline of a :class:`gmwm.stationarity.StationarityReport`: one panel per channel (the
    per-bin mean as a line, the min-max envelope shaded), ranges flagged by that channel shaded
    strongly and ranges flagged by others lightly, the part of the recording not used by the
    estimate greyed; a last panel with the temperature when the recording has one. x: seconds
    since the first sample (samples without a rate). Returns the Figure."""
    names = [c for c in (channels or report.channels) if c in report.timeline]
    temp = report.temperature_timeline
    rows = len(names) + (temp is not None)
    if rows == 0:
        raise ValueError("the report has no timeline to draw")
    fig, axes = subplots(rows, 1, squeeze=False, sharex=True,
                         figsize=(width, 0.5 + panel_height * rows))
    axes = list(axes[:, 0])
    unit_t = "s" if report.freq else "samples"
    used = report.used or (0, report.n)
    t_end = report.time_at(report.n)
    with style():
        for ax, c in zip(axes, names, strict=False):
            t, mean, lo, hi = report.timeline[c]
            ax.fill_between(t, lo, hi, color=EMPIRICAL_COLOR, alpha=0.25, linewidth=0)
            ax.plot(t, mean, color=EMPIRICAL_COLOR, linewidth=0.7)
            for s in report.segments:
                own = c in s.channels
                ax.axvspan(s.start_s, s.end_s, color=FLAG_COLOR, alpha=0.35 if own else 0.10,
                           linewidth=0)
            unit = report.units.get(c) or ""
            ax.set_ylabel(f"{c} [{unit}]" if unit else c)
        if temp is not None:
            ax = axes[-1]
            ax.plot(temp[0], temp[1], color=PALETTE[4], linewidth=1.0)
            for s in report.segments:
                ax.axvspan(s.start_s, s.end_s, color=FLAG_COLOR, alpha=0.10, linewidth=0)
            ax.set_ylabel("temp. [°C]")
        for ax in axes:
            if used[0] > 0:
                ax.axvspan(report.time_at(0), report.time_at(used[0]), color=UNUSED_COLOR, alpha=0.5,
                           linewidth=0)
            if used[1] < report.n:
                ax.axvspan(report.time_at(used[1]), t_end, color=UNUSED_COLOR, alpha=0.5,
                           linewidth=0)
            ax.set_xlim(report.time_at(0), t_end)
        axes[-1].set_xlabel(f"Time [{unit_t}]")
        verdict = (f"not static: {len(report.segments)} flagged range(s)" if report.moving
                   else "no range flagged")
        axes[0].set_title(f"Stationarity: {verdict}"
                          + ("" if used == (0, report.n) else "; grey: not used"))
    return fig


#: colour of a datasheet's curves (grey, dashed: a reference, not an estimate)
DATASHEET_COLOR = "#777777"


def add_datasheet_line(ax: Axes, x: Sequence[float], y: Sequence[float],
                       label: str = "Datasheet") -> Axes:
    """Draw a datasheet's curve (its WV or Allan deviation, from
    :func:`gmwm.sensor_datasheet.datasheet_curves`) on an existing log-log plot: a grey dash-dot
    line (gid ``datasheet``), added to the legend."""
    with style():
        ax.plot(np.asarray(x, float), positive(np.asarray(y, float)), ls="-.", lw=1.3,
                color=DATASHEET_COLOR, label=label, gid="datasheet", zorder=4)
        ax.legend()
    return ax


def plot_plan(seconds: Sequence[float], rse: Mapping[str, Sequence[float]], plan: Any, *,
              ax: Axes | None = None) -> Axes:
    """Predicted relative standard error [%] of every coefficient against the recording length
    [h] (log-log) for a :class:`gmwm.plan.Plan`: one line per coefficient (``rse[name]`` at
    ``seconds``), markers at the plan's lengths, the identifiability limit (relative SE 51 %,
    dashed) and each target (dotted)."""
    from gmwm.plan import IDENTIFIABLE_RSE

    ax = new_axes(ax)
    hours = np.asarray(seconds, float) / 3600.0
    skip = f"{plan.bi}.sigma" if getattr(plan, "bi", None) else None
    with style():
        for i, (name, y) in enumerate((k, v) for k, v in rse.items() if k != skip):
            color = PALETTE[1:][i % (len(PALETTE) - 1)]
            ax.plot(hours, 100 * positive(np.asarray(y, float)), color=color, label=name,
                    gid=f"plan_{name}")
            pts = [(p.seconds / 3600.0, p.coefficients.get(name, {}).get("rse"))
                   for p in plan.predictions]
            pts = [(h, 100 * r) for h, r in pts if r is not None and np.isfinite(r)]
            if pts:
                ax.plot(*zip(*pts, strict=True), "o", color=color, ms=3.5)
        ax.axhline(100 * IDENTIFIABLE_RSE, ls="--", lw=0.9, color=PALETTE[0],
                   label="identifiability limit (51 %)", gid="identifiable")
        for t in getattr(plan, "targets", {}).values():
            ax.axhline(100 * t["relative_se"], ls=":", lw=0.9, color=PALETTE[5],
                       gid="target")
            if t["seconds"] is not None:
                ax.axvline(t["seconds"] / 3600.0, ls=":", lw=0.9, color=PALETTE[5])
        finish_loglog(ax, "Recording length [h]", "Relative standard error [%]")
        lo, hi = ax.get_ylim()
        if hi > 2e3:  # far beyond identifiable: keep the useful range readable
            ax.set_ylim(lo, 2e3)
    return ax
