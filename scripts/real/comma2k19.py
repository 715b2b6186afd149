"""A real car in the forms its owner has: comma2k19's Example_1 (a Toyota RAV4, one minute
on California's highway 280) turned into graphcal's inputs, written to
``data/real/comma2k19/``.

    python scripts/real/comma2k19.py SEGMENT_DIR DBC --out data/real/comma2k19

``SEGMENT_DIR`` is ``Example_1/b0c9d2329ad1606b|2018-08-02--08-34-47/40`` of
https://github.com/commaai/comma2k19 (MIT, © 2018 comma.ai): its ``processed_log`` numpy
arrays and ``global_pose``. ``DBC`` is ``opendbc/dbc/generator/toyota/_toyota_2017.dbc`` of
https://github.com/commaai/opendbc (MIT, © 2020 comma.ai), which decodes this car's
``WHEEL_SPEEDS`` (0xAA) as comma's own processing did.

Written (all times on the recording's own boot clock, seconds):

* ``wheels.csv`` — CAN wheel speeds of the four wheels [m/s] at 83 Hz, as the ECU reports
  them (``processed_log/CAN/wheel_speed``); the manifests undo a reference circumference of
  2 m, the nominal c_e of graphcal's default car, so c_e comes out as 2 m × the ECU's scale
  error.
* ``gnss.csv`` — the u-blox receiver's fixes (latitude, longitude [deg]) at 10 Hz, timed when
  they were logged (``t``; the receiver's UTC epoch is kept in ``utc_ms``); no heading.
* ``imu.csv`` — the device's accelerometer [m/s²] and gyro [rad/s] at 100 Hz in its own frame
  (forward, right, down: ``mounting = [180, 0, 0]`` turns that into x forward, y left, z up).
* ``pose.csv`` — the fused pose (comma's INS/GNSS/vision optimizer) at 20 Hz: the camera's
  position in east/north metres around its first sample and the car's heading [rad, ENU]
  (the camera's, less its yaw mounting: :func:`fused_pose`).
* ``bus.log.gz`` — the raw CAN log of the whole bus (all 135,468 frames, the panda's sources
  as ``can0``, ``can1``, ``can128``, ``can129``) in candump ``-L`` format;
  ``toyota_2017.dbc`` — the DBC.
* manifests: ``fused.toml`` (pose + wheel speeds), ``gnss.toml`` (u-blox + wheel speeds),
  ``gnss_imu.toml`` (+ the IMU), ``can.toml`` (u-blox + the raw CAN log and the DBC);
* ``drive.csv`` + ``drive.json`` — ``fused.toml`` imported (``graphcal import``): the fused
  pose as a drive-log CSV.
* ``README.md``, ``LICENSE-comma2k19``, ``LICENSE-opendbc`` — attribution.
"""

from __future__ import annotations

import argparse
import gzip
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pymap3d

#: The wheel speeds' reference circumference [m]: the nominal c_e of the default car.
REFERENCE_CIRCUMFERENCE = 2.0

WHEELS = """[wheels]
file = "wheels.csv"
time = "t"
rear_left = "rl"
rear_right = "rr"
kind = "speed"
speed_unit = "m/s"
circumference = {circumference}
"""

GNSS = """[gnss]
file = "gnss.csv"
time = "t"
latitude = "lat"
longitude = "lon"
"""

POSE = """[pose]
file = "pose.csv"
time = "t"
x = "x"
y = "y"
heading = "heading"
heading_unit = "rad"
heading_convention = "enu"
"""

IMU = """[imu]
file = "imu.csv"
time = "t"
acceleration = ["ax", "ay", "az"]
angular_velocity = ["wx", "wy", "wz"]
mounting = [180.0, 0.0, 0.0]  # the device's forward, right, down -> x forward, y left, z up
"""

CAN = """[wheels]
can = "bus.log.gz"
dbc = "toyota_2017.dbc"
message = "WHEEL_SPEEDS"
rear_left = "WHEEL_SPEED_RL"
rear_right = "WHEEL_SPEED_RR"
kind = "speed"
circumference = {circumference}
bus = 0
"""

HEADER = (
    "# comma2k19 Example_1 (MIT, (c) 2018 comma.ai): {what}. Made by scripts/real/comma2k19.py\n"
)


def load(segment: Path, name: str) -> np.ndarray:
    """One of the segment's numpy arrays (stored without the .npy suffix)."""
    with open(segment / name, "rb") as f:
        return np.load(f)


def wheel_speeds(segment: Path) -> pd.DataFrame:
    """The four wheel speeds [m/s] with their times."""
    t = load(segment, "processed_log/CAN/wheel_speed/t")
    v = load(segment, "processed_log/CAN/wheel_speed/value")
    return pd.DataFrame({"t": t, "fl": v[:, 0], "fr": v[:, 1], "rl": v[:, 2], "rr": v[:, 3]})


def ublox_fixes(segment: Path) -> pd.DataFrame:
    """The u-blox fixes: latitude, longitude [deg], logged time and the receiver's UTC epoch."""
    t = load(segment, "processed_log/GNSS/live_gnss_ublox/t")
    v = load(segment, "processed_log/GNSS/live_gnss_ublox/value")
    return pd.DataFrame(
        {"t": t, "lat": v[:, 0], "lon": v[:, 1], "utc_ms": v[:, 3].astype(np.int64)}
    )


