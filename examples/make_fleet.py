"""Write a synthetic fleet of IMU recordings for trying ``gmwm fleet`` (and its benchmark).

    python examples/make_fleet.py FOLDER [--units 12] [--minutes 5] [--long-minutes M]
                                         [--freq 100] [--seed 1] [--bags 0.25] [--h5 0.25]
                                         [--odd 1] [--dated 4] [--corrupt 1]
    gmwm fleet FOLDER --columns all --units gx,gy,gz=rad/s --units ax,ay,az=m/s^2 -o fleet

What is written (file names follow the fleet's unit rule ``<unit>_<YYYY-MM-DD>``):

* ``--units`` static six-axis units (gyroscope rad/s, accelerometer m/s^2 with gravity on z),
  white noise plus a weak random walk; each unit's densities drawn around a typical value with a
  between-unit spread of 10 % on the log scale (gyroscope 1e-4 rad/s/sqrt(Hz), accelerometer
  1e-3 m/s^2/sqrt(Hz));
* ``--odd`` of them out of family (gyroscope noise density 3x the typical value), named
  ``odd<k>``;
* one degrading unit ``aging`` recorded ``--dated`` times, 60 days apart, its gyroscope noise
  density growing by 40 % per year;
* one unit ``moved`` whose log is static for its first 40 % and then turns (the fleet uses the
  static start);
* ``--corrupt`` unreadable files ``corrupt<k>_...``: in turn a CSV with a broken row, a ROS 1 bag
  cut after its header, an ``.h5`` file that is not HDF5.

``aging`` and ``moved`` last ``--long-minutes`` (default ``--minutes``): the fleet needs a static
stretch of at least 60 s, so ``moved`` needs at least 2.5 minutes, and a longer ``aging`` gives
its drift a narrower interval. A share ``--bags`` of the static units is written as ROS 1 bags
(``sensor_msgs/Imu``, by ``rosbags``' own writer; needs the ``recordings`` extra), a share
``--h5`` as HDF5 (by h5py: 1-D datasets ``time``, ``gx`` ... ``az``), the rest as CSV with a
time column.
``truth.json`` beside them lists every recording's true densities (not a recording suffix:
the fleet ignores it). Nothing random is unseeded.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
from pathlib import Path

import numpy as np

GYRO_ND, ACCEL_ND = 1e-4, 1e-3  # typical white-noise densities [rad/s/sqrt(Hz)], [m/s^2/sqrt(Hz)]
SPREAD = 0.10  # between-unit standard deviation of log(density)
DAY0 = dt.date(2026, 1, 5)


def signals(n: int, freq: float, gyro_nd: float, accel_nd: float, rng: np.random.Generator,
            turn_from: int | None = None) -> np.ndarray:
    """(n, 6) samples gx, gy, gz, ax, ay, az: white noise of the given densities plus a weak
    random walk (1 % of the density per sqrt(s)); a 0.5 rad/s turn from ``turn_from`` on."""
    out = np.empty((n, 6))
    for k, nd in enumerate([gyro_nd] * 3 + [accel_nd] * 3):
        white = rng.normal(0.0, nd * math.sqrt(freq), n)
        walk = np.cumsum(rng.normal(0.0, 0.01 * nd / math.sqrt(freq), n))
        out[:, k] = white + walk
    out[:, 5] += 9.80665
    if turn_from is not None:
        out[turn_from:, 2] += 0.5 * np.sin(np.arange(n - turn_from) / freq)
    return out


def write_csv(path: Path, data: np.ndarray, freq: float) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "w") as fh:
        fh.write("time,gx,gy,gz,ax,ay,az\n")
        np.savetxt(fh, np.column_stack([np.arange(len(data)) / freq, data]), delimiter=",",
                   fmt="%.9g")
    tmp.replace(path)


def write_bag(path: Path, data: np.ndarray, freq: float) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    Imu, Header = ts.types["sensor_msgs/msg/Imu"], ts.types["std_msgs/msg/Header"]
    Time, V3 = ts.types["builtin_interfaces/msg/Time"], ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    cov = np.zeros(9)
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0
    t0 = 1_700_000_000 * 10**9
    step = round(1e9 / freq)
    tmp = path.with_name(path.name + ".part.bag")
    with Writer(tmp) as w:
        conn = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        for i, row in enumerate(data):
            t = t0 + i * step
            msg = Imu(Header(seq=i, stamp=Time(sec=t // 10**9, nanosec=t % 10**9),
                             frame_id="imu"), Q(0.0, 0.0, 0.0, 1.0), no_orientation,
                      V3(*map(float, row[:3])), cov, V3(*map(float, row[3:])), cov)
            w.write(conn, t, ts.serialize_ros1(msg, "sensor_msgs/msg/Imu"))
    tmp.replace(path)


def write_h5(path: Path, data: np.ndarray, freq: float) -> None:
    import h5py

    tmp = path.with_name(path.name + ".part.h5")
    with h5py.File(tmp, "w") as fh:
        fh.create_dataset("time", data=np.arange(len(data)) / freq)
        for k, name in enumerate(("gx", "gy", "gz", "ax", "ay", "az")):
            fh.create_dataset(name, data=data[:, k])
    tmp.replace(path)


WRITERS = {".csv": write_csv, ".bag": write_bag, ".h5": write_h5}
#: the corrupt files in turn: suffix, content (a broken CSV row, a bag cut after its header, an
#: .h5 file that is text)
CORRUPT = ((".csv", b"time,gx,gy,gz,ax,ay,az\n0,1,2\nnot a number\n"),
           (".bag", b"#ROSBAG V2.0\nE\x00\x00\x00"), (".h5", b"not an HDF5 file\n"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--units", type=int, default=12, help="static units (besides the others)")
    ap.add_argument("--minutes", type=float, default=5.0, help="length of each recording")
    ap.add_argument("--long-minutes", type=float, default=None,
                    help="length of the aging and moved units' recordings (default --minutes)")
    ap.add_argument("--freq", type=float, default=100.0, help="sampling rate [Hz]")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bags", type=float, default=0.0, help="share of units written as bags")
    ap.add_argument("--h5", type=float, default=0.0, help="share of units written as HDF5")
    ap.add_argument("--odd", type=int, default=1, help="out-of-family units")
    ap.add_argument("--dated", type=int, default=4, help="recordings of the degrading unit")
    ap.add_argument("--corrupt", type=int, default=1, help="unreadable files")
    a = ap.parse_args(argv)
    a.folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    if a.bags < 0 or a.h5 < 0 or a.bags + a.h5 > 1:
        ap.error("--bags and --h5 are shares: each >= 0, together <= 1")
    n = int(a.minutes * 60 * a.freq)
    n_long = int((a.long_minutes or a.minutes) * 60 * a.freq)
    truth: list[dict[str, object]] = []

    def emit(unit: str, date: dt.date, g: float, acc: float, turn: float | None = None,
             suffix: str = ".csv", length: int = n) -> None:
        name = f"{unit}_{date.isoformat()}{suffix}"
        data = signals(length, a.freq, g, acc, rng,
                       None if turn is None else int(turn * length))
        WRITERS[suffix](a.folder / name, data, a.freq)
        truth.append({"file": name, "unit": unit, "date": date.isoformat(),
                      "gyro_noise_density": g, "accel_noise_density": acc,
                      "seconds": length / a.freq})

    for i in range(a.units):
        g = GYRO_ND * math.exp(rng.normal(0, SPREAD))
        acc = ACCEL_ND * math.exp(rng.normal(0, SPREAD))
        # formats spread evenly over the units: unit i's place in [0, 1) picks its format
        place = (i * 0.6180339887) % 1.0
        suffix = ".bag" if place < a.bags else ".h5" if place < a.bags + a.h5 else ".csv"
        emit(f"unit{i:04d}", DAY0, g, acc, suffix=suffix)
    for k in range(a.odd):
        emit(f"odd{k}", DAY0, 3 * GYRO_ND, ACCEL_ND)
    for j in range(a.dated):
        day = DAY0 + dt.timedelta(days=60 * j)
        emit("aging", day, GYRO_ND * 1.4 ** ((day - DAY0).days / 365.25), ACCEL_ND,
             length=n_long)
    emit("moved", DAY0, GYRO_ND, ACCEL_ND, turn=0.4, length=n_long)
    for k in range(a.corrupt):
        suffix, content = CORRUPT[k % len(CORRUPT)]
        (a.folder / f"corrupt{k}_{DAY0.isoformat()}{suffix}").write_bytes(content)
    (a.folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    print(f"wrote {len(truth) + a.corrupt} recordings to {a.folder} (truth.json lists the "
          "true densities)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
