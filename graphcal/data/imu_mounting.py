"""A mounted IMU: its 3-axis signals rotated from its own frame into the vehicle frame, and
the mounting estimated from the drive when it is not known.

**Convention.** ``mounting = [roll, pitch, yaw]`` [deg] is the rotation of the IMU's frame
in the vehicle frame (REP 103: x forward, y left, z up), intrinsic z-y'-x'' (yaw about the
vehicle's z, then pitch about the new y, then roll about the newest x)::

    v_vehicle = R · v_imu,   R = Rz(yaw) · Ry(pitch) · Rx(roll)

the same as a URDF joint's ``rpy`` of the IMU link in ``base_link`` and tf2's
``Quaternion.setRPY``. The columns of ``R`` are the IMU's axes in vehicle coordinates: an
IMU whose x axis points to the vehicle's left has yaw = 90°. A 3×3 matrix (rows of ``R``)
may be given instead of the angles.

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

import dataclasses
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from graphcal.data.streams import (
    Field,
    ImuStream,
    PoseStream,
    StreamError,
    WheelStream,
    interval_means,
    wheel_rotations,
)

if TYPE_CHECKING:
    from graphcal.data.manifest import Manifest

#: Standard gravity [m/s²].
GRAVITY = 9.80665
#: Units of ``acceleration_unit`` [m/s² per unit].
ACCELERATION_UNITS = {"m/s²": 1.0, "m/s^2": 1.0, "m/s2": 1.0, "g": GRAVITY}
#: Units of ``angular_velocity_unit`` [rad/s per unit].
ANGULAR_VELOCITY_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
#: The ``mounting`` value that asks for the estimate.
ESTIMATE = "estimate"
#: ``[imu]`` keys of a 3-axis IMU in its own frame.
MOUNTED_KEYS = (
    "acceleration",
    "acceleration_unit",
    "angular_velocity",
    "angular_velocity_unit",
    "mounting",
)
#: Bin [s] over which the streams are averaged for the estimate.
ESTIMATE_BIN_S = 0.5
#: Horizontal acceleration [m/s²] of a bin that counts as excitation of the yaw, and the
#: time [s] of such bins the estimate needs.
EXCITATION_MIN = 0.5
EXCITATION_MIN_S = 20.0
#: Largest σ [deg] of an estimated angle that is accepted.
MAX_SIGMA_DEG = 0.5
#: Yaw acceleration [rad/s²] below which a bin (and its neighbours) is steady: where the yaw
#: rate changes, speed × yaw rate is not the lateral acceleration (the sideslip's rate, the
#: IMU's lever arm from the rear axle), and the estimate leaves the bin out.
STEADY_YAW_ACCELERATION = 0.05
#: Residuals of bins closer than this [s] are counted as correlated in the σ.
CORRELATION_S = 2.0
#: Accepted ratio of the IMU's mean specific force's magnitude to gravity.
GRAVITY_RANGE = (0.8, 1.2)
#: Largest angle [deg] of the rotated mean specific force from the vehicle's up, and of the
#: rotated gyro's turn axis from the vehicle's z.
MAX_TILT_DEG = 10.0
#: Yaw rate [rad/s] of a bin that counts as turning, and the time [s] of such bins the gyro's
#: axis check needs.
TURNING_MIN = 0.1
TURNING_MIN_S = 10.0
#: Span [s] of the chords that scale the wheels to metres for the estimate.
SCALE_STEP_S = 2.0
#: How far [1] a given matrix may be from a rotation (max |RᵀR − I|).
ROTATION_TOLERANCE = 1e-3


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


def parse_mounting(value: Any, where: str) -> np.ndarray | str:
    """The ``mounting`` value: :data:`ESTIMATE`, or its rotation ``R`` ``(3, 3)`` from
    ``[roll, pitch, yaw]`` [deg] or a 3×3 matrix (rows); ``where`` prefixes the one-line
    error (``"manifest.toml: [imu] mounting"``)."""
    how = (
        "give [roll, pitch, yaw] in degrees (vehicle = Rz(yaw)·Ry(pitch)·Rx(roll)·IMU), a 3×3 "
        'rotation matrix, or "estimate"'
    )
    if isinstance(value, str):
        if value == ESTIMATE:
            return ESTIMATE
        raise StreamError(f"{where} = {_toml(value)} is not known; {how}")
    if not isinstance(value, list):
        raise StreamError(f"{where} = {_toml(value)}: {how}")
    if value and all(isinstance(row, list) for row in value):
        rows = value
        if len(rows) != 3 or any(len(row) != 3 for row in rows):
            shape = "×".join(map(str, (len(rows), *{len(row) for row in rows})))
            raise StreamError(f"{where} is a {shape} matrix; {how}")
        numbers = [x for row in rows for x in row]
    else:
        numbers = value
        if len(numbers) != 3:
            raise StreamError(f"{where} = {_toml(value)} has {len(numbers)} value(s); {how}")
    if any(isinstance(x, bool) or not isinstance(x, int | float) for x in numbers) or not all(
        np.isfinite(numbers)
    ):
        raise StreamError(f"{where} = {_toml(value)} must hold finite numbers; {how}")
    if numbers is value:
        return rotation(*np.radians(np.asarray(value, dtype=float)))
    matrix = np.asarray(value, dtype=float)
    off = float(np.abs(matrix.T @ matrix - np.eye(3)).max())
    if off > ROTATION_TOLERANCE:
        raise StreamError(
            f"{where}: the matrix is not orthonormal (|RᵀR − I| up to {off:.2g}), not a "
            f"rotation; {how}"
        )
    if np.linalg.det(matrix) < 0:
        raise StreamError(
            f"{where}: the matrix is a reflection (determinant −1), not a rotation: a "
            f"left-handed axis, or one axis negated; {how}"
        )
    return matrix


def _toml(value: Any) -> str:
    """A manifest value as TOML writes it (``["ax", "ay"]``, ``[5.0, 90.0]``, ``"guess"``)."""
    return json.dumps(value, ensure_ascii=False)


def _column_list(manifest: Manifest, key: str) -> list[str] | None:
    """The three columns of ``acceleration`` or ``angular_velocity``, or ``None``."""
    value = manifest.imu.get(key)
    if value is None:
        return None
    example = '["ax", "ay", "az"]' if key == "acceleration" else '["wx", "wy", "wz"]'
    if (
        not isinstance(value, list)
        or len(value) != 3
        or not all(isinstance(c, str) and c for c in value)
    ):
        count = f"{len(value)} column(s) " if isinstance(value, list) else ""
        raise manifest.error(
            f"[imu] {key} = {_toml(value)} names {count}but needs 3: the x, y and z columns of the "
            f"IMU's own frame, e.g. {key} = {example}"
        )
    if len(set(value)) < 3:
        raise manifest.error(f"[imu] {key} = {_toml(value)} names a column twice; name x, y and z")
    return value


def _check_keys(manifest: Manifest) -> None:
    """One line for a mix of the vehicle-frame keys and the 3-axis ones."""
    table = manifest.imu
    for frame, mounted, unit in (
        ("lateral_acceleration", "acceleration", None),
        ("yaw_rate", "angular_velocity", "yaw_rate_unit"),
    ):
        if frame in table and mounted in table:
            raise manifest.error(
                f"[imu] has both {frame} (vehicle frame) and {mounted} (the IMU's frame, rotated "
                f"by mounting); keep one"
            )
        if unit in table and mounted in table:
            raise manifest.error(
                f"[imu] {unit} applies to yaw_rate; with {mounted} use angular_velocity_unit"
            )
    for key, needs in (
        ("acceleration_unit", "acceleration"),
        ("angular_velocity_unit", "angular_velocity"),
    ):
        if key in table and needs not in table:
            raise manifest.error(f"[imu] {key} applies to {needs}, which is not given")
    if "mounting" not in table:
        raise manifest.error(
            "[imu] acceleration and angular_velocity are in the IMU's frame: add mounting = "
            '[roll, pitch, yaw] (degrees; [0, 0, 0] if its axes are the vehicle\'s) or "estimate"'
        )
    if not ({"acceleration", "angular_velocity"} & set(table)):
        raise manifest.error(
            "[imu] mounting rotates acceleration and angular_velocity (3 columns each), and "
            "neither is given; without them, lateral_acceleration and yaw_rate are in the "
            "vehicle frame already"
        )


def read_mounted_imu(
    manifest: Manifest, notes: list[str], pose: PoseStream, wheels: WheelStream
) -> ImuStream:
    """The ``[imu]`` of a 3-axis IMU in its own frame (``acceleration``, ``angular_velocity``,
    ``mounting``), rotated into the vehicle frame: its lateral acceleration [m/s²] and yaw
    rate [rad/s]. With ``mounting = "estimate"`` the mounting is estimated from the drive
    (:func:`estimate_mounting`; the pose and the wheels give the vehicle's accelerations) and
    said in a note."""
    from graphcal.data.manifest import _declared, _read_columns

    table = manifest.imu
    _check_keys(manifest)
    where = f"{manifest.source}: [imu] mounting"
    mounting = parse_mounting(table["mounting"], where)
    accelerations = _column_list(manifest, "acceleration")
    rates = _column_list(manifest, "angular_velocity")
    if isinstance(mounting, str) and (accelerations is None or rates is None):
        raise StreamError(
            f'{where} = "estimate" needs both acceleration and angular_velocity (gravity and '
            "the turns); give mounting = [roll, pitch, yaw] in degrees instead"
        )
    acceleration_unit = manifest.choice(
        table, "acceleration_unit", ACCELERATION_UNITS, "imu", "m/s²"
    )
    rate_unit = manifest.choice(
        table, "angular_velocity_unit", ANGULAR_VELOCITY_UNITS, "imu", "rad/s"
    )
    columns: dict[str, str] = {}
    for key, names in (("acceleration", accelerations), ("angular_velocity", rates)):
        for axis, name in enumerate(names or ()):
            columns[f"{key}[{axis}]"] = name
    acceleration_declared = _declared(table, "acceleration_unit", "m/s²")
    rate_declared = _declared(table, "angular_velocity_unit", "rad/s")
    units = {
        role: acceleration_declared if role.startswith("acceleration") else rate_declared
        for role in columns
    }
    source, t, values, provenance = _read_columns(manifest, "imu", table, columns, notes, units)
    force = rate = None
    if accelerations is not None:
        force = np.column_stack([values[f"acceleration[{i}]"] for i in range(3)])
        force *= ACCELERATION_UNITS[acceleration_unit]
    if rates is not None:
        rate = np.column_stack([values[f"angular_velocity[{i}]"] for i in range(3)])
        rate *= ANGULAR_VELOCITY_UNITS[rate_unit]
    if isinstance(mounting, str):
        estimate = estimate_mounting(t, force, rate, pose, wheels, where)
        matrix = estimate.rotation
        notes.append(f"{source}: {estimate.note()}")
        mounting_value = f'"estimate" = {degrees_text(matrix)}'
    else:
        matrix = mounting
        mounting_value = _toml(table["mounting"])
        check_mounting(matrix, force, rate, f"{where} = {mounting_value}", acceleration_declared)
    mounting_text = f"mounting = {mounting_value}"
    fields = dict(provenance.fields)
    if accelerations is not None:
        fields["lateral_acceleration"] = Field(
            ", ".join(accelerations),
            "[imu] acceleration",
            f"{acceleration_declared}, {mounting_text}",
            (("acceleration_unit", acceleration_unit), ("mounting", mounting_value)),
        )
    if rates is not None:
        fields["yaw_rate"] = Field(
            ", ".join(rates),
            "[imu] angular_velocity",
            f"{rate_declared}, {mounting_text}",
            (("angular_velocity_unit", rate_unit), ("mounting", mounting_value)),
        )
    return ImuStream(
        t=t,
        lateral_acceleration=None if force is None else to_vehicle(matrix, force)[:, 1],
        yaw_rate=None if rate is None else to_vehicle(matrix, rate)[:, 2],
        source=source,
        provenance=dataclasses.replace(provenance, fields=fields),
    )


def mounted_fix(field: Field | None) -> str | None:
    """For a quantity rotated from a mounted IMU's columns (:func:`read_mounted_imu`), the
    keys to check, in the manifest's words (``check [imu] angular_velocity_unit (now
    "rad/s") and mounting (now [5, 0, 90])``); ``None`` for any other field."""
    mounting = None if field is None else field.declares("mounting")
    if mounting is None:
        return None
    unit_key, unit = next((k, v) for k, v in field.declared if k.endswith("_unit"))
    return (
        f'check {field.section} {unit_key} (now "{unit}") and mounting (now {mounting}: roll, '
        "pitch, yaw in degrees, vehicle = Rz(yaw)·Ry(pitch)·Rx(roll)·IMU)"
    )


def _tilt(vector: np.ndarray) -> float:
    """Angle [rad] of ``vector`` from the vehicle's z (up)."""
    return float(np.arccos(np.clip(vector[2] / np.linalg.norm(vector), -1.0, 1.0)))


