"""The ``gmwm`` command line: every command in-process through ``main([...])``, one subprocess run of
the installed entry point, and every bad-input case (non-zero status, one line on stderr, no
traceback)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import h5py
import numpy as np
import pytest
import yaml

from conftest import c_toolchain, needs_c_kernel
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
    (d / "x.csv").write_text("t_s,gyro\n" + "".join(f"{i},{float(v)!r}\n" for i, v in enumerate(x)))
    with h5py.File(d / "x.h5", "w") as fh:
        fh.create_dataset("imu/gyro", data=x)
        fh.create_dataset("imu/accel", data=2 * x)
    return {"x": x, "dir": d, "npy": d / "x.npy", "csv": d / "x.csv", "h5": d / "x.h5"}


# ---- help -------------------------------------------------------------------------------------


@pytest.mark.parametrize("cmd", ["simulate", "wv", "av", "fit", "model-wv", "report"])
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
    from gmwm.readers import read_signal

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
    # a seeded WN+AR1 (phi = 0.9, T = 2^13) fitted with its own model: locally and globally
    # identified, so the check passes, in the text and in the JSON, and the exit status is 0
    code, out, err = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--check")
    assert code == 0 and err == ""
    assert "identifiability (WN+AR1): PASS" in out and "rank 3/3" in out
    code, out, _ = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--check", "--json")
    check = json.loads(out)["check"]
    assert code == 0 and check["status"] == "pass" and check["reasons"] == []
    assert check["local"]["rank"] == 3


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
    # the fit's own check (gmwm.fit), not a copy of it in the CLI
    "more parameters than scales": (["fit", "{tiny}", "WN+RW+AR1"], 1,
                                    "4 parameters but only 3 wavelet scales"),
    "more parameters than levels": (["fit", "{short}", "WN+AR1", "--levels", "2"], 1,
                                    "more levels"),
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


# ---- diagnostics a user sees -----------------------------------------------------


@pytest.fixture(scope="module")
def white_noise(tmp_path_factory):
    d = tmp_path_factory.mktemp("wn")
    np.save(d / "wn.npy", np.random.default_rng(3).standard_normal(2**13))
    return d / "wn.npy"


def test_boundary_fit_warns_in_text_and_json(capsys, white_noise):
    # WN+RW on pure white noise: RW ends at the boundary 0, which is a warning, not a failure
    code, out, err = run(capsys, "fit", white_noise, "WN+RW")
    assert code == 0 and "converged yes" in out
    lines = err.splitlines()
    assert lines and all(line.startswith("gmwm: warning: ") for line in lines)
    assert any("RW[1]" in line for line in lines)
    code, out, err_json = run(capsys, "fit", white_noise, "WN+RW", "--json")
    obj = json.loads(out)
    assert code == 0 and obj["params"]["RW[1].gamma2"] == 0.0
    assert obj["warnings"] and any("RW[1]" in w for w in obj["warnings"])
    assert len(obj["warnings"]) == len(lines) and err_json == err


def test_python_warnings_never_reach_stderr(capsys, white_noise, monkeypatch):
    import warnings

    import gmwm

    real = gmwm.fit

    def noisy(*args, **kwargs):
        np.log(np.zeros(1))  # a NumPy RuntimeWarning: divide by zero
        warnings.warn("numerical trouble", RuntimeWarning, stacklevel=1)
        warnings.warn("something the user should know", UserWarning, stacklevel=1)
        return real(*args, **kwargs)

    monkeypatch.setattr(gmwm, "fit", noisy)
    code, _, err = run(capsys, "fit", white_noise, "WN")
    assert code == 0
    assert "RuntimeWarning" not in err and "divide" not in err and "numerical trouble" not in err
    assert "gmwm: warning: something the user should know\n" in err
    assert all(line.startswith("gmwm: ") for line in err.splitlines())


# ---- a whole IMU ---------------------------------------------------------------


@pytest.fixture(scope="module")
def imu(tmp_path_factory) -> dict:
    """A 4-axis CSV (time at 100 Hz, two gyros in deg/s, two accelerometers in m/s^2)."""
    d = tmp_path_factory.mktemp("imu")
    fs, n = 100.0, 2**14
    rng = np.random.default_rng(21)
    gyro, accel = Model("WN+RW", freq=fs), Model("WN+RW", freq=fs)
    tg = gyro.theta({"WN[1].sigma2": 0.15**2 / 3600 * fs, "RW[1].gamma2": (50 / 216000) ** 2 / fs})
    ta = accel.theta({"WN[1].sigma2": 0.05**2 / 3600 * fs, "RW[1].gamma2": (30 / 216000) ** 2 / fs})
    cols = {"time": np.arange(n) / fs, "gx": gyro.simulate(tg, n, rng), "gy": gyro.simulate(tg, n, rng),
            "ax": accel.simulate(ta, n, rng), "ay": accel.simulate(ta, n, rng)}
    p = d / "imu.csv"
    np.savetxt(p, np.column_stack(list(cols.values())), delimiter=",", fmt="%.17g",
               header=",".join(cols), comments="")
    return {"path": p, "cols": cols, "fs": fs, "dir": d}


def test_fit_columns_json_per_column_with_datasheet(capsys, imu):
    code, out, _ = run(capsys, "fit", imu["path"], "gx=WN+RW,gy=WN+RW,WN", "--columns", "all",
                       "--units", "gx,gy=deg/s", "--units", "m/s^2", "--json")
    assert code == 0
    fits = json.loads(out)["fits"]
    assert list(fits) == ["gx", "gy", "ax", "ay"]
    assert fits["gx"]["model"] == "WN+RW" and fits["ax"]["model"] == "WN"
    assert fits["gx"]["freq"] == 100.0  # from the time column
    # ARW 0.15 deg/sqrt(h) within 5 % (about 0.8 % Monte Carlo SD at 2^14 samples)
    assert fits["gx"]["datasheet"]["ARW"]["value"] == pytest.approx(0.15, rel=0.05)
    assert fits["gx"]["datasheet"]["ARW"]["unit"] == "deg/sqrt(h)"
    assert fits["ax"]["datasheet"]["VRW"]["value"] == pytest.approx(0.05, rel=0.05)
    assert fits["ax"]["units"] == "m/s^2"
    # the same column fitted alone gives the same JSON
    code, out1, _ = run(capsys, "fit", imu["path"], "WN+RW", "--column", "gy", "--json")
    assert json.loads(out1)["params"] == fits["gy"]["params"]


def test_fit_columns_text_has_one_table_per_column(capsys, imu):
    code, out, _ = run(capsys, "fit", imu["path"], "WN", "--columns", "ax,ay", "--units", "m/s^2")
    assert code == 0
    assert out.count("fit of WN to ") == 2 and "ax of" in out and "ay of" in out
    assert out.count("datasheet coefficients") == 2 and "m/s/sqrt(h)" in out


@pytest.mark.parametrize(("argv", "needle"), [
    (["--column", "gx", "--freq", "50"], "contradicts the sampling frequency 100 Hz"),
    (["--columns", "gx,gz"], "column 'gz' not found"),
    (["--columns", "gx", "--column", "gy"], "not both"),
    (["--columns", "gx", "--units", "gq=deg/s"], "not among the columns"),
])
def test_fit_columns_errors(capsys, imu, argv, needle):
    code, _, err = run(capsys, "fit", imu["path"], "WN", *argv)
    assert code in (1, 2) and err.count("\n") == 1 and needle in err


def test_model_pairs_must_cover_columns(capsys, imu):
    code, _, err = run(capsys, "fit", imu["path"], "gx=WN+RW", "--columns", "gx,gy")
    assert code == 1 and "no model for column(s) gy" in err


def test_wv_and_av_columns_one_table_and_multichannel_fit(capsys, imu, tmp_path):
    table = tmp_path / "wv.csv"
    code, out, _ = run(capsys, "wv", imu["path"], "--columns", "gx,ax", "-o", table)
    assert code == 0 and "variance per channel" in out and "gx" in out.splitlines()[2]
    header = table.read_text().splitlines()[0].split(",")
    assert header[:4] == ["level", "scale", "scale_s", "n"] and "variance[ax]" in header
    code, out, _ = run(capsys, "fit", table, "WN+RW", "--columns", "all", "--json")
    fits = json.loads(out)["fits"]
    code2, out2, _ = run(capsys, "fit", imu["path"], "WN+RW", "--columns", "gx,ax", "--json")
    assert code == code2 == 0
    for c in ("gx", "ax"):
        assert fits[c]["freq"] == 100.0
        for name, v in json.loads(out2)["fits"][c]["params"].items():
            assert fits[c]["params"][name] == pytest.approx(v, rel=1e-6)
    code, out, _ = run(capsys, "av", imu["path"], "--columns", "gx,gy", "--units", "deg/s", "--json")
    obj = json.loads(out)
    assert code == 0 and set(obj["av"]) == {"gx", "gy"} and set(obj["readings"]) == {"gx", "gy"}
    assert obj["readings"]["gx"]["N"]["value"] == pytest.approx(0.15, rel=0.05)


def test_hdf5_attribute_gives_the_frequency(capsys, tmp_path, signal_files):
    p = tmp_path / "imu.h5"
    with h5py.File(p, "w") as fh:
        fh.create_dataset("gyro", data=signal_files["x"]).attrs["rate"] = 25.0
    code, out, _ = run(capsys, "wv", p, "--json")
    assert code == 0 and json.loads(out)["freq"] == 25.0


# ---- datasheet readings from av -------------------------------------------------


def test_av_readings_text_json_and_adev_plot(capsys, imu, tmp_path):
    png = tmp_path / "adev.png"
    code, out, _ = run(capsys, "av", imu["path"], "--column", "gx", "--units", "deg/s", "--adev",
                       "--plot", png)
    assert code == 0 and "IEEE 952" in out and "N (ARW)" in out and "B (bias instability)" in out
    assert png.read_bytes()[:8] == PNG
    code, out, _ = run(capsys, "av", imu["path"], "--column", "gx", "--units", "deg/s", "--json")
    r = json.loads(out)["readings"]
    assert r["N"]["unit"] == "deg/sqrt(h)" and r["N"]["ci95"][0] < r["N"]["value"] < r["N"]["ci95"][1]
    assert r["B"]["unit"] == "deg/h" and r["B"]["value"] > 0


@pytest.mark.slow
def test_report_writes_markdown_html_yaml(capsys, imu, tmp_path):
    outdir = tmp_path / "rep"
    code, _, err = run(capsys, "report", imu["path"], "--columns", "all", "--units", "gx,gy=deg/s",
                         "--units", "ax,ay=m/s^2", "-o", outdir)
    assert code == 0, err
    md = (outdir / "report.md").read_text()
    for c in ("gx", "gy", "ax", "ay"):
        assert f"## {c}" in md and (outdir / f"{c}_wv.png").read_bytes()[:8] == PNG
    assert "deg/sqrt(h)" in md and "m/s/sqrt(h)" in md and "```yaml" in md
    assert md.count("B (bias instability)") == 4
    values = yaml.safe_load((outdir / "imu.yaml").read_text())
    # gyro noise density 0.15 deg/sqrt(h) = 0.15/60 deg/s/sqrt(Hz), in rad/s/sqrt(Hz)
    assert values["gyroscope_noise_density"] == pytest.approx(0.15 / 60 * np.pi / 180, rel=0.06)
    assert values["accelerometer_noise_density"] == pytest.approx(0.05 / 60, rel=0.06)
    assert set(values) >= {"gyroscope_random_walk", "accelerometer_random_walk", "update_rate"}
    assert values["update_rate"] == 100.0
    html = (outdir / "report.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and 'src="gx_wv.png"' in html


@pytest.mark.slow
def test_report_export_targets_and_inflation(capsys, imu, tmp_path):
    # --export writes the configuration files asked for, --inflate multiplies the densities
    common = ["report", imu["path"], "--columns", "gx,ax", "--units", "gx=deg/s",
              "--units", "ax=m/s^2", "--json"]
    code, out, err = run(capsys, *common, "-o", tmp_path / "plain")
    assert code == 0, err
    code, out, err = run(capsys, *common, "--export", "kalibr,openvins,json", "--inflate",
                         "noise=2,walk=10", "-o", tmp_path / "infl")
    assert code == 0, err
    files = {p.split("/")[-1] for p in json.loads(out)["files"]}
    assert {"imu.yaml", "kalibr_imu_chain.yaml", "imu_noise.json"} <= files
    assert {p.name for p in (tmp_path / "plain").iterdir()} >= {"imu.yaml"}
    assert not (tmp_path / "plain" / "imu_noise.json").exists()   # default: Kalibr only
    plain = yaml.safe_load((tmp_path / "plain" / "imu.yaml").read_text())
    infl = yaml.safe_load((tmp_path / "infl" / "imu.yaml").read_text())
    for sensor in ("gyroscope", "accelerometer"):
        assert infl[f"{sensor}_noise_density"] == pytest.approx(
            2 * plain[f"{sensor}_noise_density"], rel=1e-3)
        assert infl[f"{sensor}_random_walk"] == pytest.approx(
            10 * plain[f"{sensor}_random_walk"], rel=1e-3)
    noise = json.loads((tmp_path / "infl" / "imu_noise.json").read_text())
    assert json.dumps(noise, allow_nan=False)  # strict JSON, read back
    chain = (tmp_path / "infl" / "kalibr_imu_chain.yaml").read_text()
    assert "gyroscope_noise_density" in chain
    # a bad target or factor: one line, exit 1, before any fit and any file
    for opt, bad, msg in (("--export", "rovio", "unknown export target"),
                          ("--inflate", "noise=0.5", "inflation")):
        code, _, err = run(capsys, *common, opt, bad, "-o", tmp_path / "bad")
        assert code == 1 and err.count("\n") == 1 and msg in err, err
        assert not (tmp_path / "bad").exists()


# ---- tables that round-trip ---------------------------------------------------


def test_wv_table_refits_with_its_recorded_frequency(capsys, tmp_path):
    model = Model("WN+GM", freq=200.0)
    theta = model.theta({"WN[1].sigma2": 1.0, "GM[1].beta": 2.0, "GM[1].sigma2": 0.5})
    np.save(tmp_path / "g.npy", model.simulate(theta, 2**14, np.random.default_rng(8)))
    table = tmp_path / "wv.csv"
    assert run(capsys, "wv", tmp_path / "g.npy", "--freq", 200, "-o", table)[0] == 0
    code, out, _ = run(capsys, "fit", table, "WN+GM", "--json")  # no --freq needed
    code2, out2, _ = run(capsys, "fit", tmp_path / "g.npy", "WN+GM", "--freq", 200, "--json")
    assert code == code2 == 0
    a, b = json.loads(out), json.loads(out2)
    assert a["freq"] == 200.0
    assert a["params"]["GM[1].beta"] == pytest.approx(b["params"]["GM[1].beta"], rel=1e-6)
    code, _, err = run(capsys, "fit", table, "WN+GM", "--freq", 1)
    assert code == 1 and "contradicts the 200 Hz" in err


def test_av_table_is_readable_by_fit(capsys, signal_files, tmp_path):
    table = tmp_path / "av.csv"
    assert run(capsys, "av", signal_files["npy"], "--freq", 10, "-o", table)[0] == 0
    code, out, _ = run(capsys, "fit", table, "WN+AR1", "--json")
    code2, out2, _ = run(capsys, "fit", signal_files["npy"], "WN+AR1", "--freq", 10, "--json")
    assert code == code2 == 0
    for name, v in json.loads(out2)["params"].items():
        assert json.loads(out)["params"][name] == pytest.approx(v, rel=1e-6)
    # the old mistake: the table's column read as a 13-sample signal
    code, _, err = run(capsys, "wv", table, "--column", "allan_var")
    assert code == 1 and "looks like a WV/AV table" in err


# ---- edge cases found by a new user ----------------------------------------------


@pytest.fixture(scope="module")
def edge_files(tmp_path_factory) -> dict:
    d = tmp_path_factory.mktemp("edge")
    np.save(d / "empty.npy", np.array([]))
    (d / "junk.npy").write_bytes(b"\x00\x01garbage" * 20)
    (d / "outdir.csv").mkdir()
    (d / "outdir.png").mkdir()
    np.save(d / "x.npy", np.random.default_rng(0).standard_normal(512))
    return {"dir": d}


EDGE_CASES = {
    "empty npy": (["wv", "{dir}/empty.npy"], 1, "empty signal"),
    "junk npy": (["wv", "{dir}/junk.npy"], 1, "not a NumPy .npy file"),
    "levels 2000": (["model-wv", "WN", "-p", "WN[1].sigma2=1", "--levels", "2000"], 1,
                    "--levels 2000 is too large"),
    "negative count": (["fit", "{dir}/x.npy", "-1*WN"], 1, "must be a positive integer"),
    "negative reweight": (["fit", "{dir}/x.npy", "WN", "--reweight", "-1"], 2,
                          "must be a non-negative integer"),
    "output is a directory": (["wv", "{dir}/x.npy", "-o", "{dir}/outdir.csv"], 1, "is a directory"),
    "plot is a directory": (["wv", "{dir}/x.npy", "--plot", "{dir}/outdir.png"], 1, "is a directory"),
    "missing table with --n-samples": (["fit", "{dir}/missing.csv", "WN", "--n-samples", "10"], 1,
                                       "file not found"),
}


@pytest.mark.parametrize("case", list(EDGE_CASES))
def test_edge_cases_one_clear_line(capsys, edge_files, case):
    argv, status, needle = EDGE_CASES[case]
    code, out, err = run(capsys, *(a.format(dir=edge_files["dir"]) for a in argv))
    assert code == status, err
    assert err.count("\n") == 1 and err.startswith("gmwm: error: ") and needle in err, err
    assert "internal error" not in err and "pickle" not in err and ".tmp" not in err
    assert out == ""


def test_model_wv_at_the_level_cap_is_finite(capsys):
    code, out, err = run(capsys, "model-wv", "WN+RW+DR+AR1", "-p", "WN[1].sigma2=1", "-p",
                         "RW[1].gamma2=1e-6", "-p", "DR[1].omega=1e-6", "-p", "AR1[1].phi=0.9",
                         "-p", "AR1[1].sigma2=0.1", "--levels", 60, "--json")
    assert code == 0 and err == ""
    assert all(v is not None and v > 0 for v in json.loads(out)["total"])


def test_quiet_and_non_terminal_have_no_progress_lines(capsys, signal_files):
    code, _, err = run(capsys, "wv", signal_files["npy"])  # stderr captured: not a terminal
    assert code == 0 and err == ""


def test_wv_json_separates_first_call_and_steady_state(capsys, signal_files):
    code, out, _ = run(capsys, "wv", signal_files["npy"], "--json", "--quiet")
    obj = json.loads(out)
    assert code == 0 and obj["seconds"] >= 0 and obj["seconds_first_call"] >= 0
    assert obj["seconds_read"] >= 0 and obj["seconds_import_scipy"] >= 0
    assert obj["wv_kernel"] == ("c" if c_toolchain() else "numba")


@needs_c_kernel
def test_wv_command_never_loads_numba(tmp_path):
    # the C kernel is what makes `gmwm wv` fast: Numba's runtime alone costs ~0.6 s per process
    x = np.random.default_rng(3).standard_normal(5000)
    np.save(tmp_path / "x.npy", x)
    code = ("import sys\n"
            "from gmwm.cli import main\n"
            "rc = main(['wv', sys.argv[1], '--json', '--quiet'])\n"
            "print(rc, sorted(m for m in sys.modules if m.split('.')[0] == 'numba')[:3])\n")
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path / "x.npy")],
                         capture_output=True, text=True, check=True)
    last = res.stdout.strip().splitlines()[-1]
    assert last == "0 []", last


# ---- fast start and progress ---------------------------------------------------


def test_help_and_usage_errors_load_no_numerics():
    # the package and its parser import the standard library only and main imports the one
    # command it runs, so `gmwm --help` and a usage error start fast
    code = ("import sys\n"
            "from gmwm.cli import main\n"
            "codes = [main(a) for a in (['--help'], ['fit', '--help'], ['fit'],\n"
            "                           ['wv', 'x.npy', '--levels', '0'])]\n"
            "heavy = ('numpy', 'scipy', 'numba', 'matplotlib', 'pandas', 'h5py')\n"
            "print(codes, sorted(m for m in heavy if m in sys.modules))\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip().splitlines()[-1] == "[0, 0, 2, 2] []"


class _Tty:
    def __init__(self) -> None:
        self.text = ""

    def isatty(self) -> bool:
        return True

    def write(self, s: str) -> None:
        self.text += s

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        pass


def test_progress_lines_only_on_a_terminal_and_not_quiet(signal_files, monkeypatch, capsys):
    from gmwm.cli import Progress

    tty = _Tty()
    Progress(tty, quiet=False)("fitting WN to gx")
    assert tty.text.startswith("gmwm: [") and tty.text.endswith("s] fitting WN to gx\n")
    quiet = _Tty()
    Progress(quiet, quiet=True)("x")
    assert quiet.text == ""
    tty = _Tty()
    monkeypatch.setattr("sys.stderr", tty)
    assert main(["fit", str(signal_files["npy"]), "WN+AR1", "--json"]) == 0
    assert "reading" in tty.text and "fitting WN+AR1" in tty.text
    capsys.readouterr()


# ---- the automatic model choice ('auto') ----------------------------------------------------------


@pytest.mark.slow
def test_fit_auto_prints_the_ranking_and_keeps_wn_and_rw(capsys, signal_files):
    code, out, err = run(capsys, "fit", signal_files["npy"], "auto", "--freq", "100",
                         "--units", "deg/s", "-q")
    assert code == 0, err
    head = out.splitlines()[0]
    assert head.startswith("model ") and "chosen for the gyroscope" in head
    chosen = head.split()[1]
    assert "WN" in chosen and "RW" in chosen  # the terms a filter needs, in every candidate
    assert "GOF p" in out and "rank" in out
    code, out, _ = run(capsys, "fit", signal_files["npy"], "auto", "--freq", "100",
                       "--units", "deg/s", "--json", "-q")
    obj = json.loads(out)
    assert obj["model"] == chosen and obj["model_choice"]["model"] == chosen
    assert [c["rank"] for c in obj["model_choice"]["candidates"]][:2] == [1, 2]


def test_auto_refuses_the_slope_method(capsys, signal_files):
    code, _, err = run(capsys, "fit", signal_files["npy"], "auto", "--freq", "100",
                       "--method", "avsm")
    assert code == 1 and err.count("\n") == 1 and "automatic model choice" in err


def test_weight_choices_are_the_librarys():
    from gmwm.cli.parser import _WEIGHTS
    from gmwm.settings import WEIGHT_KINDS

    assert set(_WEIGHTS) == set(WEIGHT_KINDS)
