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
#: one is held).
COURSE_WINDOW_S = 1.0
COURSE_MIN_DISTANCE = 1.0
#: Half the chord [m] along the wheels' travel over which a course is taken.
COURSE_HALF_DISTANCE = 5.0


def course(
    x: np.ndarray, y: np.ndarray, dt: float, travelled: np.ndarray | None = None
) -> np.ndarray:
    """Direction of travel [rad, unwrapped] from grid positions, as a central chord.

    With ``travelled`` (distance [m] at each sample, from the wheels) the chord spans
    :data:`COURSE_HALF_DISTANCE` on each side, so that its direction error (position noise
    over chord length) does not grow at low speed; else :data:`COURSE_WINDOW_S`. Where the
    chord is shorter than :data:`COURSE_MIN_DISTANCE` (standstill) the last defined course
    is held (the first defined one before it).
    """
    n = len(x)
    if travelled is not None:
        ahead = np.searchsorted(travelled, travelled + COURSE_HALF_DISTANCE, side="left")
        behind = np.searchsorted(travelled, travelled - COURSE_HALF_DISTANCE, side="right") - 1
        ahead, behind = np.minimum(ahead, n - 1), np.maximum(behind, 0)
    else:
        half = max(1, round(0.5 * COURSE_WINDOW_S / dt))
        ahead = np.minimum(np.arange(n) + half, n - 1)
        behind = np.maximum(np.arange(n) - half, 0)
    dx, dy = x[ahead] - x[behind], y[ahead] - y[behind]
    defined = np.hypot(dx, dy) >= COURSE_MIN_DISTANCE
    if not defined.any():
        return np.zeros(n)
    index = np.where(defined, np.arange(n), -1)
    index = np.maximum.accumulate(index)
    index[index < 0] = int(np.flatnonzero(defined)[0])
    angle = np.arctan2(dy, dx)[index]
    return np.unwrap(angle)


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
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The track ``(px, py, psi)`` at every sample from the measured components.

    Args:
        t: sample times [s] ``(N,)``.
        px, py, psi: ``(N,)``, read only where ``measured`` says (``psi`` in radians, any
            branch).
        measured: ``(N, 2)`` booleans [position, heading]; at least two positions.
        lag: ``(N,)`` [s] each row's measurement was taken this long before ``t``, or
            ``None``.
        travelled: distance [m] at each sample from the wheels (for a course).

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
        angle = course(x, y, float(np.median(np.diff(t))), travelled)
    return x, y, angle
