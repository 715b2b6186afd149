"""Where each drive-log column of an import came from (:func:`column_origins`): the user's
file, column, manifest key and line behind a grid row, and the key to change."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graphcal.log.checks import ColumnOrigin
from graphcal.recording.import_keys import is_flag, key_name, stream_advice
from graphcal.recording.imu.mounting import mounted_fix
from graphcal.recording.resampling import Resampled
from graphcal.recording.stream_grid import FIX_TIME_TOLERANCE
from graphcal.recording.streams import Provenance, Recording, provenance_of


def sample_before(t: np.ndarray, time: float) -> int:
    """The last sample of a stream at or before ``time`` (the first if none is)."""
    return max(int(np.searchsorted(t, time + FIX_TIME_TOLERANCE, side="right")) - 1, 0)


def sample_within(t: np.ndarray, lo: float, hi: float, values: np.ndarray | None) -> int:
    """The sample of a stream in ``[lo, hi]`` or next to it with the largest ``|values|``
    (the first one if ``values`` is None), else the last one before ``lo``."""
    # with the samples just outside: the trapezoid rule spreads each over its neighbours'
    a = max(int(np.searchsorted(t, lo - FIX_TIME_TOLERANCE, side="left")) - 1, 0)
    b = int(np.searchsorted(t, hi + FIX_TIME_TOLERANCE, side="right")) + 1
    if b <= a:
        return sample_before(t, lo)
    if values is None:
        return a
    return a + int(np.argmax(np.abs(values[a:b])))


Locator = Callable[[int | None], str]


@dataclass(frozen=True)
class _Grid:
    """The drive log's rows in the streams' time base, to find the sample behind a row."""

    t: np.ndarray

    def at_fix(self, provenance: Provenance, quantities: tuple[str, ...], stream) -> Locator:
        """Where a row's value came from: the stream's last sample at or before the row."""

        def where(row: int | None) -> str:
            k = None if row is None else sample_before(stream.t, self.t[row])
            return provenance.at(quantities, k)

        return where

    def within(
        self, provenance: Provenance, quantities: tuple[str, ...], stream, values=None
    ) -> Locator:
        """Where a row's value came from: the stream's sample within the row's interval with
        the largest ``|values|`` (:func:`sample_within`)."""
        last = len(self.t) - 1

        def where(row: int | None) -> str:
            if row is None:
                return provenance.at(quantities)
            k = sample_within(stream.t, self.t[row], self.t[min(row + 1, last)], values)
            return provenance.at(quantities, k)

        return where


def _joined(first: Locator, second: Locator) -> Locator:
    return lambda row: f"{first(row)}, times the speed of {second(row)}"


def column_origins(resampled: Resampled, recording: Recording) -> dict[str, ColumnOrigin]:
    """Where each drive-log column of an import came from (:class:`ColumnOrigin`), so that
    the drive log's checks name the user's file, column, manifest key and line, and the key
    to change; a derived column (``ay`` from speed × yaw rate) names every stream behind it."""
    grid = _Grid(resampled.columns["t"] + resampled.overlap[0])
    pose, wheels = recording.pose, recording.wheels
    at_pose, at_wheels = provenance_of(pose), provenance_of(wheels)
    position = ("latitude", "longitude") if pose.origin is not None else ("x", "y")
    position_fix = _position_fix(pose, at_pose, position)
    wheel_fix = _wheel_fix(at_wheels)
    origins = {
        "px": ColumnOrigin("position", grid.at_fix(at_pose, position, pose), position_fix),
        "py": ColumnOrigin("position", grid.at_fix(at_pose, position, pose), position_fix),
    }
    for column, side, signal in (
        ("n_rl", "rear_left", wheels.left),
        ("n_rr", "rear_right", wheels.right),
    ):
        values = None if wheels.cumulative else signal
        origins[column] = ColumnOrigin(
            f"{side.replace('_', '-')} wheel speed",
            grid.within(at_wheels, (side,), wheels, values),
            wheel_fix,
        )
    if pose.heading is not None:
        origins["psi"] = ColumnOrigin(
            "heading", grid.at_fix(at_pose, ("heading",), pose), _heading_fix(at_pose)
        )
    else:
        origins["psi"] = ColumnOrigin(
            "course of the GNSS track (no heading logged)",
            lambda row: (
                f"{at_pose.at(position)} against {at_wheels.at(('rear_left', 'rear_right'))}"
            ),
            f"{position_fix}; {wheel_fix}",
        )
    if pose.sideslip is not None:
        field = at_pose.fields.get("sideslip")
        fix = (
            f"check {field.section} sideslip_unit (rad | deg)"
            if field is not None and field.declares("sideslip_unit")
            else "check the Odometry twist (body frame, REP 103)"
        )
        origins["beta"] = ColumnOrigin("sideslip", grid.at_fix(at_pose, ("sideslip",), pose), fix)
    origins["ay"] = _lateral_acceleration(grid, recording, wheel_fix)
    return origins


def _position_fix(pose, at_pose: Provenance, position: tuple[str, ...]) -> str:
    """What to check when the positions are wrong."""
    section = next((f.section for f in at_pose.fields.values() if f.section), "[gnss]")
    return stream_advice(
        at_pose,
        "position",
        f"check {section} {' and '.join(position)}"
        + (" (degrees WGS-84)" if pose.origin is not None else " (metres, east and north)")
        if at_pose.unit == "line"
        else "check the pose topic (--pose-topic)",
    )


def _heading_fix(at_pose: Provenance) -> str:
    """What to check when the heading is wrong."""
    heading_field = at_pose.fields.get("heading")
    return stream_advice(
        at_pose,
        "heading",
        f"check {key_name(heading_field, 'heading_unit')} (deg | rad) and "
        f"{key_name(heading_field, 'heading_convention')} "
        "(enu | compass)"
        if heading_field is not None and heading_field.declares("heading_unit")
        else "check the pose's orientation (ENU, REP 103)",
    )


def _wheel_fix(at_wheels: Provenance) -> str:
    """What to check when the wheel speeds are wrong: manifest keys, or the bag's flags."""
    return (
        "check [wheels] kind, speed_unit, circumference (the ECU's) or ticks_per_revolution, "
        "and the vehicle's c_e (--vehicle)"
        if at_wheels.unit == "line"
        else "check --wheel-kind, --speed-unit, --circumference or --ticks-per-revolution and "
        "the vehicle's c_e (--vehicle)"
        if is_flag(at_wheels.fields.get("rear_left"))
        else "check --wheel-kind (angle or angular_speed) and the vehicle's c_e (--vehicle)"
    )


