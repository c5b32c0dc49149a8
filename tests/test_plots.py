"""gmwm.plots and the studies' figures (gmwm_studies.figures): every figure draws on small inputs
and shows what it claims.

The modules build Figures without pyplot, so no backend needs selecting (saving uses Agg)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from gmwm.atomic import save_figure
from gmwm.model import Model
from gmwm.plots import (
    plot_av,
    plot_model_wv,
    plot_virtual_wv,
    plot_wv,
    subplots,
    variance_label,
)
from gmwm.wv import avar, wvar
from gmwm_studies.figures import (
    boxplot_grouped,
    boxplot_standardized,
    plot_rmse_curves,
    plot_runtime,
    plot_wv_replicates,
)

SIM1 = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
        "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35}


@pytest.fixture(scope="module")
def sim1():
    model = Model("WN+RW+AR1+SIN", freq=100.0)
    theta = model.theta(SIM1)
    x = model.simulate(theta, 2**12, np.random.default_rng(3))
    return model, theta, wvar(x, freq=100.0)


def _component_lines(ax):
    return [ln for ln in ax.get_lines() if ln.get_gid() == "component"]


def test_plot_wv_band_components_and_axes(sim1, tmp_path):
    model, theta, wv = sim1
    ax = plot_wv(wv, model=model, theta=theta, units="deg/s")
    band = [c for c in ax.collections if c.get_gid() == "ci_band"]
    assert len(band) == 1 and isinstance(band[0], PolyCollection)
    verts = band[0].get_paths()[0].vertices
    # the polygon spans exactly ci_low..ci_high, at x = scales in seconds
    np.testing.assert_allclose(verts[:, 1].min(), wv.ci_low.min())
    np.testing.assert_allclose(verts[:, 1].max(), wv.ci_high.max())
    np.testing.assert_allclose([verts[:, 0].min(), verts[:, 0].max()],
                               [wv.scales[0] / 100.0, wv.scales[-1] / 100.0])
    comps = _component_lines(ax)
    assert [ln.get_label() for ln in comps] == model.component_names
    np.testing.assert_allclose(comps[0].get_ydata(), model.component_wv(theta, wv.scales)["WN[1]"])
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert ax.get_xlabel() == "Scale τ [s]"
    assert ax.get_ylabel() == "Wavelet variance [(deg/s)²]"
    assert save_figure(ax.figure, tmp_path / "wv.png")[0].stat().st_size > 1000


def test_plot_wv_from_result_dict_theta_and_no_components(sim1):
    model, theta, wv = sim1

    class Result:  # the fields plot_wv reads from a GMWM result (docs/API.md)
        pass

    res = Result()
    res.model, res.params, res.wv = model, theta, wv
    ax = plot_wv(wv, result=res)
    assert len(_component_lines(ax)) == 4
    ax2 = plot_wv(wv, model=model, theta=model.as_dict(theta), components=False)
    assert _component_lines(ax2) == []
    model_line = next(ln for ln in ax2.get_lines() if ln.get_label() == "Model")
    np.testing.assert_allclose(model_line.get_ydata(), model.wv(theta, wv.scales))


def test_plot_wv_single_component_and_samples_axis():
    model = Model("WN")
    x = model.simulate(np.array([2.0]), 512, np.random.default_rng(0))
    wv = wvar(x)
    ax = plot_wv(wv, model=model, theta=[2.0])
    assert _component_lines(ax) == []  # the model line is the component
    assert ax.get_xlabel() == "Scale τ [samples]"
    assert ax.get_ylabel() == "Wavelet variance"


def test_plot_wv_draws_into_given_axes(sim1):
    _, _, wv = sim1
    fig, (ax, ax2) = subplots(1, 2)
    assert ax.figure is fig
    assert plot_wv(wv, ax=ax) is ax
    assert len(ax.get_lines()) == 1 and ax2.get_lines() == []
    assert not ax.spines["top"].get_visible()  # the grid was made in the project style
    assert plot_wv(wv, ax=Figure().add_subplot()).get_xscale() == "log"


def test_plot_av_uses_cluster_time():
    x = np.random.default_rng(0).standard_normal(1024)
    av = avar(x, freq=10.0)
    ax = plot_av(av, units="m/s")
    line = ax.get_lines()[0]
    np.testing.assert_allclose(line.get_xdata(), av.clusters / 10.0)
    np.testing.assert_allclose(line.get_ydata(), av.avar)
    assert ax.get_xlabel() == "Cluster time τ [s]"


def test_plot_model_wv_total_equals_sum_of_components(sim1):
    model, theta, _ = sim1
    scales = 2.0 ** np.arange(1, 11)
    ax = plot_model_wv(model, theta, scales, freq=100.0)
    total = next(ln for ln in ax.get_lines() if ln.get_gid() != "component").get_ydata()
    comps = np.nansum([ln.get_ydata() for ln in _component_lines(ax)], axis=0)
    np.testing.assert_allclose(total, comps, rtol=1e-12)


def test_plot_virtual_wv_draws_every_signal_and_the_virtual_band():
    from gmwm.virtual import equal

    X = np.random.default_rng(4).standard_normal((2048, 3))
    res = equal(X, freq=10.0, names=["a", "b", "c"])
    ax = plot_virtual_wv(res, units="deg/s")
    labels = [ln.get_label() for ln in ax.get_lines()]
    assert labels == ["a", "b", "c", "virtual (equal)"]
    np.testing.assert_allclose(ax.get_lines()[3].get_ydata(), res.wv().variance)
    np.testing.assert_allclose(ax.get_lines()[0].get_xdata(), res.wccv.scales / 10.0)
    assert len([c for c in ax.collections if isinstance(c, PolyCollection)]) == 1
    assert ax.get_xlabel() == "Scale τ [s]"

def test_plot_wv_replicates(sim1):
    model, theta, _ = sim1
    scales = 2.0 ** np.arange(1, 9)
    v = model.wv(theta, scales) * np.exp(0.1 * np.random.default_rng(0).standard_normal((7, 8)))
    ax = plot_wv_replicates(scales, v, model, theta, freq=100.0)
    reps = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(reps) == 1 and len(reps[0].get_segments()) == 7
    assert len(_component_lines(ax)) == 4
    lo, hi = ax.get_ylim()
    assert lo <= v.min() and hi >= v.max()
    with pytest.raises(ValueError, match="scales"):
        plot_wv_replicates(scales[:-1], v, model, theta)


def test_boxplot_standardized_dict_and_array():
    rng = np.random.default_rng(0)
    data = {"sigma2": rng.standard_normal(50), "phi": rng.standard_normal(50)}
    ax = boxplot_standardized(data, title="T = 1000", math_labels=False)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["sigma2", "phi"]
    zero = [ln for ln in ax.get_lines() if ln.get_gid() == "zero_line"]
    assert len(zero) == 1 and set(zero[0].get_ydata()) == {0.0}
    assert len(ax.patches) == 2  # one box per parameter
    ax2 = boxplot_standardized(rng.standard_normal((30, 3)), labels=["a", "b", "c"])
    assert len(ax2.patches) == 3
    with pytest.raises(ValueError, match="labels"):
        boxplot_standardized(rng.standard_normal((30, 3)), labels=["a"])


def test_boxplot_grouped_side_by_side():
    rng = np.random.default_rng(0)
    vals = {"GMWM": {"a": rng.standard_normal(20), "b": rng.standard_normal(20)},
            "MLE": {"a": rng.standard_normal(20), "b": rng.standard_normal(20)}}
    ax = boxplot_grouped(vals)
    assert len(ax.patches) == 4
    centres = sorted(p.get_path().vertices[:, 0].mean() for p in ax.patches)
    assert centres[0] < 1 < centres[1] < centres[2] < 2 < centres[3]  # pairs around each tick
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["GMWM", "MLE"]


def test_plot_rmse_curves_one_log_panel_per_parameter():
    T = np.array([1e4, 2e4, 4e4])
    rmse = {"GMWM": {"a": [3, 2, 1.0], "b": [1, 0.7, 0.5], "c": [1, 1, 1.0]},
            "MLE": {"a": [2, 1, 0.5], "b": [0.5, 0.3, 0.2]}}
    fig = plot_rmse_curves(T, rmse)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == ["a", "b", "c"]
    assert all(ax.get_xscale() == "log" and ax.get_yscale() == "log" for ax in axes)
    assert [len(ax.get_lines()) for ax in axes] == [2, 2, 1]


def test_plot_runtime_annotates_speedup():
    T = [1e4, 1e5]
    ax = plot_runtime(T, {"MLE": [2.0, 300.0], "GMWM": [0.01, 0.1]})
    texts = [t.get_text() for t in ax.texts if t.get_gid() == "speedup"]
    assert texts == ["×200", "×3000"]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"


def test_variance_label():
    assert variance_label("Wavelet variance", "m") == "Wavelet variance [m²]"
    assert variance_label("Allan variance", "rad/s") == "Allan variance [(rad/s)²]"
    assert variance_label("Wavelet variance") == "Wavelet variance"


def test_component_at_zero_is_not_drawn_or_named(sim1):
    model, theta, wv = sim1
    th = np.array(theta, dtype=float)
    th[model.param_names.index("RW[1].gamma2")] = 0.0  # RW estimated at the boundary
    ax = plot_wv(wv, model=model, theta=th)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "RW[1]" not in labels and "WN[1]" in labels
    assert len(_component_lines(ax)) == 3


def test_plot_av_deviation_with_readings_and_channel_grid():
    from gmwm.datasheet import allan_readings
    from gmwm.plots import channel_grid

    fs = 100.0
    model = Model("WN+RW", freq=fs)
    x = model.simulate(np.array([1e-4 * fs, 1e-6 / fs]), 2**16, np.random.default_rng(5))
    av = avar(x, freq=fs)
    fig, axes = channel_grid(4)
    assert len(axes) == 4 and sum(a.get_visible() for a in fig.axes) == 4
    ax = plot_av(av, ax=axes[0], deviation=True, readings=allan_readings(av), units="rad/s")
    main = next(ln for ln in ax.get_lines() if ln.get_label() == "Allan deviation")
    np.testing.assert_allclose(main.get_ydata(), np.sqrt(av.avar))
    gids = {ln.get_gid() for ln in ax.get_lines()}
    assert {"reading_N", "reading_B"} <= gids
    assert ax.get_ylabel() == "Allan deviation [rad/s]"


def test_param_label_uses_the_papers_notation():
    from gmwm.plots import param_label

    names = ["WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "AR1[2].phi", "SIN[1].beta",
             "GM[1].sigma2", "RW[1].gamma2"]
    got = [param_label(n, names) for n in names]
    assert got == [r"$\sigma^2$", r"$\phi_{1}$", r"$\varsigma_{1}^2$", r"$\phi_{2}$",
                   r"$\beta$", r"$\sigma_{GM}^2$", r"$\gamma^2$"]
    assert param_label("not a parameter") == "not a parameter"


def test_boxplot_marks_and_counts_flagged_replicates():
    rng = np.random.default_rng(1)
    z = rng.standard_normal(40)
    bnd = np.zeros(40, bool)
    bnd[:3] = True
    sw = np.zeros(40, bool)
    sw[5:12] = True
    data = {"AR1[1].phi": {"z": z, "boundary": bnd, "switched": sw},
            "WN[1].sigma2": {"z": z, "boundary": np.zeros(40, bool), "switched": np.zeros(40, bool)}}
    ax = boxplot_standardized(data)
    marks = {ln.get_gid(): len(ln.get_xdata()) for ln in ax.get_lines()
             if (ln.get_gid() or "").startswith("mark_")}
    assert marks == {"mark_boundary": 3, "mark_switched": 7}
    counts = [t.get_text() for t in ax.texts if t.get_gid() == "mark_counts"]
    assert counts == ["b 3\ns 7"]  # only the flagged parameter gets a count
    assert [t.get_text() for t in ax.get_xticklabels()] == [r"$\phi$", r"$\sigma^2$"]


def test_corner_plot_log_coordinates_for_scale_parameters():
    from gmwm.identify import corner_plot

    rng = np.random.default_rng(2)
    phi = 0.9 + 0.01 * rng.standard_normal(400)
    s2 = 10 ** rng.normal(-6, 1, 400)  # spans decades: shown as log10
    fig = corner_plot(np.column_stack([phi, s2]), ["AR1[1].phi", "AR1[1].sigma2"],
                      truths=np.array([0.9, 1e-6]))
    ax = fig.axes[3]  # bottom row, second column: the variance's histogram
    lo, hi = ax.get_xlim()
    assert -11 < lo < hi < -1  # log10 coordinates, not 0..1e-4
    assert ax.get_xlabel() == r"log10 $\varsigma^2$"
    assert fig.axes[2].get_xlabel() == r"$\phi$"  # phi stays linear
    assert fig.axes[2].get_ylabel() == r"log10 $\varsigma^2$"


def test_plot_wv_marks_the_scales_a_rejected_model_misses():
    import gmwm

    model = gmwm.Model("WN+AR1")
    x = model.simulate(model.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99,
                                    "AR1[1].sigma2": 2e-3}), 2**13, np.random.default_rng(2))
    wrong = gmwm.fit(x, "WN")
    assert wrong.gof.rejected()
    ax = wrong.plot()
    rings = [ln for ln in ax.get_lines() if ln.get_gid() == "gof_miss"]
    u = np.asarray(wrong.gof.residuals)
    assert len(rings) == 1 and len(rings[0].get_xdata()) == int(np.sum(np.abs(u) > 2))
    labels = [t.get_text() for t in ax.texts if t.get_gid() == "gof_miss_label"]
    assert labels == [f"{v:+.1f}" for v in u[np.abs(u) > 2]]
    assert "rejected" in ax.get_legend().get_title().get_text()
    right = gmwm.fit(x, model)
    ax = right.plot(residuals=False)
    assert not [ln for ln in ax.get_lines() if ln.get_gid() == "gof_miss"]