def imu(segment: Path) -> pd.DataFrame:
    """Accelerometer and gyro in the device frame (forward, right, down), one time base."""
    t = load(segment, "processed_log/IMU/accelerometer/t")
    a = load(segment, "processed_log/IMU/accelerometer/value")
    tg = load(segment, "processed_log/IMU/gyro/t")
    w = load(segment, "processed_log/IMU/gyro/value")
    if not np.array_equal(t, tg):
        raise SystemExit("accelerometer and gyro times differ: not handled")
    names = ["ax", "ay", "az", "wx", "wy", "wz"]
    return pd.DataFrame({"t": t, **dict(zip(names, np.column_stack([a, w]).T, strict=True))})


def _rotation(q: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` rotation matrices of Hamilton quaternions ``(N, 4)`` [w, x, y, z]."""
    w, x, y, z = q.T
    return np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)


def fused_pose(segment: Path) -> tuple[pd.DataFrame, float]:
    """The car's fused pose: the camera's position in east/north [m] around its first sample,
    and the car's heading [rad, ENU]: the camera's forward axis turned by its yaw mounting,
    which is returned [rad]. The mounting is the mean angle from the camera's forward axis to
    the pose's own velocity (the direction of travel, about 0.9° here: the camera looks a
    little off the car's axis), as openpilot calibrates it; the owner knows it, and a
    drive-log CSV holds the vehicle's heading."""
    t = load(segment, "global_pose/frame_times")
    ecef = load(segment, "global_pose/frame_positions")
    quaternion = load(segment, "global_pose/frame_orientations")
    velocity = load(segment, "global_pose/frame_velocities")
    lat0, lon0, h0 = pymap3d.ecef2geodetic(*ecef[0])
    east, north, _ = pymap3d.ecef2enu(*ecef.T, lat0, lon0, h0)
    forward = _rotation(quaternion)[:, :, 0]
    fe, fn, _ = pymap3d.ecef2enuv(*forward.T, lat0, lon0)
    ve, vn, _ = pymap3d.ecef2enuv(*velocity.T, lat0, lon0)
    camera = np.unwrap(np.arctan2(fn, fe))
    mounting = float(np.mean(np.angle(np.exp(1j * (camera - np.arctan2(vn, ve))))))
    heading = camera - mounting
    return pd.DataFrame({"t": t, "x": east, "y": north, "heading": heading}), mounting


def candump(segment: Path, path: Path) -> int:
    """The raw CAN frames as a gzipped candump ``-L`` log; returns the number of frames."""
    t = load(segment, "processed_log/CAN/raw_can/t")
    address = load(segment, "processed_log/CAN/raw_can/address")
    data = load(segment, "processed_log/CAN/raw_can/data")
    source = load(segment, "processed_log/CAN/raw_can/src")
    order = np.argsort(t, kind="stable")
    lines = []
    for i in order:
        ident = f"{address[i]:03X}" if address[i] < 0x800 else f"{address[i]:08X}"
        lines.append(f"({t[i]:.6f}) can{source[i]} {ident}#{data[i].hex().upper()}\n")
    with gzip.GzipFile(path, "wb", mtime=0) as f:  # mtime 0: the same bytes every run
        f.write("".join(lines).encode())
    return len(lines)


def write_csv(frame: pd.DataFrame, path: Path) -> None:
    """``frame`` as CSV, no index, 9 significant digits (CSV takes no comment line: the
    attribution is in README.md)."""
    frame.to_csv(path, index=False, float_format="%.9g")


def manifest(path: Path, what: str, *sections: str) -> None:
    """A manifest of ``sections`` with an attribution line."""
    path.write_text(HEADER.format(what=what) + "\n".join(sections))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("segment", type=Path, help="comma2k19 Example_1 segment directory")
    parser.add_argument("dbc", type=Path, help="opendbc's _toyota_2017.dbc")
    parser.add_argument("--out", type=Path, default=Path("data/real/comma2k19"))
    parser.add_argument("--comma-license", type=Path, help="comma2k19's LICENSE")
    parser.add_argument("--opendbc-license", type=Path, help="opendbc's LICENSE")
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    segment = args.segment

    write_csv(wheel_speeds(segment), out / "wheels.csv")
    write_csv(ublox_fixes(segment), out / "gnss.csv")
    write_csv(imu(segment), out / "imu.csv")
    pose, mounting = fused_pose(segment)
    write_csv(pose, out / "pose.csv")
    frames = candump(segment, out / "bus.log.gz")
    shutil.copyfile(args.dbc, out / "toyota_2017.dbc")
    wheels = WHEELS.format(circumference=REFERENCE_CIRCUMFERENCE)
    manifest(out / "fused.toml", "fused pose + CAN wheel speeds", POSE, wheels)
    manifest(out / "gnss.toml", "u-blox fixes + CAN wheel speeds", GNSS, wheels)
    manifest(out / "gnss_imu.toml", "u-blox fixes + CAN wheel speeds + IMU", GNSS, wheels, IMU)
    can = CAN.format(circumference=REFERENCE_CIRCUMFERENCE)
    manifest(out / "can.toml", "u-blox fixes + the raw CAN log and its DBC", GNSS, can)
    for given, name in (
        (args.comma_license, "LICENSE-comma2k19"),
        (args.opendbc_license, "LICENSE-opendbc"),
    ):
        if given is not None:
            shutil.copyfile(given, out / name)
    for old in ("drive.csv", "drive.json"):
        (out / old).unlink(missing_ok=True)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "graphcal.cli",
            "import",
            str(out / "fused.toml"),
            "--out",
            str(out / "drive.csv"),
        ],
        check=True,
    )
    print(
        f"{out}: {frames} CAN frames; camera yaw mounting {np.degrees(mounting):+.3f}° taken out "
        "of the fused heading; drive.csv imported from fused.toml"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