def _turn_axis(rates: np.ndarray) -> np.ndarray | None:
    """The main axis of ``rates`` ``(N, 3)`` [rad/s] (the eigenvector of their second moment
    with the largest eigenvalue, pointing up), or ``None`` if they turn too little."""
    turning = np.linalg.norm(rates, axis=1) > TURNING_MIN
    if turning.sum() * ESTIMATE_BIN_S < TURNING_MIN_S:
        return None
    _, vectors = np.linalg.eigh(rates[turning].T @ rates[turning])
    axis = vectors[:, -1]
    return axis if axis[2] >= 0 else -axis


def _check_gravity(force: np.ndarray, where: str, unit: str) -> np.ndarray:
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
    order or frame; ``where`` prefixes it (``"manifest.toml: [imu] mounting = [5, 0, 90]"``)."""
    fix = 'check the angles and their order, or set mounting = "estimate"'
    if force is not None:
        up = to_vehicle(matrix, _check_gravity(force, where, unit)[None])[0]
        if _tilt(up) > np.radians(MAX_TILT_DEG):
            raise StreamError(
                f"{where} puts the IMU's gravity (its mean specific "
                f"force) {np.degrees(_tilt(up)):.0f}° from the vehicle's up (it must be within "
                f"{MAX_TILT_DEG:g}°); {fix}"
            )
    if rates is not None:
        axis = _turn_axis(to_vehicle(matrix, rates))
        if axis is not None and _tilt(axis) > np.radians(MAX_TILT_DEG):
            raise StreamError(
                f"{where} puts the gyro's turn axis {np.degrees(_tilt(axis)):.0f}° from the "
                f"vehicle's z (it must be within {MAX_TILT_DEG:g}°); check that "
                "angular_velocity names the x, y, z columns of the accelerometer's frame, in "
                f"that order, and {fix.removeprefix('check ')}"
            )


def _metres_per_revolution(pose: PoseStream, wheels: WheelStream) -> float | None:
    """The wheels' distance scale [m/rev]: the GNSS track's chords over the wheels'
    revolutions, in :data:`SCALE_STEP_S` steps where the vehicle clearly moves."""
    lo, hi = max(pose.t[0], wheels.t[0]), min(pose.t[-1], wheels.t[-1])
    edges = np.arange(lo, hi, SCALE_STEP_S)
    if len(edges) < 3:
        return None
    chords = np.hypot(
        np.diff(np.interp(edges, pose.t, pose.x)), np.diff(np.interp(edges, pose.t, pose.y))
    )
    left, right = wheel_rotations(wheels, edges)
    revolutions = np.abs(0.5 * (left + right))[:-1]
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
    how = "set mounting = [roll, pitch, yaw] (degrees) measured on the vehicle"
    lo, hi = max(t[0], wheels.t[0]), min(t[-1], wheels.t[-1])
    edges = np.arange(lo, hi, ESTIMATE_BIN_S)
    scale = _metres_per_revolution(pose, wheels)
    if len(edges) * ESTIMATE_BIN_S < EXCITATION_MIN_S or scale is None:
        raise StreamError(
            f'{where} = "estimate": the IMU overlaps the moving wheels for '
            f"{max(hi - lo, 0.0):.0f} s, too little to estimate the mounting; {how}"
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
            f"of samples, too little to estimate the mounting; {how}"
        )
    up = _check_gravity(f, where, "as given")
    vertical = up / np.linalg.norm(up)  # the vehicle's z in the IMU's frame, first guess
    for _ in range(3):
        yaw_rate = w @ vertical
        steady = np.abs(np.gradient(yaw_rate, ESTIMATE_BIN_S)) < STEADY_YAW_ACCELERATION
        steady &= np.roll(steady, 1) & np.roll(steady, -1)
        reference = np.column_stack([longitudinal, speed * yaw_rate, np.full(len(f), GRAVITY)])
        reference, measured = reference[steady], f[steady]
        u, _, vt = np.linalg.svd(reference.T @ measured)
        matrix = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
        vertical = matrix[2]
    horizontal = np.hypot(reference[:, 0], reference[:, 1])
    excitation = float((horizontal > EXCITATION_MIN).sum() * ESTIMATE_BIN_S)
    if excitation < EXCITATION_MIN_S:
        raise StreamError(
            f'{where} = "estimate": the drive has {excitation:.0f} s of acceleration, braking or '
            f"steady turning above {EXCITATION_MIN:g} m/s² (the yaw needs {EXCITATION_MIN_S:g} "
            f"s); {how}"
        )
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
            f"{spread:.2g} m/s² rms; at most ±{MAX_SIGMA_DEG:g}° is accepted); {how}"
        )
    axis = _turn_axis(to_vehicle(matrix, w))
    axis_tilt = None if axis is None else _tilt(axis)
    if axis_tilt is not None and axis_tilt > np.radians(MAX_TILT_DEG):
        raise StreamError(
            f'{where} = "estimate": the gyro turns about an axis {np.degrees(axis_tilt):.0f}° '
            "from the vertical the accelerometer's gravity gives; acceleration and "
            "angular_velocity must name the x, y, z columns of one frame, in that order"
        )
    return MountingEstimate(matrix, sigma, excitation, axis_tilt)
