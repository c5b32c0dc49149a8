"""The report's division of work: a warm server that loads the fitting stack beside the reading
and forks warm choice workers (reaped at the end), workers that also draw each axis's figure and
compute its datasheet and readings (the page must be the same as when everything runs in one
process), and page figures laid out with fixed margins (nothing may fall outside the figure)."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from gmwm import Model, calibrate
from gmwm.cli import main


def _probe(_: int) -> tuple[bool, int]:
    """In a worker: is the fitting stack already loaded, and which process is this."""
    return "gmwm.automodel" in sys.modules and "gmwm.search" in sys.modules, os.getpid()


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.fixture
def two_cores():
    if calibrate.available_cores() < 2 or os.name != "posix":
        pytest.skip("the warm server needs two cores and a forkserver")


@pytest.mark.slow
def test_warm_server_forks_warm_workers_and_is_reaped(two_cores):
    from multiprocessing import forkserver

    assert calibrate.start_warm_server()
    pid = forkserver._forkserver._forkserver_pid
    try:
        with calibrate.executor("process", 2, warm=True) as pool:
            got = list(pool.map(_probe, range(4)))
    finally:
        calibrate.stop_warm_server()
    assert all(warm for warm, _ in got)
    assert os.getpid() not in {p for _, p in got}
    assert not calibrate.warm_server_running()
    assert _gone(pid)  # waited for: no process outlives the command


def test_unused_warm_server_is_stopped_without_waiting_for_its_loading(two_cores):
    from multiprocessing import forkserver

    assert calibrate.start_warm_server()
    pid = forkserver._forkserver._forkserver_pid
    calibrate.stop_warm_server()  # one channel after all: no pool was made
    assert _gone(pid) and not calibrate.warm_server_running()


@pytest.fixture(scope="module")
def imu_csv(tmp_path_factory):
    """Three axes at 100 Hz: two gyros (WN+RW), one accelerometer (WN+GM+RW)."""
    fs, n = 100.0, 2 ** 13
    rng = np.random.default_rng(5)
    g = Model("WN+RW", freq=fs)
    tg = g.theta({"WN[1].sigma2": 1e-4, "RW[1].gamma2": 1e-10})
    a = Model("WN+GM+RW", freq=fs)
    ta = a.theta({"WN[1].sigma2": 4e-4, "GM[1].beta": 2.0, "GM[1].sigma2": 1e-4,
                  "RW[1].gamma2": 1e-10})
    cols = {"time": np.arange(n) / fs, "gx": g.simulate(tg, n, rng), "gy": g.simulate(tg, n, rng),
            "ax": a.simulate(ta, n, rng)}
    p = tmp_path_factory.mktemp("rw") / "imu.csv"
    np.savetxt(p, np.column_stack(list(cols.values())), delimiter=",", fmt="%.17g",
               header=",".join(cols), comments="")
    return p


@pytest.mark.slow
def test_report_from_workers_equals_report_from_one_process(imu_csv, tmp_path, monkeypatch,
                                                           two_cores, capsys):
    args = ["report", str(imu_csv), "--columns", "all", "--units", "gx,gy=deg/s",
            "--units", "ax=m/s^2"]
    assert main([*args, "-o", str(tmp_path / "par")]) == 0
    monkeypatch.setattr(calibrate, "available_cores", lambda: 1)
    assert main([*args, "-o", str(tmp_path / "one")]) == 0
    capsys.readouterr()
    for name in ("report.md", "report.html", "imu.yaml"):
        assert (tmp_path / "par" / name).read_text() == (tmp_path / "one" / name).read_text()
    for c in ("gx", "gy", "ax"):
        assert (tmp_path / "par" / f"{c}_wv.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not calibrate.warm_server_running()


def test_power_of_ten_labels():
    from gmwm.plots import power_of_ten_label

    assert power_of_ten_label(1e-3) == "10\u207b\u00b3"
    assert power_of_ten_label(1e12) == "10\u00b9\u00b2"
    assert power_of_ten_label(1.0) == "10\u2070"
    assert power_of_ten_label(3e-3) == "" and power_of_ten_label(0.0) == ""


def _outside(fig) -> list[str]:
    """Texts of ``fig`` (tick labels, axis labels, titles) drawn outside the figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box = fig.bbox
    bad = []
    for ax in fig.get_axes():
        texts = [ax.title, ax.xaxis.label, ax.yaxis.label]
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            texts += [t.label1 for t in axis.get_major_ticks()
                      if lo <= t.get_loc() <= hi and t.label1.get_visible()]
        for t in texts:
            if not t.get_text() or not t.get_visible():
                continue
            e = t.get_window_extent(renderer)
            if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 \
                    or e.y1 > box.y1 + 0.5:
                bad.append(t.get_text())
    return bad


