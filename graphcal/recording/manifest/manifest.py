"""The streams manifest: a TOML file naming one CSV per sensor (or a ROS bag's topics).

Every key, with its default (``graphcal import --help-manifest`` prints this)::

    rate = 40.0                      # Hz of the written drive log
    max_gap = 0.5                    # s: a longer gap in any stream masks the log there
    # bag = "drive.bag"              # a ROS 1/2 bag or MCAP file instead of CSV files;
                                     # then a section holds only `topic` and `time_offset`
                                     # ([wheels] also rear_left/rear_right joints and kind)
    [gnss]                           # the pose: GNSS fixes or a fused pose ([pose] works too)
    file = "gnss.csv"                # relative to the manifest
    time = "t"                       # column
    time_unit = "s"                  # s | ms | us | ns
    time_offset = 0.0                # s added to this stream's time (clock offset)
    latitude = "lat"                 # degrees WGS-84 ...
    longitude = "lon"
    # x = "x", y = "y"               # ... or a local metric frame [m] (east, north)
    heading = "heading"              # optional; without it positions only are measured
    heading_unit = "deg"             # deg | rad (required with heading)
    heading_convention = "enu"       # enu: 0 = east, counter-clockwise
                                     # compass: 0 = north, clockwise
    # sideslip = "beta"              # optional, sideslip_unit = "rad" (rad | deg); else 0
    # nmea = "receiver.nmea"         # instead of file and columns: a receiver's NMEA 0183
                                     # log (pip install -e ".[nmea]"): GGA and RMC fixes at
                                     # their UTC times, heading from HDT/THS (never VTG's
                                     # course); keys: nmea, date, heading, time_offset
    # date = "2025-11-23"            # with nmea: UTC date of the first fix, for a log
                                     # without RMC (RMC's dates are used where logged)
    # heading = false                # with nmea: ignore HDT/THS (positions only)
    [wheels]
    file = "wheels.csv"
    time = "t"
    rear_left = "rl"                 # columns (joint names for a bag)
    rear_right = "rr"
    kind = "speed"                   # speed [m/s] | angular_speed [rad/s] | rpm
                                     # | ticks (cumulative) | angle [rad, cumulative]
    circumference = 2.0              # m: what the ECU used to turn rotations into speed
    speed_unit = "m/s"               # m/s | km/h | mph (kind = speed)
    ticks_per_revolution = 96        # kind = ticks
    # ticks_wrap = 65536             # a tick counter that wraps at this count
    # can = "drive.log"              # instead of file, time and columns: a raw CAN log
                                     # (pip install -e ".[can]"): candump -l/-L .log or .log.gz,
                                     # Vector .asc or .blf, python-can .csv; time: the log's
    # dbc = "car.dbc"                # with can: the DBC that decodes it (cantools)
    # message = "WHEEL_SPEEDS"       # with can: the DBC message, by name or frame id (0xAA);
                                     # rear_left/rear_right name its signals, speed_unit and
                                     # ticks_wrap default to the DBC's unit and signal range
    # bus = 0                        # with can: only this bus ("can0" or 0; ASC/BLF: 1, 2)
    [imu]                            # optional
    file = "imu.csv"
    time = "t"
    lateral_acceleration = "ay"      # m/s², positive to the left
    yaw_rate = "wz"                  # positive counter-clockwise
    yaw_rate_unit = "rad/s"          # rad/s | deg/s
    # message = "KINEMATICS"         # signals of a CAN message instead of columns: can and
                                     # dbc as [wheels]' unless given (the wheels' log brings
                                     # its bus and time_offset); yaw_rate_unit defaults to
                                     # the DBC's unit (deg/s | rad/s)
    # ... or a 3-axis IMU in its own frame (instead of lateral_acceleration / yaw_rate):
    # acceleration = ["ax", "ay", "az"]     # specific force, gravity included
    # acceleration_unit = "m/s²"            # m/s² (also "m/s^2") | g
    # angular_velocity = ["wx", "wy", "wz"]
    # angular_velocity_unit = "rad/s"       # rad/s | deg/s
    # mounting = [0.0, 0.0, 90.0]           # required: [roll, pitch, yaw] in degrees, the
                                     # IMU's frame in the vehicle's: v = Rz(yaw)·Ry(pitch)
                                     # ·Rx(roll)·v_imu (URDF rpy), a 3×3 matrix (rows), or
                                     # "estimate" (from gravity and the accelerations)

``time_unit`` and ``time_offset`` exist in every section; ``heading_unit`` and
``heading_convention`` are required with ``heading``. Wheel speeds from an ECU were
computed with the ECU's own circumference: ``circumference`` undoes that, so the wheel stream
is in revolutions and the calibrated c_e is the true effective circumference.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

from graphcal.recording.section import Section
from graphcal.recording.stream_grid import MAX_GAP_S
from graphcal.recording.streams import StreamError

#: Keys each section and the top level may hold (anything else is a one-line error).
TOP_KEYS = ("rate", "max_gap", "bag", "truth", "gnss", "pose", "wheels", "imu")
COMMON_KEYS = ("file", "topic", "time", "time_unit", "time_offset")
POSE_KEYS = (
    *COMMON_KEYS,
    *("latitude", "longitude", "x", "y", "heading", "heading_unit", "heading_convention"),
    *("sideslip", "sideslip_unit"),
    *("nmea", "date"),  # an NMEA log: graphcal.recording.nmea.read
)
WHEEL_KEYS = (
    *COMMON_KEYS,
    *("rear_left", "rear_right", "kind", "circumference", "speed_unit"),
    *("ticks_per_revolution", "ticks_wrap"),
    *("can", "dbc", "message", "bus"),  # a raw CAN log and its DBC: graphcal.recording.can.log
)
IMU_KEYS = (
    *(*COMMON_KEYS, "lateral_acceleration", "yaw_rate", "yaw_rate_unit"),
    *("acceleration", "acceleration_unit", "angular_velocity", "angular_velocity_unit"),
    "mounting",  # a 3-axis IMU in its own frame: graphcal.recording.imu.mounting
    *("can", "dbc", "message", "bus"),  # signals of a CAN message: graphcal.recording.can.log
)


class Manifest:
    """A parsed streams manifest: its sections, checked keys, and where it lives.

    Attributes:
        path: the manifest file; ``source`` its path as messages start.
        rate, max_gap: the top-level keys [Hz], [s].
        bag: the bag it reads instead of CSV files, or ``None``.
        pose_name: ``"gnss"`` or ``"pose"``, the pose section's name.
        pose, wheels: those sections (:class:`~graphcal.recording.section.Section`; empty
            when a bag's topics are found without them); ``imu`` ``None`` if absent.
    """

    def __init__(self, data: dict[str, Any], path: Path) -> None:
        self.path = path
        self.source = str(path)
        self.top = Section("", data, self.source, path.parent)
        unknown = sorted(set(data) - set(TOP_KEYS))
        if unknown:
            raise self.error(f"unknown key(s) {unknown}; known: {list(TOP_KEYS)}")
        if "gnss" in data and "pose" in data:
            raise self.error("both [gnss] and [pose]: name the pose stream once")
        self.data = data
        self.rate = self.top.number("rate", 40.0, positive=True)
        self.max_gap = self.top.number("max_gap", MAX_GAP_S, positive=True)
        bag = data.get("bag")
        if bag is not None and not isinstance(bag, str):
            raise self.error(f"bag must be a path (text), got {bag!r}")
        self.bag = self.resolve(bag) if bag else None
        csv = self.bag is None  # a bag's topics are found when the sections do not name them
        self.pose_name = "pose" if "pose" in data else "gnss"
        self.pose = self._section(self.pose_name, POSE_KEYS, required=csv) or self._empty(
            self.pose_name
        )
        self.wheels = self._section("wheels", WHEEL_KEYS, required=csv) or self._empty("wheels")
        self.imu = self._section("imu", IMU_KEYS, required=False)

    def error(self, what: str) -> StreamError:
        """A one-line :class:`StreamError` about this manifest."""
        return self.top.error(what)

    def resolve(self, name: str) -> Path:
        """A path named in the manifest, relative to the manifest's directory."""
        return self.top.resolve(name)

    def _empty(self, name: str) -> Section:
        return Section(name, {}, self.source, self.path.parent)

    def _section(self, name: str, keys: tuple[str, ...], required: bool) -> Section | None:
        """Section ``name`` with its keys checked, or ``None`` if absent and optional."""
        table = self.data.get(name)
        if table is None:
            if required:
                what = "[gnss] (or [pose])" if name == "gnss" else f"[{name}]"
                raise self.error(f"no {what} section; the manifest must name that stream")
            return None
        if not isinstance(table, dict):
            raise self.error(f"{name} must be a table ([{name}]), got {table!r}")
        unknown = sorted(set(table) - set(keys))
        if unknown:
            raise self.error(f"unknown key(s) {unknown} in [{name}]; known: {list(keys)}")
        return Section(name, table, self.source, self.path.parent)


def load_manifest(path: str | os.PathLike[str]) -> Manifest:
    """Read and check a streams manifest (see the module docstring for every key)."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise StreamError(f"{path}: no such manifest; check the path") from None
    except IsADirectoryError:
        raise StreamError(f"{path}: is a directory, not a manifest or bag") from None
    except OSError as exc:
        raise StreamError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise StreamError(f"{path}: not a valid TOML manifest ({exc})") from exc
    return Manifest(data, path)
