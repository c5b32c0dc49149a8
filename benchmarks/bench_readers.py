"""Decoding speed of gmwm.readers per format: one hour of sensor_msgs/Imu at 200 Hz (720,000
messages) as a ROS 1 bag, a ROS 2 sqlite3 bag and a ROS 2 MCAP bag (written by rosbags' writers),
a PX4 ULog of the same length, and a 1e7-row EuRoC CSV.

    python benchmarks/bench_readers.py [--dir DIR] [--repeat 3] [--euroc-rows 10000000]
        [--no-report] [--readme]

Files are written once to DIR (default: a temporary folder; give --dir to keep them between
runs). Each read is ``gmwm.readers.read_recording(path)``, best of --repeat after a warm-up
call, CPU and wall seconds; the import of the container libraries is outside the timing. Then
``gmwm report`` on the ROS 1 bag end to end (a child process: wall, CPU and peak RSS of the child).
``--readme`` writes the tables into benchmarks/README.md (run it on an idle machine).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_wv import best_time
from readme_section import load as load_avg
from readme_section import machine, run_measured, update_section

T0 = 1_700_000_000_000_000_000
FS = 200.0


def _template(kind: str):
    """One serialized Imu message (library serializer) and the byte offsets of its fields."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
    T = ts.types
    hdr = {"seq": 0} if kind == "ros1" else {}
    msg = T["sensor_msgs/msg/Imu"](
        T["std_msgs/msg/Header"](**hdr, stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                 frame_id="imu_link"),
        T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0), np.zeros(9),
        T["geometry_msgs/msg/Vector3"](3.0, 4.0, 5.0), np.zeros(9),
        T["geometry_msgs/msg/Vector3"](6.0, 7.0, 8.0), np.zeros(9))
    raw = (ts.serialize_ros1 if kind == "ros1" else ts.serialize_cdr)(msg, "sensor_msgs/msg/Imu")
    b = bytes(raw)
    pos = {"sec": 4, "nsec": 8, "g": b.index(np.float64(3.0).tobytes()),
           "a": b.index(np.float64(6.0).tobytes())}
    return ts, b, pos


def _messages(kind: str, n: int, rng: np.random.Generator):
    """(stamps, (n, size) uint8 messages, gyro, accel): the template with fields replaced."""
    ts, b, pos = _template(kind)
    stamps = T0 + np.arange(n, dtype=np.int64) * 5_000_000
    g = rng.standard_normal((n, 3)) * 1e-3
    a = rng.standard_normal((n, 3)) * 2e-2
    m = np.tile(np.frombuffer(b, np.uint8), (n, 1))
    m[:, pos["sec"]:pos["sec"] + 4] = (stamps // 10**9).astype("<u4").view(np.uint8).reshape(n, 4)
    m[:, pos["nsec"]:pos["nsec"] + 4] = (stamps % 10**9).astype("<u4").view(np.uint8).reshape(n, 4)
    m[:, pos["g"]:pos["g"] + 24] = g.astype("<f8").view(np.uint8).reshape(n, 24)
    m[:, pos["a"]:pos["a"] + 24] = a.astype("<f8").view(np.uint8).reshape(n, 24)
    return ts, stamps, m, g, a


def write_bag(path: Path, kind: str, n: int) -> np.ndarray:
    ts, stamps, m, g, _ = _messages(kind, n, np.random.default_rng(1))
    if kind == "ros1":
        from rosbags.rosbag1 import Writer

        w = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap"
                   else StoragePlugin.SQLITE3)
    with w:
        c = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        for i in range(n):
            w.write(c, int(stamps[i]), m[i].tobytes())
    return g


def write_ulog(path: Path, n: int) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from _ulog_writer import write_ulog as _write

    rng = np.random.default_rng(2)
    g = rng.standard_normal((n, 3)).astype(np.float32)
    fields = {"sensor_combined": [("timestamp", "uint64_t"), ("gyro_rad", "float[3]"),
                                  ("accelerometer_m_s2", "float[3]")]}
    t = 1_000_000 + np.arange(n, dtype=np.uint64) * 5000
    _write(path, {("sensor_combined", 0): {"timestamp": t, "gyro_rad": g,
                                           "accelerometer_m_s2": g}}, fields)