def test_page_layout_keeps_every_label_inside_the_figure():
    import gmwm
    from gmwm.plots import page_layout, plot_wv

    rng = np.random.default_rng(0)
    # tiny values and a compound unit: the widest tick labels and axis label a page gets
    x = 1e-6 * rng.standard_normal(2 ** 14) + 1e-8 * np.cumsum(rng.standard_normal(2 ** 14))
    res = gmwm.fit(x, "WN+RW", freq=1000.0)
    ax = plot_wv(res.wv, result=res, units="m/s^2")
    ax.set_title("a_RS_S_x: QN+WN+GM+SIN+RW")
    fig = page_layout(ax.figure)
    assert fig.get_layout_engine() is None
    assert _outside(fig) == []


def test_stationarity_page_layout_keeps_labels_inside(tmp_path):
    from gmwm.plots import page_layout, plot_stationarity
    from gmwm.stationarity import check_stationarity

    rng = np.random.default_rng(1)
    n, fs = 20000, 100.0
    x = {"gx": 1e-3 * rng.standard_normal(n), "az": 9.81 + 0.02 * rng.standard_normal(n)}
    x["gx"][8000:9000] += 0.5  # a flagged range
    st = check_stationarity(x, freq=fs, units={"gx": "rad/s", "az": "m/s^2"})
    fig = page_layout(plot_stationarity(st))
    assert _outside(fig) == []


def test_bad_input_stops_the_warm_server(two_cores, tmp_path, capsys):
    # the server starts before the file is read: an unreadable file must not leave it running
    from multiprocessing import forkserver

    bad = tmp_path / "bad.csv"
    bad.write_text("time,gx\n0,1\n")
    assert main(["report", str(bad), "-o", str(tmp_path / "out")]) != 0
    capsys.readouterr()
    assert not calibrate.warm_server_running()
    assert getattr(forkserver._forkserver, "_forkserver_pid", None) is None


def test_calibrate_and_report_import_no_cycle_and_no_private_names():
    # report renders what calibrate returns: calibrate must not import report, not even inside a
    # function, and neither (nor the CLI) imports another module's _private name
    import ast
    from pathlib import Path

    import gmwm

    src = Path(gmwm.__file__).parent
    files = [src / "calibrate.py", src / "report.py", *sorted((src / "cli").rglob("*.py"))]
    for f in files:
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("gmwm"):
                assert not (f.name == "calibrate.py" and node.module == "gmwm.report"), f
                assert all(not a.name.startswith("_") or a.name.startswith("__")
                           for a in node.names), (f, node.lineno)
            if isinstance(node, ast.Import):
                assert not (f.name == "calibrate.py"
                            and any(a.name == "gmwm.report" for a in node.names)), f


@pytest.mark.slow
def test_identifiability_from_the_workers_equals_the_verdicts_own(imu_csv, two_cores):
    # the workers search each axis's identifiable length beside its fit; the verdict must be the
    # one it computes itself when every fit runs in this process
    from gmwm.verdict import decide

    kw = {"columns": "all", "units": {"gx": "deg/s", "gy": "deg/s", "ax": "m/s^2"},
          "require_time": None}
    par = calibrate.calibrate(str(imu_csv), "auto", workers=2, **kw).only()
    alone = calibrate.calibrate(str(imu_csv), "auto", workers=1, **kw).only()
    assert par.verdict.unidentified  # the case has terms this length cannot identify
    assert par.verdict == alone.verdict
    own = decide({c: a.choice for c, a in par.axes.items()}, n_samples=2 ** 13,
                 kinds={"gx": "gyroscope", "gy": "gyroscope", "ax": "accelerometer"},
                 to_si={"gx": np.pi / 180, "gy": np.pi / 180, "ax": 1.0})
    assert own.unidentified == par.verdict.unidentified
