"""The IMU's frame and the vehicle's: the mounting rotation, and its checks against gravity
and the turns.

**Convention.** ``mounting = [roll, pitch, yaw]`` [deg] is the rotation of the IMU's frame
in the vehicle frame (REP 103: x forward, y left, z up), intrinsic z-y'-x'' (yaw about the
vehicle's z, then pitch about the new y, then roll about the newest x)::

    v_vehicle = R · v_imu,   R = Rz(yaw) · Ry(pitch) · Rx(roll)

the same as a URDF joint's ``rpy`` of the IMU link in ``base_link`` and tf2's
``Quaternion.setRPY``. The columns of ``R`` are the IMU's axes in vehicle coordinates: an
IMU whose x axis points to the vehicle's left has yaw = 90°. A 3×3 matrix (rows of ``R``)
may be given instead of the angles.
"""

from __future__ import annotations

import numpy as np

from graphcal.recording.stream_grid import interval_means
from graphcal.recording.streams import StreamError
from graphcal.recording.vocabulary import GRAVITY

#: Bin [s] over which the streams are averaged for the estimate.
ESTIMATE_BIN_S = 0.5
#: Accepted ratio of the IMU's mean specific force's magnitude to gravity.
GRAVITY_RANGE = (0.8, 1.2)
#: Largest angle [deg] of the rotated mean specific force from the vehicle's up, and of the
#: rotated gyro's turn axis from the vehicle's z.
MAX_TILT_DEG = 10.0
#: Yaw rate [rad/s] of a bin that counts as turning, and the time [s] of such bins the gyro's
#: axis check needs.
TURNING_MIN = 0.1
TURNING_MIN_S = 10.0


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R = Rz(yaw) · Ry(pitch) · Rx(roll)`` ``(3, 3)`` of angles [rad]: vehicle = R · IMU."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (np.cos, np.sin))
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def angles(matrix: np.ndarray) -> np.ndarray:
    """``(roll, pitch, yaw)`` [rad] of a rotation ``R = Rz(yaw) · Ry(pitch) · Rx(roll)``."""
    m = np.asarray(matrix, dtype=float)
    return np.array(
        [
            np.arctan2(m[2, 1], m[2, 2]),
            -np.arcsin(np.clip(m[2, 0], -1.0, 1.0)),
            np.arctan2(m[1, 0], m[0, 0]),
        ]
    )


def to_vehicle(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Vectors ``(N, 3)`` in the IMU's frame, in the vehicle frame: each row ``R · v``."""
    return np.asarray(vectors, dtype=float) @ np.asarray(matrix, dtype=float).T


def to_sensor(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Vectors ``(N, 3)`` in the vehicle frame, in the IMU's frame: each row ``Rᵀ · v``."""
    return np.asarray(vectors, dtype=float) @ np.asarray(matrix, dtype=float)


def degrees_text(matrix: np.ndarray) -> str:
    """``[5.0, 0.0, 90.0]``: a rotation's roll, pitch, yaw [deg] as the manifest writes them."""
    return "[" + ", ".join(f"{round(a, 2) + 0.0:g}" for a in np.degrees(angles(matrix))) + "]"


def tilt(vector: np.ndarray) -> float:
    """Angle [rad] of ``vector`` from the vehicle's z (up)."""
    return float(np.arccos(np.clip(vector[2] / np.linalg.norm(vector), -1.0, 1.0)))


def bin_means(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` ``(N, 3)`` at times ``t`` [s] averaged over :data:`ESTIMATE_BIN_S` bins,
    ``(M, 3)``: a turn lasts seconds, a bump's pitch and roll a fraction of a bin."""
    edges = np.arange(t[0], t[-1], ESTIMATE_BIN_S)
    if len(edges) < 2:
        return np.empty((0, 3))
    return np.column_stack([interval_means(t, values[:, i], edges) for i in range(3)])[:-1]


def turn_axis(rates: np.ndarray) -> np.ndarray | None:
    """The main axis of ``rates`` ``(N, 3)`` [rad/s], one row per :data:`ESTIMATE_BIN_S` bin
    (the eigenvector of their second moment with the largest eigenvalue, pointing up), or
    ``None`` if they turn too little."""
    turning = np.linalg.norm(rates, axis=1) > TURNING_MIN
    if turning.sum() * ESTIMATE_BIN_S < TURNING_MIN_S:
        return None
    _, vectors = np.linalg.eigh(rates[turning].T @ rates[turning])
    axis = vectors[:, -1]
    return axis if axis[2] >= 0 else -axis


def check_gravity(force: np.ndarray, where: str, unit: str) -> np.ndarray:
    """The mean specific force [m/s²] ``(3,)``; one line if its magnitude is not gravity's."""
    mean = force.mean(axis=0)
    ratio = float(np.linalg.norm(mean)) / GRAVITY
    if not GRAVITY_RANGE[0] <= ratio <= GRAVITY_RANGE[1]:
        hint = (
            'it is apparently in g: set [imu] acceleration_unit = "g"'
            if abs(ratio * GRAVITY - 1.0) < 0.2
            else "check [imu] acceleration (the accelerometer's three columns, gravity included)"
        )
        raise StreamError(
            f"{where}: the IMU's mean specific force is {ratio * GRAVITY:.3g} m/s² as declared "
            f"({unit}), not gravity's {GRAVITY:.2f}; {hint}"
        )
    return mean


def check_mounting(
    matrix: np.ndarray,
    force: np.ndarray | None,
    rates: np.ndarray | None,
    where: str,
    unit: str = 'acceleration_unit = "m/s²"',
) -> None:
    """One line if a given mounting does not put the IMU's gravity up or its turns about the
    vehicle's z (each within :data:`MAX_TILT_DEG`): a wrong mounting, or columns in another
    order or frame; ``where`` prefixes it (``"manifest.toml: [imu] mounting = [5, 0, 90]"``).
    ``rates`` are :func:`bin_means` of the gyro: judged sample by sample, a highway's bumps
    (pitch rates of 0.3 rad/s for a tenth of a second) looked like turns about the y axis."""
    fix = 'check the angles and their order, or set mounting = "estimate"'
    if force is not None:
        up = to_vehicle(matrix, check_gravity(force, where, unit)[None])[0]
        if tilt(up) > np.radians(MAX_TILT_DEG):
            raise StreamError(
                f"{where} puts the IMU's gravity (its mean specific "
                f"force) {np.degrees(tilt(up)):.0f}° from the vehicle's up (it must be within "
                f"{MAX_TILT_DEG:g}°); {fix}"
            )
    if rates is not None:
        axis = turn_axis(to_vehicle(matrix, rates))
        if axis is not None and tilt(axis) > np.radians(MAX_TILT_DEG):
            raise StreamError(
                f"{where} puts the gyro's turn axis {np.degrees(tilt(axis)):.0f}° from the "
                f"vehicle's z (it must be within {MAX_TILT_DEG:g}°); check that "
                "angular_velocity names the x, y, z columns of the accelerometer's frame, in "
                f"that order, and {fix.removeprefix('check ')}"
            )
