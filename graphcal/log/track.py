"""The drive log's track: a pose at every sample, from measurements that need not be at every
sample.

A recording measures the pose where its receiver did — a GNSS fix at 1–10 Hz at its own
time, a heading only where one is logged — while segment cutting, the yaw-rate selection,
initial values and figures want a pose at every sample of the wheel grid. The track gives
them one: positions interpolated linearly in time between fixes, the heading between heading
samples on the circle, or, with no heading logged at all, the direction of travel of that
interpolated path (:func:`course`). **The track is never a measurement**: calibration and
validation read only the measured components (``DriveLog.measured``) at their own times.
"""

from __future__ import annotations

import numpy as np

#: Window [s] over which a course (direction of travel) is taken without the wheels' travel,
#: and the distance [m] the chord must span for the course to be defined (else the last
#: one is held): the paper's car's; a smaller vehicle passes its own (half its wheel
#: circumference, :data:`COURSE_MIN_REVS`).
COURSE_WINDOW_S = 1.0
COURSE_MIN_DISTANCE = 1.0
COURSE_MIN_REVS = 0.5
#: Half the chord [m] along the wheels' travel over which a course is taken (the car's;
#: :data:`COURSE_HALF_REVS` wheel revolutions for another vehicle).
COURSE_HALF_DISTANCE = 5.0
COURSE_HALF_REVS = 2.5


def course(
    x: np.ndarray,
    y: np.ndarray,
    dt: float,
    travelled: np.ndarray | None = None,
    *,
    min_distance: float = COURSE_MIN_DISTANCE,
    half_distance: float = COURSE_HALF_DISTANCE,
) -> np.ndarray:
    """Direction of travel [rad, unwrapped] from grid positions, as a central chord.

    With ``travelled`` (distance [m] along the path at each sample, from the wheels) the
    chord spans ``half_distance`` [m] on each side, so that its direction error (position
    noise over chord length) does not grow at low speed; else :data:`COURSE_WINDOW_S`. Where
    the chord is shorter than ``min_distance`` [m] (standstill) the last defined course is
    held (the first defined one before it). The defaults are the paper's car's; a vehicle
    with wheels ``c_e`` around passes :func:`course_distances`.
    """
    n = len(x)
    if travelled is not None:
        behind, ahead = chord_ends(travelled, half_distance)
    else:
        half = max(1, round(0.5 * COURSE_WINDOW_S / dt))
        ahead = np.minimum(np.arange(n) + half, n - 1)
        behind = np.maximum(np.arange(n) - half, 0)
    dx, dy = x[ahead] - x[behind], y[ahead] - y[behind]
    defined = np.hypot(dx, dy) >= min_distance
    if not defined.any():
        return np.zeros(n)
    index = np.where(defined, np.arange(n), -1)
    index = np.maximum.accumulate(index)
    index[index < 0] = int(np.flatnonzero(defined)[0])
    angle = np.arctan2(dy, dx)[index]
    return np.unwrap(angle)


def chord_ends(travelled: np.ndarray, half_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``(behind, ahead)`` of each row's chord: ``half_distance`` [m] of ``travelled``
    [m] on each side, clipped to the log."""
    n = len(travelled)
    ahead = np.searchsorted(travelled, travelled + half_distance, side="left")
    behind = np.searchsorted(travelled, travelled - half_distance, side="right") - 1
    return np.maximum(behind, 0), np.minimum(ahead, n - 1)


def course_distances(wheel_circumference: float) -> dict[str, float]:
    """:func:`course`'s ``min_distance`` and ``half_distance`` [m] for a vehicle whose wheels
    are ``wheel_circumference`` [m] around (its nominal c_e): :data:`COURSE_MIN_REVS` and
    :data:`COURSE_HALF_REVS` revolutions, the car's 1 m and 5 m for its 2 m wheels."""
    return {
        "min_distance": COURSE_MIN_REVS * wheel_circumference,
        "half_distance": COURSE_HALF_REVS * wheel_circumference,
    }


def fix_times(t: np.ndarray, lag: np.ndarray | None) -> np.ndarray:
    """Time [s] of each row's measurement: the row's time less its lag."""
    return t if lag is None else t - lag


def fill_track(
    t: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    psi: np.ndarray,
    measured: np.ndarray,
    lag: np.ndarray | None,
    travelled: np.ndarray,
    wheel_circumference: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The track ``(px, py, psi)`` at every sample from the measured components.

    Args:
        t: sample times [s] ``(N,)``.
        px, py, psi: ``(N,)``, read only where ``measured`` says (``psi`` in radians, any
            branch).
        measured: ``(N, 2)`` booleans [position, heading]; at least two positions.
        lag: ``(N,)`` [s] each row's measurement was taken this long before ``t``, or
            ``None``.
        travelled: distance [m] along the path at each sample from the wheels (for a
            course).
        wheel_circumference: [m] the vehicle's nominal c_e, which sets the chord of a
            course (:func:`course_distances`; ``None``: the paper's car's).

    Returns:
        The measured values in their rows; between them positions interpolated in time
        (held before the first fix and after the last), the heading on the circle between
        heading samples, or the course of that path where no heading is logged.
    """
    at = fix_times(t, lag)
    position = measured[:, 0]
    x = np.interp(t, at[position], px[position])
    y = np.interp(t, at[position], py[position])
    x[position], y[position] = px[position], py[position]  # a fix row keeps its fix
    heading = measured[:, 1]
    if heading.sum() >= 2:
        unwrapped = np.unwrap(psi[heading])
        angle = np.interp(t, at[heading], unwrapped)
        angle[heading] = unwrapped
    elif heading.any():
        angle = np.full(len(t), float(psi[heading][0]))
    else:
        scale = {} if wheel_circumference is None else course_distances(wheel_circumference)
        angle = course(x, y, float(np.median(np.diff(t))), travelled, **scale)
    return x, y, angle
