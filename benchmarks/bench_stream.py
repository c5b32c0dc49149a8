"""Large recordings through the CLI: peak memory, wall time and exactness of the streamed WV.

Usage: python benchmarks/bench_stream.py [--dir DIR] [--channels 6] [--hdf5-samples 5e7]
       [--npy-samples 3e8] [--no-in-memory] [--readme]
       python benchmarks/bench_stream.py --check [--check-samples 2e8] [--before SRC] [--dir DIR]
       [--readme]

1. Writes a six-channel HDF5 recording (/imu/gx ... /imu/az, float64, 1 kHz attribute, 5e7
   samples per channel: WN + RW on offsets up to 1e3) and runs `gmwm report rec.h5 WN+RW
   --columns all` on it; the WV of /imu/gx from the report is compared with `gmwm.wvar` of that
   channel read whole.
2. Writes a one-channel .npy of 3e8 samples (WN + RW on a 1e8 offset) and runs `gmwm wv` on it
   (streamed), then the same with streaming disabled (GMWM_STREAM_MIN_BYTES huge: the whole file in
   memory, the previous behaviour) when the machine has the memory, and compares the two WVs.
3. Projects wall time and memory to 6 channels x 2.6e8 samples (72 h at 1 kHz).

``--check [--check-samples 2e8]`` instead measures the streamed stationarity check against the
streamed WV on a one-channel .npy (WN + RW on a 1e8 offset, 2e8 samples = 1.6 GB, with a knock
and a noise burst, so flagged blocks are re-read): peak RSS (GNU time around a child process)
and time of `gmwm.stream.wvar_stream`, `gmwm.stationarity.check_stationarity_stream` (no rate:
windows from 8 samples, the most statistics; and at 100 Hz), `gmwm wv big.npy` (WV and check in
one read) and `gmwm report big.npy --freq 100`; ``--before SRC`` also runs the check and
`gmwm wv` of another checkout (e.g. /work/main/src); --readme writes the section
bench_stream_check.

Peak RSS is each CLI process's own (wait4 rusage). The files go to a temporary directory under
--dir (default: the system's) and are deleted; the free disk is checked first and a part that
does not fit is skipped with a message. --readme writes the results into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from readme_section import load, machine, run_measured, update_section

REPO = Path(__file__).resolve().parents[1]
CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")
OFFSETS = (1e-3, -2e-3, 5e-4, 0.1, -0.2, 9.81)
GB = 1e9


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO / "src"), env.get("PYTHONPATH")]))
    env.update(extra)
    return env


def _gmwm(*args: str, env: dict[str, str] | None = None, cwd: Path | None = None) -> dict:
    r = run_measured([sys.executable, "-m", "gmwm", *args], env=env or _env(),
                     cwd=None if cwd is None else str(cwd))
    if r["code"] not in (0, 3):
        raise SystemExit(f"gmwm {' '.join(args)} failed:\n{str(r['err'])[-3000:]}")
    return r


def _signal_chunks(n: int, seed: int, offset: float, chunk: int = 1 << 22):
    """WN(1) + RW(gamma2 = 1e-6) on ``offset``, in chunks (the random walk carried across)."""
    rng = np.random.default_rng(seed)
    level = 0.0
    for a in range(0, n, chunk):
        m = min(chunk, n - a)
        rw = level + np.cumsum(1e-3 * rng.standard_normal(m))
        level = float(rw[-1])
        yield a, offset + rw + rng.standard_normal(m)


def _free_gb(path: Path) -> float:
    return shutil.disk_usage(path).free / GB


def _mem_available_gb() -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024 / GB
    except OSError:
        pass
    return 0.0


def _rel(a: list[float], b: list[float]) -> float:
    a_, b_ = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a_ / b_ - 1.0)))


def hdf5_part(tmp: Path, n: int, n_ch: int) -> dict:
    import h5py

    from gmwm.wv import wvar

    path = tmp / "rec.h5"
    t0 = time.perf_counter()
    with h5py.File(path, "w") as f:
        g = f.create_group("imu")
        g.attrs["freq"] = 1000.0
        for c in range(n_ch):
            ds = g.create_dataset(CHANNELS[c], shape=(n,), dtype="f8", chunks=(1 << 16,))
            for a, x in _signal_chunks(n, 100 + c, OFFSETS[c]):
                ds[a:a + x.size] = x
    gen_s = time.perf_counter() - t0
    cols = ",".join(f"imu/{CHANNELS[c]}" for c in range(n_ch))
    r = _gmwm("report", str(path), "WN+RW", "--columns", cols, "-o", str(tmp / "report"),
              "--json", cwd=tmp)
    obj = json.loads(str(r["out"]))
    fits = obj["fits"]
    wv_s = max(f["seconds_wv"] for f in fits.values())
    with h5py.File(path, "r") as f:
        x = f[f"imu/{CHANNELS[0]}"][()]
    t1 = time.perf_counter()
    ref = wvar(x, freq=1000.0)
    mem_s = time.perf_counter() - t1
    del x
    diff = _rel(fits[f"imu/{CHANNELS[0]}"]["wv"]["variance"], ref.variance.tolist())
    size = path.stat().st_size
    path.unlink()
    shutil.rmtree(tmp / "report", ignore_errors=True)
    return {"n": n, "channels": n_ch, "size_gb": size / GB, "gen_s": gen_s, "run": r,
            "wv_s": wv_s, "diff": diff, "inmem_wvar_s": mem_s,
            "levels": len(ref.variance)}


def npy_part(tmp: Path, n: int, in_memory: bool) -> dict:
    path = tmp / "big.npy"
    t0 = time.perf_counter()
    out = np.lib.format.open_memmap(path, mode="w+", dtype=np.float64, shape=(n,))
    for a, x in _signal_chunks(n, 7, 1e8):
        out[a:a + x.size] = x
    out.flush()
    del out
    gen_s = time.perf_counter() - t0
    r = _gmwm("wv", str(path), "--freq", "1000", "--json", cwd=tmp)
    streamed = json.loads(str(r["out"]))
    res = {"n": n, "size_gb": path.stat().st_size / GB, "gen_s": gen_s, "run": r,
           "wv_s": streamed["seconds"], "streamed": streamed["streamed"], "inmem": None}
    need = 2.2 * res["size_gb"]
    if in_memory and _mem_available_gb() > need + 2:
        m = _gmwm("wv", str(path), "--freq", "1000", "--json",
                  env=_env(GMWM_STREAM_MIN_BYTES=str(1 << 60)), cwd=tmp)
        whole = json.loads(str(m["out"]))
        res["inmem"] = m
        res["inmem_wv_s"] = whole["seconds"]
        res["diff"] = _rel(streamed["variance"], whole["variance"])
        res["levels"] = len(whole["variance"])
    else:
        res["skip_inmem"] = (f"in-memory run skipped: {_mem_available_gb():.1f} GB available, "
                             f"~{need:.1f} GB needed")
    path.unlink()
    return res


def _child(what: str, path: str, freq: str) -> int:
    """One computation measured in this (child) process: prints its wall and CPU seconds as JSON
    (imports and opening the file excluded)."""
    from gmwm.stationarity import check_stationarity_stream
    from gmwm.stream import open_source, wvar_stream

    f = None if freq == "none" else float(freq)
    with open_source(path) as src:
        t0, c0 = time.perf_counter(), time.process_time()
        out: dict = {}
        if what == "wv":
            wvar_stream(src, freq=f)
        else:
            rep = check_stationarity_stream(src, freq=f)
            out = {"moving": rep.moving, "flags": len(rep.flags), "windows": len(rep.windows)}
        out.update(comp_s=time.perf_counter() - t0, comp_cpu=time.process_time() - c0)
    print(json.dumps(out))
    return 0


def check_part(tmp: Path, n: int, before: str | None = None) -> dict:
    """The streamed check against the streamed WV on a one-channel .npy of ``n`` samples; with
    ``before`` (another checkout's src directory) also its check and `gmwm wv`."""
    path = tmp / "big.npy"
    t0 = time.perf_counter()
    out = np.lib.format.open_memmap(path, mode="w+", dtype=np.float64, shape=(n,))
    rng = np.random.default_rng(11)
    for a, x in _signal_chunks(n, 7, 1e8):
        out[a:a + x.size] = x
    k = int(0.4 * n)
    out[k:k + 1000] += 50.0  # a knock
    k = int(0.7 * n)
    out[k:k + 20_000] += 30.0 * rng.standard_normal(20_000)  # a burst of vibration
    out.flush()
    del out
    gen_s = time.perf_counter() - t0
    me = [sys.executable, str(Path(__file__).resolve()), "--child"]
    res: dict = {"n": n, "size_gb": path.stat().st_size / GB, "gen_s": gen_s, "runs": []}
    for label, cmd in (
            ("`gmwm.stream.wvar_stream` (streamed WV)", [*me, "wv", str(path), "none"]),
            ("`check_stationarity_stream`, no rate (windows from 8 samples)",
             [*me, "check", str(path), "none"]),
            ("`check_stationarity_stream`, 100 Hz (windows from 10 samples)",
             [*me, "check", str(path), "100"])):
        r = run_measured(cmd, env=_env(), cwd=str(tmp))
        if r["code"] != 0:
            raise SystemExit(f"{label} failed:\n{str(r['err'])[-3000:]}")
        r.update(json.loads(str(r["out"]).strip().splitlines()[-1]))
        res["runs"].append((label, r))
    r = _gmwm("wv", str(path), "--json", cwd=tmp)
    r["comp_s"] = json.loads(str(r["out"]))["seconds"]
    res["runs"].append(("`gmwm wv big.npy` (WV and check in one read; WV seconds)", r))
    r = _gmwm("report", str(path), "--freq", "100", "-o", str(tmp / "report"), cwd=tmp)
    res["runs"].append(("`gmwm report big.npy --freq 100`", r))
    if before:
        env = dict(os.environ, PYTHONPATH=before)
        r = run_measured([*me, "check", str(path), "none"], env=env, cwd=str(tmp))
        if r["code"] == 0:
            r.update(json.loads(str(r["out"]).strip().splitlines()[-1]))
            res["runs"].append((f"before ({before}): `check_stationarity_stream`, no rate", r))
        r = _gmwm("wv", str(path), "--json", env=env, cwd=tmp)
        r["comp_s"] = json.loads(str(r["out"]))["seconds"]
        res["runs"].append((f"before ({before}): `gmwm wv big.npy` (WV seconds)", r))
    path.unlink()
    shutil.rmtree(tmp / "report", ignore_errors=True)
    return res


def check_main(args: argparse.Namespace) -> int:
    base = Path(args.dir or tempfile.gettempdir())
    tmp = Path(tempfile.mkdtemp(prefix="gmwm-bench-check-", dir=base))
    n = int(args.check_samples)
    load_before = load()
    try:
        need = n * 8 / GB * 2.1  # the file and the WV's panel file
        if _free_gb(tmp) < need:
            raise SystemExit(f"{_free_gb(tmp):.1f} GB free in {base}, {need:.1f} GB needed")
        res = check_part(tmp, n, args.before)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load_after = load()
    lines = [("| run | peak RSS [MB] | process wall / CPU [s] | computation wall / CPU [s] | "
              "result |"), "|---|---|---|---|---|"]
    for label, r in res["runs"]:
        comp = "" if r.get("comp_s") is None else (
            f"{r['comp_s']:.1f}" + (f" / {r['comp_cpu']:.1f}" if "comp_cpu" in r else ""))
        what = (f"{'moving' if r['moving'] else 'static'}, {r['flags']} flagged range(s), "
                f"{r['windows']} window lengths" if "moving" in r else "")
        lines.append(f"| {label} | {r['rss_mb']:.0f} | {r['wall']:.1f} / {r['cpu']:.1f} | {comp} | "
                     f"{what} |")
    wv = res["runs"][0][1]["comp_s"]
    ratios = ", ".join(f"{r['comp_s'] / wv:.2f}x" for _, r in res["runs"][1:3])
    text = (f"`python benchmarks/bench_stream.py --check` ({machine()}; load average "
            f"{load_before} before, {load_after} after; one channel of {res['n']:.3g} float64 "
            f"samples, {res['size_gb']:.2f} GB, WN + RW on a 1e8 offset with a knock at 40 % and a "
            f"burst of vibration at 70 %, written to {base} in {res['gen_s']:.0f} s and deleted)."
            "\n\n" + "\n".join(lines) + "\n\n"
            f"* The streamed check takes {ratios} the streamed WV's wall time (no rate, 100 Hz); "
            "its memory does not grow with the length (per test at most 65536 statistics for the "
            "robust scale and the extremes of 2048 blocks; the flagged blocks are re-read).\n"
            "* Peak RSS is each process's own (GNU time); process wall / CPU include start-up "
            "and imports, computation wall / CPU (in the process) do not.\n")
    print(text)
    if args.readme:
        update_section("bench_stream_check", text)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", default=None, help="where the temporary files go")
    parser.add_argument("--channels", type=int, default=6)
    parser.add_argument("--hdf5-samples", type=float, default=5e7)
    parser.add_argument("--npy-samples", type=float, default=3e8)
    parser.add_argument("--project-channels", type=int, default=6)
    parser.add_argument("--project-samples", type=float, default=2.6e8)
    parser.add_argument("--no-in-memory", action="store_true",
                        help="skip the whole-file (non-streamed) gmwm wv run")
    parser.add_argument("--readme", action="store_true", help="write the results into README.md")
    parser.add_argument("--check", action="store_true",
                        help="the streamed stationarity check against the streamed WV instead")
    parser.add_argument("--check-samples", type=float, default=2e8)
    parser.add_argument("--before", default=None, metavar="SRC",
                        help="with --check: also run another checkout's src directory")
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--child":
        return _child(*sys.argv[2:5])
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO / "src"))
    if args.check:
        return check_main(args)
    base = Path(args.dir or tempfile.gettempdir())
    tmp = Path(tempfile.mkdtemp(prefix="gmwm-bench-stream-", dir=base))
    n_h, n_n, C = int(args.hdf5_samples), int(args.npy_samples), args.channels
    load_before = load()
    notes, h, b = [], None, None
    try:
        need_h = 2 * C * n_h * 8 / GB * 1.05       # the file and the streamed WV's panel files
        free = _free_gb(tmp)
        print(f"free disk in {tmp}: {free:.1f} GB; the HDF5 part needs {need_h:.1f} GB", flush=True)
        if free > need_h:
            h = hdf5_part(tmp, n_h, C)
        else:
            notes.append(f"HDF5 part skipped: {free:.1f} GB free in {base}, {need_h:.1f} GB needed")
        need_n = 2 * n_n * 8 / GB * 1.05
        free = _free_gb(tmp)
        print(f"free disk in {tmp}: {free:.1f} GB; the .npy part needs {need_n:.1f} GB", flush=True)
        if free > need_n:
            b = npy_part(tmp, n_n, not args.no_in_memory)
        else:
            notes.append(f".npy part skipped: {free:.1f} GB free in {base}, {need_n:.1f} GB needed")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load_after = load()
    header = ("| run | file | peak RSS [MB] | wall / CPU [s] | streamed WV [s] | WV vs in-memory "
              "(max rel. diff, all levels) |")
    lines = [header, "|---|---|---|---|---|---|"]
    if h is not None:
        r = h["run"]
        lines.append(f"| `gmwm report rec.h5 WN+RW --columns` {C} channels | HDF5, {C} x "
                     f"{h['n']:.3g} samples, {h['size_gb']:.2f} GB | {r['rss_mb']:.0f} | "
                     f"{r['wall']:.1f} / {r['cpu']:.1f} | {h['wv_s']:.1f} (all channels) | "
                     f"{h['diff']:.1e} (/imu/gx, {h['levels']} levels, against `wvar` of the "
                     "channel read whole) |")
    if b is not None:
        r = b["run"]
        diff = f"{b['diff']:.1e} ({b['levels']} levels)" if b.get("inmem") else b["skip_inmem"]
        lines.append(f"| `gmwm wv big.npy` (streamed) | .npy, {b['n']:.3g} samples, "
                     f"{b['size_gb']:.2f} GB | {r['rss_mb']:.0f} | {r['wall']:.1f} / "
                     f"{r['cpu']:.1f} | {b['wv_s']:.1f} | {diff} |")
        if b.get("inmem"):
            m = b["inmem"]
            lines.append(f"| `gmwm wv big.npy`, whole file in memory (GMWM_STREAM_MIN_BYTES "
                         f"huge) | same | {m['rss_mb']:.0f} | {m['wall']:.1f} / {m['cpu']:.1f} | "
                         f"{b['inmem_wv_s']:.1f} (not streamed) | reference |")
    proj = []
    P, N = args.project_channels, args.project_samples
    if h is not None:
        r = h["run"]
        per = h["wv_s"] / (h["n"] * h["channels"])
        rest = max(r["wall"] - h["wv_s"], 0.0)
        proj.append(f"* Projection to {P} x {N:.3g} samples ({P * N * 8 / GB:.1f} GB as float64): "
                    f"the streamed WV takes {per * 1e9:.2f} ns per sample and channel in the "
                    f"{C}-channel run, so ~{per * P * N:.0f} s for the WVs plus ~{rest:.0f} s for "
                    f"the fits and the report (independent of T): ~{(per * P * N + rest) / 60:.1f} "
                    f"min. Peak RSS stays at the measured {r['rss_mb']:.0f} MB (the chunk size "
                    f"and the phase-2 groups are fixed by the memory budget, "
                    "`gmwm.stream.DEFAULT_MEMORY`, not by T); the panel files need "
                    f"{P * N * 8 / GB:.1f} GB of temporary disk (8 bytes per sample and channel).")
    if b is not None:
        per1 = b["wv_s"] / b["n"]
        proj.append(f"* One channel: {per1 * 1e9:.2f} ns per sample streamed from .npy "
                    f"({b['n'] * 8 / 1e6 / b['wv_s']:.0f} MB/s of float64).")
    text = (f"`python benchmarks/bench_stream.py` ({machine()}; load average {load_before} "
            f"before, {load_after} after; files generated in {base} and deleted).\n\n"
            + "\n".join(lines) + "\n\n" + "\n".join(proj + [f"* {n}" for n in notes]) + "\n")
    print(text)
    if args.readme:
        update_section("bench_stream", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