def write_euroc(path: Path, n: int) -> None:
    rng = np.random.default_rng(3)
    with open(path, "w") as fh:
        fh.write("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                 "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n")
        for a in range(0, n, 1_000_000):
            k = min(1_000_000, n - a)
            t = T0 + (a + np.arange(k, dtype=np.int64)) * 5_000_000
            v = rng.standard_normal((k, 6))
            cols = [t.astype(str)] + [np.char.mod("%.9f", v[:, j]) for j in range(6)]
            fh.write("\n".join(",".join(r) for r in zip(*cols, strict=True)) + "\n")


#: real recordings of ../shared/data/external (provenance in its README), timed end to end
EXTERNAL_FILES = {
    "ros1-rl-husky/test1.bag": "ROS 1 bag, Husky robot driving, 30 Hz, 395 s",
    "ros1-imutools-phidgets/phidgets_imu_upside_down.bag": "ROS 1 bag, Phidgets IMU, 248 Hz, moved",
    "px4-pyulog-sample/sample.ulg": "PX4 ULog, 248 Hz, 69 s, in flight",
    "euroc-kimera-v101/mav0/imu0/data.csv": "EuRoC CSV, 200 Hz, 146 s, MAV flight",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--messages", type=int, default=720_000)
    ap.add_argument("--euroc-rows", type=int, default=10_000_000)
    ap.add_argument("--no-report", action="store_true", help="skip the `gmwm report` runs")
    ap.add_argument("--external", type=Path,
                    default=Path(__file__).resolve().parents[2] / "shared" / "data" / "external",
                    help="folder of real recordings written by other software: `gmwm report` "
                         "(automatic model) on each of EXTERNAL_FILES found there")
    ap.add_argument("--readme", action="store_true", help="write the tables into README.md")
    args = ap.parse_args()
    tmp = None
    if args.dir is None:
        tmp = tempfile.mkdtemp(prefix="bench_readers_")
    d = Path(args.dir or tmp)
    d.mkdir(parents=True, exist_ok=True)
    n = args.messages
    files = {"ROS 1 bag": (d / f"imu_{n}.bag", lambda p: write_bag(p, "ros1", n)),
             "ROS 2 sqlite3": (d / f"imu_{n}_db3", lambda p: write_bag(p, "sqlite3", n)),
             "ROS 2 MCAP": (d / f"imu_{n}_mcap", lambda p: write_bag(p, "mcap", n)),
             "PX4 ULog": (d / f"imu_{n}.ulg", lambda p: write_ulog(p, n)),
             "EuRoC CSV": (d / f"euroc_{args.euroc_rows}.csv",
                           lambda p: write_euroc(p, args.euroc_rows))}
    for name, (p, make) in files.items():
        if not p.exists():
            t0 = time.perf_counter()
            make(p)
            print(f"wrote {name} {p} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    import pandas  # noqa: F401 - imports outside the timing
    import pyulog  # noqa: F401
    import rosbags.rosbag1
    import rosbags.rosbag2  # noqa: F401

    from gmwm.readers.recording import read_recording

    before = load_avg()
    rows = []
    for name, (p, _) in files.items():
        rec = read_recording(p)
        wall, cpu = best_time(lambda p=p: read_recording(p), args.repeat)
        rows.append((name, rec.n, rec.freq, wall, cpu, rec.n / cpu))
    head = ("| format | messages / rows | rate [Hz] | wall [s] | CPU [s] | messages/s (CPU) |\n"
            "|---|---|---|---|---|---|")
    table = "\n".join([head] + [f"| {r[0]} | {r[1]} | {r[2]:g} | {r[3]:.3f} | {r[4]:.3f} | "
                                f"{r[5]:.3g} |" for r in rows])
    report = ""
    if not args.no_report:
        bag = files["ROS 1 bag"][0]
        out = d / "report_out"
        shutil.rmtree(out, ignore_errors=True)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [
            str(Path(__file__).resolve().parents[1] / "src"), os.environ.get("PYTHONPATH")]))}
        def timed(path: Path) -> str:
            """exit, best and median wall, median CPU and largest peak RSS of --repeat runs (a
            shared VM's steal time makes single runs vary by +-30 %)."""
            runs = []
            for _ in range(args.repeat):
                shutil.rmtree(out, ignore_errors=True)
                runs.append(run_measured([sys.executable, "-m", "gmwm", "report", str(path),
                                          "-o", str(out)], env=env))
                if runs[-1]["code"] != 0:
                    print(runs[-1]["err"], file=sys.stderr)
            shutil.rmtree(out, ignore_errors=True)
            wall = [r["wall"] for r in runs]
            return (f"{max(r['code'] for r in runs)} | {min(wall):.2f} / {np.median(wall):.2f} | "
                    f"{np.median([r['cpu'] for r in runs]):.2f} | "
                    f"{max(r['rss_mb'] for r in runs):.0f} |")

        report = (f"\n\n| run | exit | wall [s], best / median of {args.repeat} | CPU of the "
                  "child [s], median | peak RSS [MB] |\n|---|---|---|---|---|\n"
                  f"| `gmwm report {bag.name} -o DIR` ({n} messages, 200 Hz, six axes) | "
                  + timed(bag))
        for rel, what in EXTERNAL_FILES.items():
            f = args.external / rel
            if f.exists():
                report += f"\n| `gmwm report {f.name} -o DIR` ({what}; real file) | " + timed(f)
    info = (f"`python benchmarks/bench_readers.py`: `read_recording`, best of {args.repeat} after "
            f"a warm-up call; {machine()}; load average {before} before, {load_avg()} after.")
    print(info)
    print(table + report)
    if args.readme:
        update_section("bench_readers", info + "\n\n" + table + report)
    if tmp is not None:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