def _lateral_acceleration(grid: _Grid, recording: Recording, wheel_fix: str) -> ColumnOrigin:
    """Where ``ay`` came from: the IMU's lateral acceleration, else speed × its yaw rate, else
    the wheel speed × the heading's rate of turn, else the two wheels' speeds."""
    pose, wheels, imu = recording.pose, recording.wheels, recording.imu
    at_pose, at_wheels = provenance_of(pose), provenance_of(wheels)
    speeds = None if wheels.cumulative else np.abs(wheels.left) + np.abs(wheels.right)
    wheel_speed = grid.within(at_wheels, ("rear_left", "rear_right"), wheels, speeds)
    if imu is not None and imu.lateral_acceleration is not None:
        at_imu = provenance_of(imu)
        fix = (
            "it must be in m/s², positive to the left (a column in g: multiply it by 9.81); "
            "drop or fill a lone spike's line"
            if at_imu.unit == "line"
            else "linear_acceleration.y must be in m/s² (REP 103)"
        )
        mounted = mounted_fix(at_imu.fields.get("lateral_acceleration"))
        fix = f"{mounted}; drop or fill a lone spike's line" if mounted else fix
        where = grid.within(at_imu, ("lateral_acceleration",), imu, imu.lateral_acceleration)
        return ColumnOrigin("lateral acceleration", where, fix)
    if imu is not None and imu.yaw_rate is not None:
        at_imu = provenance_of(imu)
        field = at_imu.fields.get("yaw_rate")
        fix = (
            f"check {key_name(field, 'yaw_rate_unit')} (rad/s | deg/s)"
            if field is not None and field.declares("yaw_rate_unit")
            else mounted_fix(field) or "angular_velocity.z must be in rad/s (REP 103)"
        )
        return ColumnOrigin(
            "lateral acceleration (speed × yaw rate, none logged)",
            _joined(grid.within(at_imu, ("yaw_rate",), imu, imu.yaw_rate), wheel_speed),
            f"{fix}; {wheel_fix}",
        )
    if pose.heading is not None:
        return ColumnOrigin(
            "lateral acceleration (the wheel speed × the heading's rate of turn; none is logged)",
            _joined(grid.at_fix(at_pose, ("heading",), pose), wheel_speed),
            f"{_heading_fix(at_pose)}; {wheel_fix}",
        )
    return ColumnOrigin(
        "lateral acceleration (from the two wheels' speeds, none logged)",
        wheel_speed,
        wheel_fix,
    )
