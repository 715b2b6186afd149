"""A mounted IMU's mounting estimated from the drive (``[imu] mounting = "estimate"``).

**Estimation** (``mounting = "estimate"``) solves one least-squares rotation (Wahba's
problem, by SVD) between the IMU's specific force and the vehicle's, in 0.5 s bins over the
whole drive. The vehicle's specific force is ``(dv/dt, v · ω_z, g)``: the longitudinal
acceleration is the derivative of the wheel speed (metres per revolution from the GNSS
track), the lateral one is the speed times the IMU's own yaw rate (the gyro's component
along the vertical, which the yaw of the mounting does not change), and gravity is up.

* Roll and pitch come from gravity, which dominates the sum: no standstill is needed (a
  car standing on a 3 % slope would tilt a standstill's estimate by 1.7°; over a drive the
  slopes average out), and the horizontal accelerations, known, do not bias it.
* Yaw comes from the horizontal accelerations: the longitudinal ones (starting, braking)
  and the lateral ones (turns), the latter known as zero on a straight. The yaw rate cannot
  give it: a rotation about the vertical leaves the yaw rate as it is (the gyro's turn axis
  is instead checked against the accelerometer's vertical: the two must be one frame).
* An IMU ``x`` ahead of the rear axle (the point that moves along the heading) feels the
  turn's centripetal acceleration ``-x ω_z²`` along the car: ``x`` is fitted with the
  rotation (least squares on the longitudinal residual, each round; within
  :data:`MAX_IMU_AHEAD`), or turns would read as a yaw (1.4° on a 4 km city drive with the
  IMU 1.35 m ahead).
* Bins where the yaw rate changes (turn entries and exits, :data:`STEADY_YAW_ACCELERATION`)
  are left out: there speed × yaw rate is not the lateral acceleration (the sideslip's rate,
  the IMU's lever arm ahead of the rear axle), and as drivers brake into turns and
  accelerate out of them, keeping them biased the yaw by 0.3–0.9° on 4 km drives (0.05°
  without them).
* The IMU's bins are smoothed as the speed's central difference is (1/4, 1/2, 1/4), so that
  an abrupt start or stop is the same in both.
* It is refused (one line naming ``[imu] mounting``) when the drive has less than
  :data:`EXCITATION_MIN_S` of horizontal acceleration above :data:`EXCITATION_MIN`, or when
  the angles' σ from the residuals exceeds :data:`MAX_SIGMA_DEG`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.recording.imu.frame import (
    ESTIMATE_BIN_S,
    MAX_TILT_DEG,
    angles,
    check_gravity,
    degrees_text,
    tilt,
    to_vehicle,
    turn_axis,
)
from graphcal.recording.stream_grid import interval_means, stream_gaps, wheel_rotations
from graphcal.recording.streams import (
    PoseStream,
    StreamError,
    WheelStream,
)
from graphcal.recording.vocabulary import GRAVITY

#: Horizontal acceleration [m/s²] of a bin that counts as excitation of the yaw, and the
#: time [s] of such bins the estimate needs.
EXCITATION_MIN = 0.5
EXCITATION_MIN_S = 20.0
#: Largest distance [m] of the IMU ahead of (or behind) the rear axle that is fitted.
MAX_IMU_AHEAD = 5.0
#: Largest σ [deg] of an estimated angle that is accepted.
MAX_SIGMA_DEG = 0.5
#: Yaw acceleration [rad/s²] below which a bin (and its neighbours) is steady: where the yaw
#: rate changes, speed × yaw rate is not the lateral acceleration (the sideslip's rate, the
#: IMU's lever arm from the rear axle), and the estimate leaves the bin out.
STEADY_YAW_ACCELERATION = 0.05
#: Residuals of bins closer than this [s] are counted as correlated in the σ.
CORRELATION_S = 2.0
#: Span [s] of the chords that scale the wheels to metres for the estimate.
SCALE_STEP_S = 2.0
#: What a refused estimate tells the user to do instead.
HOW = "set mounting = [roll, pitch, yaw] (degrees) measured on the vehicle"


@dataclass(frozen=True)
class MountingEstimate:
    """The IMU's mounting found from a drive.

    Attributes:
        rotation: ``R`` ``(3, 3)``, vehicle = R · IMU.
        sigma: σ [rad] of roll, pitch and yaw, from the residuals.
        excitation_s: time [s] of horizontal acceleration above :data:`EXCITATION_MIN`.
        axis_tilt: angle [rad] of the rotated gyro's turn axis from the vehicle's z, or
            ``None`` if the drive turns too little to tell.
    """

    rotation: np.ndarray
    sigma: np.ndarray
    excitation_s: float
    axis_tilt: float | None

    @property
    def angles(self) -> np.ndarray:
        """``(roll, pitch, yaw)`` [rad]."""
        return angles(self.rotation)

    def note(self, key: str = "[imu] mounting") -> str:
        """What the import says about the estimate."""
        roll, pitch, yaw = np.degrees(self.angles)
        sigma = np.degrees(self.sigma)
        axis = (
            ""
            if self.axis_tilt is None
            else f"; the gyro's turn axis is {np.degrees(self.axis_tilt):.1f}° from vertical"
        )
        return (
            f'{key} = "estimate": roll {roll:+.2f}° ± {sigma[0]:.2f}, pitch {pitch:+.2f}° ± '
            f"{sigma[1]:.2f}, yaw {yaw:+.2f}° ± {sigma[2]:.2f} (roll and pitch from gravity, yaw "
            f"from {self.excitation_s:.0f} s of acceleration, braking and steady turning{axis}); "
            "to keep it, "
            f"set mounting = {degrees_text(self.rotation)}"
        )


def _metres_per_revolution(pose: PoseStream, wheels: WheelStream) -> float | None:
    """The wheels' distance scale [m/rev]: the GNSS track's chords over the wheels'
    revolutions, in :data:`SCALE_STEP_S` steps where the vehicle clearly moves and neither
    stream has a gap (a chord across a GNSS outage is the straight line between its ends,
    not the path: a town car's 50 s outage scaled its wheels to 0.8 of their travel, its
    accelerations read 1.25 times the wheels', and the mounting "only to ±1.2°")."""
    lo, hi = max(pose.t[0], wheels.t[0]), min(pose.t[-1], wheels.t[-1])
    edges = np.arange(lo, hi, SCALE_STEP_S)
    if len(edges) < 3:
        return None
    chords = np.hypot(
        np.diff(np.interp(edges, pose.t, pose.x)), np.diff(np.interp(edges, pose.t, pose.y))
    )
    left, right = wheel_rotations(wheels, edges)
    revolutions = np.abs(0.5 * (left + right))[:-1]
    gaps = np.array([*stream_gaps(pose.t), *stream_gaps(wheels.t)]).reshape(-1, 2)
    across = ((edges[:-1, None] < gaps[:, 1]) & (edges[1:, None] > gaps[:, 0])).any(axis=1)
    chords, revolutions = chords[~across], revolutions[~across]
    if len(chords) < 2:
        return None
    moving = chords > 0.2 * np.percentile(chords, 95)
    if not moving.any() or revolutions[moving].sum() <= 0:
        return None
    return float(chords[moving].sum() / revolutions[moving].sum())


def estimate_mounting(
    t: np.ndarray,
    force: np.ndarray,
    rates: np.ndarray,
    pose: PoseStream,
    wheels: WheelStream,
    where: str = "[imu] mounting",
) -> MountingEstimate:
    """The IMU's mounting from a drive (module docstring): the rotation ``R`` (vehicle =
    R · IMU) that best maps the IMU's specific force onto the vehicle's ``(dv/dt, v · ω_z,
    g)`` in 0.5 s bins, by SVD.

    Args:
        t: the IMU's time [s], ``(N,)``.
        force: specific force [m/s²] in the IMU's frame (gravity included), ``(N, 3)``.
        rates: angular velocity [rad/s] in the IMU's frame, ``(N, 3)``.
        pose: the GNSS track (scales the wheels to metres).
        wheels: the rear wheels (the vehicle's speed).
        where: prefix of the one-line errors (the manifest and key).

    Raises:
        StreamError: the data cannot determine the mounting (too short an overlap with the
            wheels, too little acceleration and turning, a σ above :data:`MAX_SIGMA_DEG`, a
            mean specific force that is not gravity, or a gyro not in the accelerometer's
            frame).
    """
    f, w, speed, longitudinal = _bins(t, force, rates, pose, wheels, where)
    matrix, reference, measured = _wahba(f, w, speed, longitudinal, where)
    horizontal = np.hypot(reference[:, 0], reference[:, 1])
    excitation = float((horizontal > EXCITATION_MIN).sum() * ESTIMATE_BIN_S)
    if excitation < EXCITATION_MIN_S:
        raise StreamError(
            f'{where} = "estimate": the drive has {excitation:.0f} s of acceleration, braking or '
            f"steady turning above {EXCITATION_MIN:g} m/s² (the yaw needs {EXCITATION_MIN_S:g} "
            f"s); {HOW}"
        )
    sigma = _sigma(matrix, reference, measured, horizontal, where)
    axis = turn_axis(to_vehicle(matrix, w))
    axis_tilt = None if axis is None else tilt(axis)
    if axis_tilt is not None and axis_tilt > np.radians(MAX_TILT_DEG):
        raise StreamError(
            f'{where} = "estimate": the gyro turns about an axis {np.degrees(axis_tilt):.0f}° '
            "from the vertical the accelerometer's gravity gives; acceleration and "
            "angular_velocity must name the x, y, z columns of one frame, in that order"
        )
    return MountingEstimate(matrix, sigma, excitation, axis_tilt)


def _bins(
    t: np.ndarray,
    force: np.ndarray,
    rates: np.ndarray,
    pose: PoseStream,
    wheels: WheelStream,
    where: str,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The IMU's specific force and angular velocity, the wheel speed [m/s] and its
    derivative [m/s²] in :data:`ESTIMATE_BIN_S` bins with samples of both streams (and
    neighbours that have them); one line if they span less than :data:`EXCITATION_MIN_S`."""
    lo, hi = max(t[0], wheels.t[0]), min(t[-1], wheels.t[-1])
    edges = np.arange(lo, hi, ESTIMATE_BIN_S)
    scale = _metres_per_revolution(pose, wheels)
    if len(edges) * ESTIMATE_BIN_S < EXCITATION_MIN_S or scale is None:
        raise StreamError(
            f'{where} = "estimate": the IMU overlaps the moving wheels for '
            f"{max(hi - lo, 0.0):.0f} s, too little to estimate the mounting; {HOW}"
        )
    f = np.column_stack([interval_means(t, force[:, i], edges) for i in range(3)])[:-1]
    w = np.column_stack([interval_means(t, rates[:, i], edges) for i in range(3)])[:-1]
    left, right = wheel_rotations(wheels, edges)
    speed = 0.5 * (left + right)[:-1] * scale / ESTIMATE_BIN_S
    longitudinal = np.gradient(speed, ESTIMATE_BIN_S)
    # bins with samples of both streams, and neighbours too (the speed's derivative)
    counted = (np.diff(np.searchsorted(t, edges)) > 0) & (
        np.diff(np.searchsorted(wheels.t, edges)) > 0
    )
    valid = counted & np.roll(counted, 1) & np.roll(counted, -1)
    valid[[0, -1]] = False
    # the central difference of bin means weighs the acceleration over three bins (1/4, 1/2,
    # 1/4): the IMU's bins the same, or an abrupt start or stop differs by up to 1 m/s²
    f = np.vstack([f[:1], 0.25 * f[:-2] + 0.5 * f[1:-1] + 0.25 * f[2:], f[-1:]])
    f, w, speed, longitudinal = f[valid], w[valid], speed[valid], longitudinal[valid]
    if len(f) * ESTIMATE_BIN_S < EXCITATION_MIN_S:
        raise StreamError(
            f'{where} = "estimate": the IMU and the wheels share {len(f) * ESTIMATE_BIN_S:.0f} s '
            f"of samples, too little to estimate the mounting; {HOW}"
        )
    return f, w, speed, longitudinal


def _wahba(
    f: np.ndarray, w: np.ndarray, speed: np.ndarray, longitudinal: np.ndarray, where: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rotation ``R`` that best maps the bins' specific force ``f`` onto the vehicle's
    ``(dv/dt - x ω_z², v · ω_z, g)`` in the steady bins (Wahba's problem, by SVD; four
    rounds, each taking the yaw rate about the previous round's vertical and fitting the
    IMU's distance ``x`` ahead of the rear axle), with the steady bins' vehicle and IMU
    specific forces."""
    up = check_gravity(f, where, "as given")
    vertical = up / np.linalg.norm(up)  # the vehicle's z in the IMU's frame, first guess
    ahead = 0.0
    for _ in range(4):
        yaw_rate = w @ vertical
        steady = np.abs(np.gradient(yaw_rate, ESTIMATE_BIN_S)) < STEADY_YAW_ACCELERATION
        steady &= np.roll(steady, 1) & np.roll(steady, -1)
        centripetal = yaw_rate[steady] ** 2
        reference = np.column_stack([longitudinal, speed * yaw_rate, np.full(len(f), GRAVITY)])
        reference, measured = reference[steady], f[steady]
        reference[:, 0] -= ahead * centripetal
        u, _, vt = np.linalg.svd(reference.T @ measured)
        matrix = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
        vertical = matrix[2]
        along = to_vehicle(matrix, measured)[:, 0] - longitudinal[steady]
        if np.sum(centripetal**2) > 0:
            fitted = -np.sum(along * centripetal) / np.sum(centripetal**2)
            ahead = float(np.clip(fitted, -MAX_IMU_AHEAD, MAX_IMU_AHEAD))
    return matrix, reference, measured


def _sigma(
    matrix: np.ndarray,
    reference: np.ndarray,
    measured: np.ndarray,
    horizontal: np.ndarray,
    where: str,
) -> np.ndarray:
    """σ [rad] of roll, pitch and yaw from the residuals (inflated for bins closer than
    :data:`CORRELATION_S`); one line if one exceeds :data:`MAX_SIGMA_DEG`."""
    residual = reference - to_vehicle(matrix, measured)
    spread = float(np.sqrt(np.mean(residual[:, :2] ** 2)))
    inflation = np.sqrt(max(1.0, CORRELATION_S / ESTIMATE_BIN_S))
    tilt_sigma = inflation * spread / (GRAVITY * np.sqrt(len(measured)))
    yaw_sigma = inflation * spread / np.sqrt(np.sum(horizontal**2))
    sigma = np.array([tilt_sigma, tilt_sigma, yaw_sigma])
    if sigma.max() > np.radians(MAX_SIGMA_DEG):
        raise StreamError(
            f'{where} = "estimate": the accelerations determine the mounting only to '
            f"±{np.degrees(sigma.max()):.1f}° (they differ from the wheels' and gravity by "
            f"{spread:.2g} m/s² rms; at most ±{MAX_SIGMA_DEG:g}° is accepted); {HOW}"
        )
    return sigma
