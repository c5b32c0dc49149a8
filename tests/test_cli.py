"""The ``gmwm`` command line: every command in-process through ``main([...])``, one subprocess run of
the installed entry point, and every bad-input case (non-zero status, one line on stderr, no
traceback)."""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import json
import subprocess

import h5py
import numpy as np
import pytest

from gmwm.cli import main
from gmwm.model import Model
from gmwm.wv import wvar

WN_AR1 = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1}
PARAMS = [a for name, v in WN_AR1.items() for a in ("--param", f"{name}={v}")]
PNG = b"\x89PNG\r\n\x1a\n"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture(scope="module")
def signal_files(tmp_path_factory) -> dict:
    """One WN+AR1 signal (T = 2^13) written as .npy, a two-column .csv and an HDF5 file."""
    d = tmp_path_factory.mktemp("signals")
    model = Model("WN+AR1")
    x = model.simulate(model.theta(WN_AR1), 2**13, np.random.default_rng(7))
    np.save(d / "x.npy", x)
    (d / "x.csv").write_text("t,gyro\n" + "".join(f"{i},{float(v)!r}\n" for i, v in enumerate(x)))
    with h5py.File(d / "x.h5", "w") as fh:
        fh.create_dataset("imu/gyro", data=x)
        fh.create_dataset("imu/accel", data=2 * x)
    return {"x": x, "dir": d, "npy": d / "x.npy", "csv": d / "x.csv", "h5": d / "x.h5"}


# ---- help -------------------------------------------------------------------------------------


@pytest.mark.parametrize("cmd", ["simulate", "wv", "av", "fit", "model-wv"])
def test_subcommand_help_explains_with_example(capsys, cmd):
    code, out, _ = run(capsys, cmd, "--help")
    assert code == 0
    assert f"usage: gmwm {cmd}" in out and "example" in out and "exit status" in out


def test_installed_entry_point_help():
    proc = subprocess.run(["gmwm", "--help"], capture_output=True, text=True, timeout=60,
                          check=False)
    assert proc.returncode == 0
    for cmd in ("simulate", "wv", "av", "fit", "model-wv"):
        assert cmd in proc.stdout


# ---- simulate ---------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", [".npy", ".csv", ".h5"])
def test_simulate_is_reproducible_in_every_format(capsys, tmp_path, ext):
    out = tmp_path / f"s{ext}"
    code, text, err = run(capsys, "simulate", "WN+AR1", *PARAMS, "-n", 1000, "--seed", 5, "-o", out)
    assert code == 0 and err == "" and "1000 samples" in text
    from gmwm.io import read_signal

    model = Model("WN+AR1")
    expected = model.simulate(model.theta(WN_AR1), 1000, np.random.default_rng(5))
    np.testing.assert_array_equal(read_signal(out), expected)


def test_simulate_json(capsys, tmp_path):
    code, out, _ = run(capsys, "simulate", "WN+AR1", *PARAMS, "-n", 100, "-o", tmp_path / "a.npy",
                       "--json")
    obj = json.loads(out)
    assert code == 0 and obj["n"] == 100 and obj["params"]["AR1[1].phi"] == 0.9


# ---- wv / av ----------------------------------------------------------------------------------


def test_wv_json_matches_library_and_plot_is_png(capsys, signal_files, tmp_path):
    png = tmp_path / "wv.png"
    code, out, err = run(capsys, "wv", signal_files["npy"], "--freq", 100, "--json", "--plot", png)
    assert code == 0 and err == ""
    obj = json.loads(out)
    ref = wvar(signal_files["x"], freq=100.0)
    np.testing.assert_allclose(obj["variance"], ref.variance, rtol=1e-14)
    np.testing.assert_allclose(obj["ci_low"], ref.ci_low, rtol=1e-14)
    np.testing.assert_allclose(obj["ci_high"], ref.ci_high, rtol=1e-14)
    np.testing.assert_allclose(obj["scales_s"], ref.scales / 100.0)
    assert obj["n"] == ref.n.tolist() and obj["n_samples"] == 2**13
    assert obj["seconds"] >= 0
    assert png.read_bytes()[:8] == PNG


@pytest.mark.parametrize(("fmt", "opts"), [("csv", ["--column", "gyro"]), ("csv", ["--column", "1"]),
                                           ("h5", ["--dataset", "/imu/gyro"])])
def test_wv_reads_csv_and_hdf5_like_npy(capsys, signal_files, fmt, opts):
    code, out, _ = run(capsys, "wv", signal_files[fmt], *opts, "--levels", 6, "--json")
    assert code == 0
    ref = wvar(signal_files["x"], levels=6)
    np.testing.assert_allclose(json.loads(out)["variance"], ref.variance, rtol=1e-14)


