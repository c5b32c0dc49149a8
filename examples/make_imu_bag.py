"""Write a static six-axis IMU recording with known noise as a ROS 1 bag (``sensor_msgs/Imu``).

For trying ``gmwm report`` without a recording of one's own::

    python examples/make_imu_bag.py imu.bag                  # 1 h at 200 Hz, topic /imu/data
    python examples/make_imu_bag.py imu.bag --minutes 10 --seed 2

The noise, in datasheet units (what ``gmwm report`` should recover; ``--truth`` prints it):

* gyroscope (each axis): angular random walk 0.4 deg/sqrt(h) (white noise), a bias instability
  as a first-order Gauss-Markov term (correlation time 100 s, standard deviation 8 deg/h) and a
  rate random walk 5 deg/h/sqrt(h);
* accelerometer (each axis): velocity random walk 0.06 m/s/sqrt(h) (white noise) and an
  acceleration random walk 3 m/s/h/sqrt(h).

The sensor lies level and still: gravity (9.80665 m/s^2) on z and a constant bias per axis are
added, which the wavelet variance does not see. Messages follow REP 103/145 (rad/s and m/s^2,
``orientation_covariance[0] = -1``: no orientation). The bag is written by ``rosbags``' own
writer (``pip install -e ".[recordings]"``); the file is written beside its final name and
renamed when complete.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

import gmwm
from gmwm import units as u

#: the simulated noise, in datasheet units
TRUTH = {
    "gyroscope": {"ARW [deg/sqrt(h)]": 0.4, "GM correlation time [s]": 100.0,
                  "GM sigma [deg/h]": 8.0, "RRW [deg/h/sqrt(h)]": 5.0},
    "accelerometer": {"VRW [m/s/sqrt(h)]": 0.06, "AccRW [m/s/h/sqrt(h)]": 3.0},
}
T0_NS = 1_700_000_000 * 10**9  # first stamp (2023-11-14), an arbitrary wall-clock epoch


def simulate(n: int, freq: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Gyroscope [rad/s] and accelerometer [m/s^2] samples, each of shape (n, 3)."""
    tg, ta = TRUTH["gyroscope"], TRUTH["accelerometer"]
    gyro = gmwm.Model("WN+GM+RW", freq=freq)  # parameters for a signal in deg/s
    theta_g = gyro.theta({
        "WN[1].sigma2": u.wn_from_arw_per_sqrt_hour(tg["ARW [deg/sqrt(h)]"], freq),
        "GM[1].beta": 1.0 / tg["GM correlation time [s]"],
        "GM[1].sigma2": (tg["GM sigma [deg/h]"] / 3600.0) ** 2,
        "RW[1].gamma2": u.rw_from_per_hour_sqrt_hour(tg["RRW [deg/h/sqrt(h)]"], freq)})
    accel = gmwm.Model("WN+RW", freq=freq)  # parameters for a signal in m/s^2
    theta_a = accel.theta({
        "WN[1].sigma2": u.wn_from_arw_per_sqrt_hour(ta["VRW [m/s/sqrt(h)]"], freq),
        "RW[1].gamma2": u.rw_from_per_hour_sqrt_hour(ta["AccRW [m/s/h/sqrt(h)]"], freq)})
    rng = np.random.default_rng(seed)
    g = np.column_stack([gyro.simulate(theta_g, n, rng) for _ in range(3)])
    a = np.column_stack([accel.simulate(theta_a, n, rng) for _ in range(3)])
    g = np.deg2rad(g + np.array([0.05, -0.03, 0.02]))             # constant biases [deg/s]
    a = a + np.array([0.02, -0.01, u.G0 + 0.03])                   # gravity on z, biases
    return g, a


def write_bag(path: Path, g: np.ndarray, a: np.ndarray, freq: float, topic: str,
              frame: str = "imu_link") -> None:
    """Write ``g``/``a`` as ``sensor_msgs/Imu`` messages stamped at ``freq`` to a ROS 1 bag."""
    try:
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import Stores, get_typestore
    except ModuleNotFoundError:
        sys.exit("make_imu_bag.py: writing a bag needs 'rosbags': "
                 "python -m pip install -e \".[recordings]\"")
    ts = get_typestore(Stores.ROS1_NOETIC)
    Imu, Header = ts.types["sensor_msgs/msg/Imu"], ts.types["std_msgs/msg/Header"]
    Time, V3 = ts.types["builtin_interfaces/msg/Time"], ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    no_orientation = np.array([-1.0] + [0.0] * 8)  # REP 145: orientation not estimated
    zeros = np.zeros(9)
    stamps = T0_NS + np.round(np.arange(len(g)) * (1e9 / freq)).astype(np.int64)
    tmp = path.with_name(path.name + ".part")
    tmp.unlink(missing_ok=True)
    with Writer(tmp) as w:
        conn = w.add_connection(topic, Imu.__msgtype__, typestore=ts)
        for i, t in enumerate(stamps.tolist()):
            msg = Imu(Header(seq=i, stamp=Time(sec=t // 10**9, nanosec=t % 10**9),
                             frame_id=frame),
                      Q(0.0, 0.0, 0.0, 1.0), no_orientation, V3(*g[i].tolist()), zeros,
                      V3(*a[i].tolist()), zeros)
            w.write(conn, t, ts.serialize_ros1(msg, Imu.__msgtype__))
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("output", type=Path, help="bag file to write, e.g. imu.bag")
    p.add_argument("--minutes", type=float, default=60.0, help="length (default: 60)")
    p.add_argument("--freq", type=float, default=200.0, help="sampling rate in Hz (default: 200)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    p.add_argument("--topic", default="/imu/data", help="topic (default: /imu/data)")
    p.add_argument("--truth", action="store_true", help="print the simulated noise and exit")
    args = p.parse_args(argv)
    if args.truth:
        for sensor, terms in TRUTH.items():
            print(sensor + ": " + ", ".join(f"{k} {v:g}" for k, v in terms.items()))
        return
    if args.minutes <= 0 or args.freq <= 0:
        p.error("--minutes and --freq must be positive")
    n = round(args.minutes * 60 * args.freq)
    g, a = simulate(n, args.freq, args.seed)
    write_bag(args.output, g, a, args.freq, args.topic)
    print(f"wrote {args.output}: {n} sensor_msgs/Imu messages on {args.topic}, "
          f"{args.minutes:g} min at {args.freq:g} Hz")


if __name__ == "__main__":
    main()
