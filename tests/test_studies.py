"""Tests of the study machinery: seeded streams, WV/estimate stores, chunking, summaries, archive."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from gmwm.errors import InputError, ModelError
from gmwm_studies import archive, store
from gmwm_studies import montecarlo as gs
from gmwm_studies.seeds import replicate_rng, replicate_seed, stable_int

SIM3 = "AR1+RW+WN+SIN"
SIM3_TRUTH = {"WN[1].sigma2": 8e-4, "AR1[1].phi": 0.9997083, "AR1[1].sigma2": 9e-6,
              "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056, "RW[1].gamma2": 1.2288e-7}


# --- seeds ---------------------------------------------------------------------------------------

def test_stable_int_is_fixed_across_processes():
    # crc32 of a fixed string: a constant, unlike the salted built-in hash()
    assert stable_int("sim2") == 0x74c64ab
    assert stable_int("sim2") != stable_int("sim3")


def test_replicate_streams_are_keyed_by_study_size_and_replicate():
    a = replicate_rng("sim2", 1000, 5, 1).normal(size=4)
    np.testing.assert_array_equal(a, replicate_rng("sim2", 1000, 5, 1).normal(size=4))
    for other in (replicate_rng("sim3", 1000, 5, 1), replicate_rng("sim2", 2000, 5, 1),
                  replicate_rng("sim2", 1000, 6, 1), replicate_rng("sim2", 1000, 5, 2)):
        assert not np.allclose(a, other.normal(size=4))
    assert replicate_seed("sim2", 1000, 5, 1) != replicate_seed("sim2", 1000, 6, 1)


def test_seed_rejects_negative_replicate():
    with pytest.raises(InputError, match="replicate"):
        replicate_rng("sim2", 1000, -1, 0)


# --- chunking ------------------------------------------------------------------------------------

def test_chunk_bounds_cover_every_replicate_once():
    bounds = gs.chunk_bounds(23, 5)
    assert bounds[0] == (0, 5) and bounds[-1] == (20, 23)
    reps = [r for c in range(len(bounds)) for r in gs.chunk_replicates(c, 23, 5)]
    assert reps == list(range(23))
    with pytest.raises(InputError, match="chunk 5 out of range"):
        gs.chunk_replicates(5, 23, 5)


def test_simulated_wv_does_not_depend_on_chunking():
    kw = {"model_spec": SIM3, "truth": SIM3_TRUTH, "n_samples": 4096, "study": "sim3",
          "base_seed": 7}
    whole = gs.simulate_wv_chunk(replicates=range(6), **kw)
    parts = [gs.simulate_wv_chunk(replicates=r, **kw) for r in ([0, 1, 2, 3], [4, 5])]
    np.testing.assert_array_equal(whole.variances, np.vstack([p.variances for p in parts]))
    # one replicate alone, out of order, gives the same row
    alone = gs.simulate_wv_chunk(replicates=[4], **kw)
    np.testing.assert_array_equal(alone.variances[0], whole.variances[4])
    assert whole.variances.shape == (6, 11)  # default J = floor(log2 4096) - 1


def test_simulator_choice_fast_reference_or_error():
    """``simulator`` picks Model.simulate_fast (default) or Model.simulate on the same stream."""
    from gmwm.model import Model

    kw = {"model_spec": SIM3, "truth": SIM3_TRUTH, "n_samples": 4096, "study": "sim3",
          "base_seed": 7, "replicates": [2]}
    model = Model(SIM3)
    theta = model.theta(SIM3_TRUTH)
    from gmwm.wv import wvar

    for name, draw in (("fast", model.simulate_fast), ("reference", model.simulate)):
        got = gs.simulate_wv_chunk(simulator=name, **kw).variances[0]
        want = wvar(draw(theta, 4096, replicate_rng("sim3", 4096, 2, 7))).variance
        np.testing.assert_array_equal(got, want)
    assert not np.array_equal(gs.simulate_wv_chunk(**kw).variances,
                              gs.simulate_wv_chunk(simulator="reference", **kw).variances)
    with pytest.raises(InputError, match="unknown simulator 'exact'"):
        gs.simulate_wv_chunk(simulator="exact", **kw)


def test_fits_do_not_depend_on_chunking():
    kw = {"model_spec": "WN+RW", "truth": {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-3},
          "n_samples": 2048, "study": "t", "base_seed": 3}
    settings = {"n_starts": 2}
    whole = gs.fit_chunk(gs.simulate_wv_chunk(replicates=range(4), **kw), settings)
    parts = gs.gather(gs.fit_chunk(gs.simulate_wv_chunk(replicates=r, **kw), settings)
                      for r in ([2, 3], [0, 1]))
    np.testing.assert_array_equal(parts["estimate"].values, whole["estimate"].values)
    assert whole.attrs["n_samples"] == 2048 and list(whole["parameter"].values) == [
        "WN[1].sigma2", "RW[1].gamma2"]
    assert np.all(np.isfinite(whole["estimate"].values))


def test_truth_must_be_canonical_and_complete():
    bad = {**{k: v for k, v in SIM3_TRUTH.items()}, "AR1[2].phi": 0.5}
    with pytest.raises(ModelError, match="unknown parameter"):
        gs.check_truth(SIM3, bad)
    two = {"AR1[1].phi": 0.9, "AR1[1].sigma2": 1.0, "AR1[2].phi": 0.1, "AR1[2].sigma2": 1.0}
    with pytest.raises(ModelError, match="canonical"):
        gs.check_truth("2*AR1", two)


# --- stores --------------------------------------------------------------------------------------

def _chunk(reps=(3, 4, 5)) -> store.WVChunk:
    r = len(reps)
    return store.WVChunk(
        study="s", model="WN", truth={"WN[1].sigma2": 2.0}, n_samples=64, base_seed=1,
        replicates=np.array(reps), levels=np.arange(1, 5), scales=2.0 ** np.arange(1, 5),
        n=64 - 2 ** np.arange(1, 5) + 1, variances=np.arange(r * 4, dtype=float).reshape(r, 4) + 1,
        seconds_simulate=np.full(r, 0.5), seconds_wv=np.full(r, 0.25),
    )


def test_wv_chunk_round_trip(tmp_path):
    c = _chunk()
    store.write_wv_chunk(tmp_path / "c.h5", c)
    back = store.read_wv_chunk(tmp_path / "c.h5")
    np.testing.assert_array_equal(back.variances, c.variances)
    np.testing.assert_array_equal(back.replicates, c.replicates)
    np.testing.assert_array_equal(back.seconds_wv, c.seconds_wv)
    assert (back.study, back.model, back.truth, back.n_samples) == ("s", "WN", c.truth, 64)
    both = store.read_wv_chunks([tmp_path / "c.h5", _write(tmp_path / "d.h5", _chunk((0, 1)))])
    assert list(both.replicates) == [0, 1, 3, 4, 5]


def _write(path, chunk):
    store.write_wv_chunk(path, chunk)
    return path


def test_interrupted_write_leaves_no_target(tmp_path, monkeypatch):
    target = tmp_path / "c.h5"

    def crash(*args, **kwargs):
        raise KeyboardInterrupt("killed mid-write")

    monkeypatch.setattr(store.h5py.File, "create_dataset", crash)
    with pytest.raises(KeyboardInterrupt):
        store.write_wv_chunk(target, _chunk())
    assert list(tmp_path.iterdir()) == []  # neither the target nor a temporary file remains


def test_interrupted_dataset_write_keeps_previous_file(tmp_path, monkeypatch):
    target = tmp_path / "e.nc"
    ds = _estimates(np.zeros((4, 1)), truth=[1.0])
    store.write_dataset(ds, target)
    before = target.read_bytes()

    def crash(self, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", crash)
    with pytest.raises(OSError):
        store.write_dataset(ds.assign(estimate=ds["estimate"] + 1), target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["e.nc"]


def test_dataset_round_trip(tmp_path):
    ds = _estimates(np.arange(6.0).reshape(3, 2), truth=[1.0, 2.0])
    store.write_dataset(ds, tmp_path / "e.nc")
    back = store.read_dataset(tmp_path / "e.nc")
    xr.testing.assert_identical(back, ds)


# --- summaries -----------------------------------------------------------------------------------

def _estimates(est: np.ndarray, truth, converged=None, reps=None) -> xr.Dataset:
    r, p = est.shape
    converged = np.ones(r, bool) if converged is None else np.asarray(converged)
    reps = np.arange(r) if reps is None else np.asarray(reps)
    return xr.Dataset(
        {"estimate": (("replicate", "parameter"), est),
         "converged": ("replicate", converged),
         "message": ("replicate", np.array([""] * r, dtype=object))},
        coords={"replicate": reps, "parameter": [f"P[{i + 1}].x" for i in range(p)],
                "truth": ("parameter", np.asarray(truth, float))},
        attrs={"study": "t", "model": "m", "n_samples": 100, "estimator": "gmwm"},
    )


def test_summary_recovers_known_bias_and_sd():
    # 4000 draws: estimate = truth + 0.5 + N(0, 2^2). MC SE of the mean is 2/sqrt(4000) = 0.032
    # and of the SD about 2/sqrt(2*4000) = 0.022; tolerances are ~5 MC SEs.
    rng = np.random.default_rng(3)
    x = 10.0 + 0.5 + 2.0 * rng.standard_normal((4000, 1))
    conv = np.ones(4000, bool)
    conv[:400] = False
    x[:400] = 1e6  # non-converged fits must not leak into the statistics
    df = gs.summarize(_estimates(x, truth=[10.0], converged=conv))
    row = df.iloc[0]
    assert row.bias == pytest.approx(0.5, abs=0.16)
    assert row.sd == pytest.approx(2.0, abs=0.11)
    assert row.rmse == pytest.approx(np.hypot(0.5, 2.0), abs=0.12)
    assert row.std_bias == pytest.approx(0.25, abs=0.08)
    assert row.share_not_converged == pytest.approx(0.1)
    assert row.n_used == 3600
    z = gs.standardized_errors(_estimates(x, truth=[10.0], converged=conv))["P[1].x"]
    assert len(z) == 3600 and np.std(z, ddof=1) == pytest.approx(1.0)


def test_gather_sorts_and_rejects_duplicates():
    a = _estimates(np.ones((2, 1)), [1.0], reps=[2, 3])
    b = _estimates(np.zeros((2, 1)), [1.0], reps=[0, 1])
    g = gs.gather([a, b])
    assert list(g["replicate"].values) == [0, 1, 2, 3]
    with pytest.raises(InputError, match="duplicate"):
        gs.gather([a, a])


def test_tables_written(tmp_path):
    df = pd.DataFrame({"parameter": ["a"], "bias": [0.123456789]})
    gs.write_table(df, tmp_path / "t.csv", tmp_path / "t.md", title="T")
    assert "0.1235" in (tmp_path / "t.md").read_text()
    assert pd.read_csv(tmp_path / "t.csv").bias[0] == pytest.approx(0.123456789)


def test_archive_never_overwrites(tmp_path):
    (tmp_path / "r").mkdir()
    f = tmp_path / "r" / "x.md"
    f.write_text("hello")
    bench = pd.DataFrame({"rule": ["fit"], "study": ["s"], "job": ["j"], "seconds": [1.0]})
    cfg = {"seed": 1}
    a = archive.make_archive(tmp_path / "arch", cfg, [f], bench, base=tmp_path)
    b = archive.make_archive(tmp_path / "arch", cfg, [f], bench, base=tmp_path)
    assert a != b and a.name.endswith(archive.config_hash(cfg))
    for d in (a, b):
        assert (d / "r" / "x.md").read_text() == "hello"
        assert json.loads((d / "config.json").read_text()) == cfg
        assert (d / "timings.csv").exists() and (d / "versions.json").exists()
    assert not [p for p in (tmp_path / "arch").iterdir() if p.name.startswith(".")]


def test_git_commit_is_dirty_only_for_changes_outside_the_runs_outputs(tmp_path):
    import subprocess

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    assert archive.git_commit(tmp_path) == "unknown"  # not a repository
    git("init", "-q")
    (tmp_path / "reports").mkdir()
    report, code = tmp_path / "reports" / "t.md", tmp_path / "code.py"
    report.write_text("old")
    code.write_text("x = 1")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=tmp_path, check=True,
                         capture_output=True, text=True).stdout.strip()
    assert archive.git_commit(tmp_path, outputs=[report]) == sha
    report.write_text("rewritten by the run")
    assert archive.git_commit(tmp_path, outputs=[report]) == sha
    assert archive.git_commit(tmp_path) == sha + "-dirty"  # not declared as an output
    code.write_text("x = 2")
    assert archive.git_commit(tmp_path, outputs=[report]) == sha + "-dirty"
    code.write_text("x = 1")
    # an output the run writes but does not archive (make_archive's ``produced``)
    design = tmp_path / "reports" / "d.md"
    design.write_text("v1")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "d")
    sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=tmp_path, check=True,
                         capture_output=True, text=True).stdout.strip()
    design.write_text("v2")
    report.write_text("again")
    arch = archive.make_archive(tmp_path / "arch", {"a": 1}, [report], pd.DataFrame(),
                                repo=tmp_path, base=tmp_path, produced=[design])
    assert (arch / "git.txt").read_text().strip() == sha
    assert not (arch / "reports" / "d.md").exists()


def test_archived_summary_takes_each_study_from_its_newest_archive(tmp_path):
    root = tmp_path / "archive"
    runs = {"20260101T000000Z-aaa": [("fit", "s1", 10.0), ("fit", "s2", 20.0)],
            "20260102T000000Z-bbb": [("fit", "s1", 1.0), ("table", "s1", 2.0)],
            "20260103T000000Z-ccc": [("fit", "other", 5.0)]}
    for name, rows in runs.items():
        (root / name).mkdir(parents=True)
        pd.DataFrame([{"rule": r, "study": st, "job": "j", "seconds": sec} for r, st, sec in rows]
                     ).to_csv(root / name / "timings.csv", index=False)
    (root / ".20260104T000000Z-ddd.tmp-1").mkdir()  # an unfinished archive has no timings
    summary, sources = archive.archived_summary(root, ["s1", "s2", "missing"])
    assert sources == {"s1": "20260102T000000Z-bbb", "s2": "20260101T000000Z-aaa"}
    totals = summary.groupby("study")["seconds"].sum()
    assert totals["s1"] == 3.0 and totals["s2"] == 20.0 and "missing" not in totals
    page = archive.render_index(
        [{"name": "s1", "model": "WN", "n_samples": [10], "replicates": 2, "table": "t.md"}],
        summary, "cfg", sources)
    assert "archived as `archive/20260102T000000Z-bbb`): 3.0 s" in page
    real = archive.render_index([{"name": "nav", "model": "WN", "table": "nav/e.md",
                                  "figures": ["nav/f.png"]}], summary, "cfg")
    assert "Full table: [nav/e.md](nav/e.md)." in real and "Sample sizes" not in real
    # a section whose jobs sit under other directory names (SVO: case1, case2)
    (root / "20260105T000000Z-eee").mkdir()
    pd.DataFrame({"rule": ["svo_train"] * 2, "study": ["case1", "case2"], "job": ["a", "b"],
                  "seconds": [4.0, 6.0]}).to_csv(root / "20260105T000000Z-eee" / "timings.csv",
                                                 index=False)
    svo, where = archive.archived_summary(root, ["svo"], {"case1": "svo", "case2": "svo"})
    assert where == {"svo": "20260105T000000Z-eee"} and svo["seconds"].sum() == 10.0
    empty, none = archive.archived_summary(tmp_path / "nowhere", ["s1"])
    assert empty.empty and none == {}


def _sim2_like(est: np.ndarray) -> xr.Dataset:
    names = ["AR1[1].phi", "AR1[1].sigma2", "SIN[1].alpha", "SIN[1].beta", "SIN[2].alpha",
             "SIN[2].beta"]
    truth = [0.5, 1e-3, 0.025, 0.056, 0.0015, 8e-6]
    ds = _estimates(est, truth=truth)
    ds = ds.assign_coords(parameter=names)
    ds.attrs["model"] = "AR1+2*SIN"
    return ds


def test_replicate_flags_boundary_and_label_switching():
    truth = np.array([0.5, 1e-3, 0.025, 0.056, 0.0015, 8e-6])
    est = np.tile(truth * 1.05, (5, 1))
    est[1, 1] = 0.0                      # AR1 variance vanished
    est[2, 0] = 1.0 - 1e-12              # phi at the domain edge
    # slow SIN absorbed; a spurious fast SIN takes label 1 (decreasing beta) and the true fast
    # SIN moves to label 2
    est[3, 2:] = [0.004, 2.0, 0.025, 0.056]
    est[4, 2:] = [0.0015, 8e-6, 0.025, 0.056]  # plain swap of the two SIN
    ds = _sim2_like(est)
    ds["converged"].values[4] = False         # non-converged replicates are never flagged
    f = gs.replicate_flags(ds)
    b = f["boundary"].values
    assert b.sum() == 2 and b[1, 1] and b[2, 0]
    s = f["switched"].values
    np.testing.assert_array_equal(s.any(axis=1), [False, False, False, True, False])
    assert not s[3, :2].any() and s[3, 2:].all()  # only the SIN columns are marked
    df = gs.summarize(ds)
    assert df.set_index("parameter").loc["SIN[2].beta", "n_switched"] == 1
    assert df.set_index("parameter").loc["AR1[1].sigma2", "n_boundary"] == 1
    ds["converged"].values[4] = True
    assert gs.replicate_flags(ds)["switched"].values[4, 2:].all()