def test_wv_text_table(capsys, signal_files):
    code, out, _ = run(capsys, "wv", signal_files["npy"], "--levels", 5)
    lines = out.strip().splitlines()
    assert code == 0 and lines[1].split()[0] == "level"
    assert len(lines) == 3 + 5  # title, header, rule, one row per level
    assert float(lines[3].split()[3]) == pytest.approx(wvar(signal_files["x"], levels=5).variance[0],
                                                       rel=1e-5)


def test_av_is_twice_wv(capsys, signal_files, tmp_path):
    code, out, _ = run(capsys, "av", signal_files["npy"], "--freq", 10, "--json",
                       "--plot", tmp_path / "av.png")
    obj = json.loads(out)
    ref = wvar(signal_files["x"])
    assert code == 0
    np.testing.assert_allclose(obj["variance"], 2 * ref.variance, rtol=1e-14)
    np.testing.assert_allclose(obj["tau_s"], ref.scales / 2 / 10.0)
    assert obj["seconds"] >= 0 and (tmp_path / "av.png").read_bytes()[:8] == PNG


# ---- fit --------------------------------------------------------------------------------------


def test_fit_json_recovers_truth_and_plots(capsys, signal_files, tmp_path):
    png = tmp_path / "fit.png"
    code, out, err = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--json", "--plot", png)
    assert code == 0, err
    obj = json.loads(out)
    for key in ("model", "n", "params", "se", "objective", "converged", "wv", "seconds_wv",
                "seconds_fit"):
        assert key in obj
    assert obj["model"] == "WN+AR1" and obj["n"] == 2**13 and obj["converged"] is True
    assert len(obj["wv"]["variance"]) == 12  # floor(log2 T) - 1
    # each estimate within 5 of its own asymptotic standard errors of the truth
    for name, truth in WN_AR1.items():
        assert abs(obj["params"][name] - truth) < 5 * obj["se"][name], name
    assert png.read_bytes()[:8] == PNG


def test_fit_text_output(capsys, signal_files):
    code, out, _ = run(capsys, "fit", signal_files["h5"], "WN+AR1", "--dataset", "imu/gyro")
    assert code == 0
    assert "AR1[1].phi" in out and "converged yes" in out and "ci95_low" in out


def test_fit_from_wv_table_equals_fit_from_signal(capsys, signal_files, tmp_path):
    table = tmp_path / "wv.csv"
    assert run(capsys, "wv", signal_files["npy"], "-o", table)[0] == 0
    code, out, _ = run(capsys, "fit", table, "WN+AR1", "--json")
    from_table = json.loads(out)
    code2, out2, _ = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--json")
    assert code == code2 == 0
    for name in WN_AR1:
        assert from_table["params"][name] == pytest.approx(json.loads(out2)["params"][name],
                                                           rel=1e-6)
    # the same table without its 'n' column needs --n-samples
    lines = table.read_text().splitlines()
    cols = lines[0].split(",")
    keep = [i for i, c in enumerate(cols) if c in ("scale", "variance", "ci_low", "ci_high")]
    bare = tmp_path / "bare.csv"
    bare.write_text("\n".join(",".join(r.split(",")[i] for i in keep) for r in lines) + "\n")
    code, _, err = run(capsys, "fit", bare, "WN+AR1")
    assert code == 1 and "--n-samples" in err
    code, out, _ = run(capsys, "fit", bare, "WN+AR1", "--n-samples", 2**13, "--json")
    assert code == 0 and json.loads(out)["n"] == 2**13


def test_fit_avsm_method(capsys, tmp_path):
    model = Model("WN+RW")
    x = model.simulate(np.array([1.0, 1e-4]), 2**14, np.random.default_rng(2))
    np.save(tmp_path / "x.npy", x)
    code, out, _ = run(capsys, "fit", tmp_path / "x.npy", "WN+RW", "--method", "avsm", "--json")
    obj = json.loads(out)
    assert code == 0 and obj["method"] == "avsm" and obj["se"]["WN[1].sigma2"] is None
    assert obj["params"]["WN[1].sigma2"] == pytest.approx(1.0, rel=0.2)  # slope method is crude


def test_fit_not_converged_exits_3_with_estimate(capsys, signal_files, monkeypatch):
    # the CLI calls the public gmwm.fit
    import gmwm

    real = gmwm.fit

    def not_converged(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), converged=False,
                                   message="iteration limit reached")

    monkeypatch.setattr(gmwm, "fit", not_converged)
    code, out, err = run(capsys, "fit", signal_files["npy"], "WN+AR1")
    assert code == 3
    assert "AR1[1].phi" in out and "converged NO" in out
    assert err.count("\n") == 1 and "did not converge (iteration limit reached)" in err


def test_fit_check(capsys, signal_files):
    code, out, err = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--check")
    if importlib.util.find_spec("gmwm.identify") is None:
        assert code == 1 and err.count("\n") == 1 and "gmwm.identify" in err
    else:
        assert code in (0, 3) and "AR1[1].phi" in out


