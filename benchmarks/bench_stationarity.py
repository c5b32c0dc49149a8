"""False alarms and detection of the stationarity check (gmwm.stationarity, docs/METHODS.md §16).

    python benchmarks/bench_stationarity.py [--static 240] [--reps 20] [--seed 1] [--write]
    python benchmarks/bench_stationarity.py --calibrate [--static 400]

* **False alarms**: ``--static`` simulated static 6-axis recordings (gyroscope in rad/s,
  accelerometer in m/s^2 with gravity on z) of the IMU-like profiles of :data:`PROFILES`
  (WN+RW, WN+GM+RW, QN+WN+RW+DR, ...), rates 100-1000 Hz, lengths 2 min - 1 h
  (:data:`SETTINGS`); a recording is a false alarm when anything is flagged.
* **Detection**: ``--reps`` static recordings per cell (10 min at 200 Hz) with one injected event
  in the middle: a bias step on one gyroscope or accelerometer axis (sizes in multiples of
  ``sd_min``, the smallest standard deviation of a window-mean difference over the tested window
  lengths under the profile's model: a step of 1 ``sd_min`` is the smallest change the best window
  can see), a tilt of a few degrees and back, a turn about the vertical, a push (translation).
  Detected = a flagged range overlaps the event.
* **Real moving recordings**: the four files of ``../shared/data/external`` when present (or of
  the folder named by the environment variable ``GMWM_EXTERNAL_DATA``).

``--calibrate`` prints, for several values of the small-sample factor c of the threshold
z * (1 + c / sqrt(K)), the false-alarm rate of the static recordings (the choice of
``gmwm.stationarity.SMALL_SAMPLE``). ``--write`` stores the tables in
docs/stationarity_results.md. The helpers :func:`static_imu`, :func:`inject_step`,
:func:`inject_tilt`, :func:`inject_turn`, :func:`inject_push` are also used by the tests.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: the real recordings: ../shared/data/external next to the repository, or $GMWM_EXTERNAL_DATA
EXTERNAL = Path(os.environ.get("GMWM_EXTERNAL_DATA") or REPO.parent / "shared" / "data" / "external")
EXTERNAL_FILES = ("px4-pyulog-sample/sample.ulg", "ros1-rl-husky/test1.bag",
                  "ros1-imutools-phidgets/phidgets_imu_upside_down.bag",
                  "euroc-kimera-v101/mav0/imu0/data.csv")
G = 9.80665


@dataclass(frozen=True)
class Profile:
    """Continuous-time coefficients of one sensor type (SI): model spec and values; per-sample
    parameters follow from the rate (docs/METHODS.md §10.1)."""

    name: str
    spec: str
    nd: float  # white noise density (unit sqrt(s))
    k: float  # random walk (unit / sqrt(s))
    gm: tuple[float, float] | None = None  # (sd, correlation time s)
    lsb: float = 0.0  # quantisation step (unit)
    drift: float = 0.0  # ramp (unit / s)

    def theta(self, fs: float):
        from gmwm.model import Model

        m = Model(self.spec, freq=fs)
        v = {"WN[1].sigma2": self.nd ** 2 * fs, "RW[1].gamma2": self.k ** 2 / fs}
        if self.gm is not None:
            v["GM[1].sigma2"], v["GM[1].beta"] = self.gm[0] ** 2, 1.0 / self.gm[1]
        if "QN" in self.spec:
            v["QN[1].Q2"] = self.lsb ** 2 / 12.0
        if "DR" in self.spec:
            v["DR[1].omega"] = self.drift / fs
        return m, m.theta(v)


#: (name, gyroscope profile, accelerometer profile): a tactical-grade MEMS (ADIS16448-like, the
#: EuRoC sensor), a consumer MEMS as measured by imu_utils (BMI160: ten times its datasheet),
#: a quantised 16-bit consumer part with a drift, and a low-noise part with a strong random walk.
PROFILES = (
    ("tactical MEMS", Profile("g", "WN+RW", 1.7e-4, 2e-5), Profile("a", "WN+RW", 2e-3, 3e-3)),
    ("consumer MEMS", Profile("g", "WN+GM+RW", 1.2e-3, 2.6e-5, (3e-4, 50.0)),
     Profile("a", "WN+GM+RW", 2e-2, 5e-4, (2e-3, 100.0))),
    ("quantised 16-bit", Profile("g", "QN+WN+RW+DR", 1.5e-4, 1e-5, lsb=1.065e-3, drift=2e-6),
     Profile("a", "QN+WN+RW+DR", 3e-3, 1e-3, lsb=2.39e-3, drift=1e-5)),
    ("low noise, strong RW", Profile("g", "WN+GM+RW", 2e-5, 1e-4, (2e-5, 300.0)),
     Profile("a", "WN+RW", 1e-4, 1e-3)),
)
#: (rate Hz, seconds) of the static recordings, used in turn
SETTINGS = ((100.0, 3600.0), (200.0, 600.0), (400.0, 1800.0), (1000.0, 120.0),
            (200.0, 3600.0), (1000.0, 900.0), (100.0, 300.0), (400.0, 600.0))
AXES = ("gx", "gy", "gz", "ax", "ay", "az")


def static_imu(profile: int, fs: float, seconds: float, rng: np.random.Generator
               ) -> dict[str, np.ndarray]:
    """Six static axes of profile ``profile`` (index into :data:`PROFILES`): gyroscope rad/s
    with an Earth-rate-like offset, accelerometer m/s^2 with gravity on z."""
    _, gp, ap = PROFILES[profile]
    n = round(fs * seconds)
    out = {}
    for i, c in enumerate(AXES):
        m, th = (gp if c[0] == "g" else ap).theta(fs)
        x = m.simulate_fast(th, n, rng)
        x -= x[0]
        off = 7.3e-5 * (i - 1) if c[0] == "g" else (G if c == "az" else 0.05 * (i - 4))
        if "QN" in m.spec:  # a quantised sensor reports multiples of its step
            lsb = (gp if c[0] == "g" else ap).lsb
            x = np.round((x + off) / lsb) * lsb
        else:
            x += off
        out[c] = x
    return out


UNITS = {c: ("rad/s" if c[0] == "g" else "m/s^2") for c in AXES}


def write_csv(path: Path, x: dict[str, np.ndarray], fs: float,
              units: dict[str, str] | None = None) -> Path:
    """The six axes of ``x`` as a CSV recording at ``fs`` Hz: a time column [s] and one column
    per axis, its unit in the header (default :data:`UNITS`)."""
    units = units or UNITS
    n = x[AXES[0]].size
    cols = [np.arange(n) / fs] + [x[c] for c in AXES]
    head = "time [s]," + ",".join(f"{c} [{units[c]}]" for c in AXES)
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=head, comments="",
               fmt="%.10g")
    return path


def sd_min(profile: int, axis: str, fs: float, n: int) -> float:
    """Smallest sd of a window-mean difference over the tested windows: sqrt(2 AV(L)) = 2 sqrt(nu)
    at the Haar filter length 2L (docs/METHODS.md §2.4)."""
    from gmwm.stationarity import _ladder

    _, gp, ap = PROFILES[profile]
    m, th = (gp if axis[0] == "g" else ap).theta(fs)
    L = 2.0 * np.asarray(_ladder(n, fs), dtype=float)
    return float(np.min(2.0 * np.sqrt(m.wv(th, 2.0 * L))))


def _window(n: int, fs: float, t0: float, dur: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) / fs
    u = (t - t0) / dur
    inside = (u >= 0) & (u <= 1)
    return u, inside


def inject_step(x: dict[str, np.ndarray], axis: str, size: float, at: int) -> None:
    """A bias step of ``size`` on ``axis`` from sample ``at`` on."""
    x[axis][at:] += size


def inject_tilt(x: dict[str, np.ndarray], fs: float, t0: float, dur: float, deg: float) -> None:
    """Tilt about x by ``deg`` degrees and back within ``dur`` s (raised cosine): gyro x sees the
    rate, accelerometer y and z the rotated gravity."""
    n = x["gx"].size
    u, inside = _window(n, fs, t0, dur)
    th = np.where(inside, 0.5 * math.radians(deg) * (1 - np.cos(2 * np.pi * u)), 0.0)
    rate = np.where(inside, 0.5 * math.radians(deg) * 2 * np.pi / dur * np.sin(2 * np.pi * u), 0)
    x["gx"] += rate
    x["ay"] += G * np.sin(th)
    x["az"] += G * (np.cos(th) - 1.0)


def inject_turn(x: dict[str, np.ndarray], fs: float, t0: float, dur: float, deg: float) -> None:
    """Turn about the vertical (z) by ``deg`` degrees within ``dur`` s: only gyro z sees it."""
    n = x["gz"].size
    u, inside = _window(n, fs, t0, dur)
    x["gz"] += np.where(inside, math.radians(deg) / dur * (1 - np.cos(2 * np.pi * u)), 0.0)


def inject_push(x: dict[str, np.ndarray], fs: float, t0: float, dur: float, metres: float
                ) -> None:
    """Move by ``metres`` along x and back within ``dur`` s (raised-cosine displacement): only
    accelerometer x sees it (peak acceleration 2 pi^2 metres / dur^2)."""
    n = x["ax"].size
    u, inside = _window(n, fs, t0, dur)
    w = 2 * np.pi / dur
    x["ax"] += np.where(inside, 0.5 * metres * w * w * np.cos(2 * np.pi * u), 0.0)


def check(x: dict[str, np.ndarray], fs: float):
    from gmwm.stationarity import check_stationarity

    return check_stationarity(x, freq=fs, units=UNITS)


# --------------------------------------------------------------------------------------------------


def false_alarms(n_rec: int, seed: int) -> tuple[list[tuple], int, int, float]:
    """Per (profile, rate, length): recordings, false alarms; total; CPU seconds of the checks."""
    rng = np.random.default_rng(seed)
    cells: dict[tuple, list[int]] = {}
    cpu = 0.0
    for r in range(n_rec):
        p = r % len(PROFILES)
        fs, sec = SETTINGS[(r // len(PROFILES)) % len(SETTINGS)]
        x = static_imu(p, fs, sec, rng)
        t0 = time.process_time()
        st = check(x, fs)
        cpu += time.process_time() - t0
        key = (PROFILES[p][0], fs, sec)
        c = cells.setdefault(key, [0, 0])
        c[0] += 1
        c[1] += int(st.moving)
    rows = [(k[0], k[1], k[2], v[0], v[1]) for k, v in sorted(cells.items())]
    return rows, n_rec, sum(v[1] for v in cells.values()), cpu


EVENTS = (("step gyro x", "step", "gx", (4, 8, 16, 32)),
          ("step accel y", "step", "ay", (4, 8, 16, 32)),
          ("tilt about x, 3 s (deg)", "tilt", None, (0.05, 0.2, 1.0, 5.0)),
          ("turn about z, 3 s (deg)", "turn", None, (0.5, 2.0, 10.0, 90.0)),
          ("push along x, 3 s (m)", "push", None, (0.0005, 0.002, 0.01, 0.1)))


def detection(reps: int, seed: int, fs: float = 200.0, seconds: float = 600.0) -> list[tuple]:
    """Rows (profile, event, size, sd_min or '', detected, reps, located)."""
    rng = np.random.default_rng(seed + 1000)
    n = int(fs * seconds)
    rows = []
    for p, (pname, _, _) in enumerate(PROFILES):
        for label, kind, axis, sizes in EVENTS:
            for size in sizes:
                hit = 0
                for _ in range(reps):
                    x = static_imu(p, fs, seconds, rng)
                    t0 = float(rng.uniform(0.3, 0.7) * seconds)
                    if kind == "step":
                        s = size * sd_min(p, axis, fs, n)
                        inject_step(x, axis, s, int(t0 * fs))
                        ev = (t0 - 1.0, t0 + 1.0)
                    else:
                        {"tilt": inject_tilt, "turn": inject_turn, "push": inject_push}[kind](
                            x, fs, t0, 3.0, size)
                        ev = (t0, t0 + 3.0)
                    st = check(x, fs)
                    hit += any(s.end_s > ev[0] and s.start_s < ev[1] for s in st.segments)
                unit = " x sd_min" if kind == "step" else ""
                rows.append((pname, label, f"{size:g}{unit}", hit, reps))
    return rows


def external() -> list[tuple]:
    """Rows (file, verdict, flagged share, ranges, clean segment) of the real moving files."""
    from gmwm.readers.recording import read_recording
    from gmwm.stationarity import check_stationarity

    rows = []
    for f in EXTERNAL_FILES:
        p = EXTERNAL / f
        if not p.exists():
            rows.append((f, "absent", "", "", ""))
            continue
        rec = read_recording(p)
        st = check_stationarity(rec)
        share = sum(s.i1 - s.i0 for s in st.segments) / st.n
        a, b = st.clean_segment()
        rng = ", ".join(f"{s.start_s:.1f}-{s.end_s:.1f}" for s in st.segments[:4])
        if len(st.segments) > 4:
            rng += f", ... ({len(st.segments)} ranges)"
        rows.append((f, "moving" if st.moving else "static", f"{100 * share:.0f} %", rng,
                     f"{st.time_at(a):.1f}-{st.time_at(b):.1f} s"))
    return rows


def calibrate(n_rec: int, seed: int, factors=(0.0, 1.0, 2.0, 3.0, 4.0)) -> list[tuple]:
    """False alarms of the static recordings for several small-sample factors c: from the largest
    statistic of every channel, test and window length (the report's ``peaks``)."""
    import gmwm.stationarity as s

    rng = np.random.default_rng(seed)
    fa = np.zeros(len(factors), dtype=int)
    margin = []
    for r in range(n_rec):
        p = r % len(PROFILES)
        fs, sec = SETTINGS[(r // len(PROFILES)) % len(SETTINGS)]
        st = check(static_imu(p, fs, sec, rng), fs)
        for i, c in enumerate(factors):
            fa[i] += any(z > st.threshold * (1 + c / math.sqrt(k)) for *_, k, z, _ in st.peaks)
        margin.append(max(z / thr for *_, z, thr in st.peaks))
    out = [(c, int(f), n_rec) for c, f in zip(factors, fa, strict=True)]
    for c, f, n in out:
        print(f"c = {c:g}: {f} false alarms in {n} static recordings")
    q = np.quantile(margin, [0.5, 0.9, 0.99])
    print(f"largest statistic / threshold at c = {s.SMALL_SAMPLE:g}: median {q[0]:.3f}, "
          f"90 % {q[1]:.3f}, 99 % {q[2]:.3f}")
    return out


def _specs(name: str) -> str:
    _, g, a = next(p for p in PROFILES if p[0] == name)
    return f"{g.spec} / {a.spec}"


def _md(headers: list[str], rows: list[tuple]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--static", type=int, default=240, help="static recordings (false alarms)")
    ap.add_argument("--reps", type=int, default=20, help="recordings per detection cell")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--calibrate", action="store_true")
    ap.add_argument("--write", action="store_true", help="write docs/stationarity_results.md")
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    if args.calibrate:
        calibrate(args.static, args.seed)
        return
    import gmwm.stationarity as s

    t0 = time.time()
    fa_rows, n, fa, cpu = false_alarms(args.static, args.seed)
    by_p: dict[str, list[int]] = {}
    by_s: dict[tuple[float, float], list[int]] = {}
    for a, b, c, d, e in fa_rows:
        for agg, key in ((by_p, a), (by_s, (b, c))):
            v = agg.setdefault(key, [0, 0])
            v[0] += d
            v[1] += e
    fa_table = (_md(["profile (gyroscope / accelerometer model)", "recordings", "false alarms"],
                    [(f"{p} ({_specs(p)})", *v) for p, v in by_p.items()]) + "\n\n"
                + _md(["rate (Hz)", "length (s)", "recordings", "false alarms"],
                      [(f"{k[0]:g}", f"{k[1]:g}", *v) for k, v in sorted(by_s.items())]))
    print(fa_table)
    print(f"false alarms: {fa} of {n} ({100 * fa / n:.2g} %); CPU of the checks {cpu:.1f} s")
    det = detection(args.reps, args.seed)
    det_table = _md(["profile", "event", "size", "detected", "of"], det)
    n10 = int(200.0 * 600.0)
    sd_rows = []
    for p, (pname, g, a) in enumerate(PROFILES):
        sd_rows.append((pname, f"{sd_min(p, 'gx', 200.0, n10):.3g}",
                        f"{g.nd * math.sqrt(200.0):.3g}", f"{sd_min(p, 'ay', 200.0, n10):.3g}",
                        f"{a.nd * math.sqrt(200.0):.3g}"))
    det_table = _md(["profile", "gyro sd_min (rad/s)", "gyro white-noise sd per sample",
                     "accel sd_min (m/s^2)", "accel white-noise sd per sample"],
                    sd_rows) + "\n\n" + det_table
    print(det_table)
    ext = external()
    ext_table = _md(["file", "verdict", "flagged", "flagged ranges (s)", "longest static"], ext)
    print(ext_table)
    wall = time.time() - t0
    info = (f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; seed {args.seed}; "
            f"alpha {s.ALPHA:g}, small-sample factor {s.SMALL_SAMPLE:g}; {wall:.0f} s wall, "
            f"1-minute load average {load0:.2f} at the start")
    if args.write:
        from gmwm.atomic import write_text_atomic

        text = "\n\n".join([
            "# Stationarity check: false alarms and detection",
            ("Written by `python benchmarks/bench_stationarity.py --write` (" + info + "). "
             "Method: docs/METHODS.md §16."),
            (f"## False alarms on static recordings\n\n{fa} of {n} simulated static 6-axis "
             f"recordings flagged ({100 * fa / n:.2g} %; target <= 1 %)."),
            fa_table,
            ("## Detection of injected events\n\n10 min at 200 Hz; the event starts at a random "
             "time between 30 and 70 % of the recording. sd_min: the smallest standard deviation "
             "of a window-mean difference over the tested window lengths under the profile's "
             "model (sqrt(2 AV(L)), docs/METHODS.md §2.4)."),
            det_table,
            "## Real moving recordings (../shared/data/external)",
            ext_table])
        write_text_atomic(REPO / "docs" / "stationarity_results.md", text + "\n")
    print(info)


if __name__ == "__main__":
    sys.exit(main())