# ---- model-wv ---------------------------------------------------------------------------------


def test_model_wv_json_text_and_plot(capsys, tmp_path):
    code, out, _ = run(capsys, "model-wv", "WN+AR1", *PARAMS, "--levels", 8, "--freq", 4, "--json",
                       "--plot", tmp_path / "m.png")
    obj = json.loads(out)
    model = Model("WN+AR1")
    scales = 2.0 ** np.arange(1, 9)
    assert code == 0 and obj["scales"] == scales.tolist()
    np.testing.assert_allclose(obj["total"], model.wv(model.theta(WN_AR1), scales), rtol=1e-14)
    np.testing.assert_allclose(obj["total"], np.sum(list(obj["components"].values()), axis=0))
    assert (tmp_path / "m.png").read_bytes()[:8] == PNG
    code, out, _ = run(capsys, "model-wv", "WN+AR1", *PARAMS, "-J", 3)
    assert code == 0 and "WN[1]" in out.splitlines()[1] and len(out.strip().splitlines()) == 6


# ---- bad input: one line on stderr, non-zero status, no traceback ------------------------------


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory) -> dict:
    d = tmp_path_factory.mktemp("bad")
    x = np.random.default_rng(0).standard_normal(256)
    y = x.copy()
    y[10] = np.nan
    np.save(d / "nan.npy", y)
    y[10] = np.inf
    np.save(d / "inf.npy", y)
    np.save(d / "short.npy", x[:20])
    np.save(d / "tiny.npy", x[:16])
    (d / "two.csv").write_text("a,b\n" + "".join(f"{float(v)!r},{float(v)!r}\n" for v in x))
    (d / "text.csv").write_text("v\n1\n2\nthree\n")
    (d / "x.xlsx").write_text("1\n")
    return {k: d / v for k, v in [("nan", "nan.npy"), ("inf", "inf.npy"), ("short", "short.npy"),
                                  ("tiny", "tiny.npy"), ("two", "two.csv"), ("text", "text.csv"),
                                  ("xlsx", "x.xlsx"), ("missing", "nope.npy")]}


BAD_CASES = {
    "nan": (["wv", "{nan}"], 1, "NaN"),
    "inf": (["fit", "{inf}", "WN"], 1, "inf"),
    "too short for levels": (["wv", "{short}", "--levels", "6"], 1, "too short for --levels 6"),
    "unknown process (fit)": (["fit", "{short}", "WN+FOO"], 1, "unknown process 'FOO'"),
    "unknown process (simulate)": (["simulate", "WN+FOO", "-n", "10", "-o", "{dir}/o.npy"], 1,
                                   "unknown process 'FOO'"),
    "more parameters than scales": (["fit", "{tiny}", "WN+RW+AR1"], 1,
                                    "more parameters than scales"),
    "more parameters than levels": (["fit", "{short}", "WN+AR1", "--levels", "2"], 1,
                                    "raise --levels"),
    "missing column": (["wv", "{two}", "--column", "c"], 1, "column 'c' not found"),
    "several columns": (["fit", "{two}", "WN"], 1, "--column"),
    "non-numeric column": (["wv", "{text}"], 1, "not numeric"),
    "missing file": (["fit", "{missing}", "WN"], 1, "file not found"),
    "unknown extension": (["wv", "{xlsx}"], 1, "unknown file extension"),
    "malformed --param": (["model-wv", "WN", "--param", "WN[1].sigma2:1", "-J", "3"], 2,
                          "malformed --param"),
    "non-numeric --param": (["model-wv", "WN", "--param", "WN[1].sigma2=abc", "-J", "3"], 2,
                            "not a number"),
    "unknown parameter": (["model-wv", "WN", "--param", "AR1[1].phi=0.5", "-J", "3"], 1,
                          "unknown parameter"),
    "missing parameter": (["model-wv", "WN+RW", "--param", "WN[1].sigma2=1", "-J", "3"], 1,
                          "missing value"),
    "bad option value": (["fit", "{short}", "WN", "--weights", "foo"], 2, "invalid choice"),
    "no command": ([], 2, "required"),
    "bad plot extension": (["wv", "{short}", "--plot", "{dir}/p.gif"], 2, "--plot"),
    "bad output extension": (["simulate", "WN", "-p", "WN[1].sigma2=1", "-n", "5", "-o",
                              "{dir}/o.xyz"], 1, "unknown output extension"),
}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_input_is_one_line_error(capsys, bad_files, case):
    argv, status, needle = BAD_CASES[case]
    fmt = {**{k: str(v) for k, v in bad_files.items()}, "dir": str(bad_files["nan"].parent)}
    code, _, err = run(capsys, *(a.format(**fmt) for a in argv))
    assert code == status
    assert err.count("\n") == 1 and err.startswith("gmwm: error: "), err
    assert needle in err
    assert "Traceback" not in err
