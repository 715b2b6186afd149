"""What a drive can tell about theta before any solve: its excitation.

c_e needs distance with positions; c_d needs the yaw the wheels' difference adds up to (any
drive long enough shows it, relative to t_r); t_r needs turning; d needs lateral
acceleration in those turns (docs/method.md, observability). This is the expectation from
the drive's motion; ``calibrate`` reports what the data actually determined from theta's
marginal covariance (:mod:`graphcal.graph.observability`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import smoothed_yaw_rate, split_segments, yaw_rate_statistic

#: |yaw rate| [rad/s] above which driving counts as turning.
TURNING_YAW_RATE = 0.1
#: |lateral acceleration| [m/s²] that turning segments must reach for d to show.
MIN_LATERAL_ACCELERATION = 1.0


@dataclass(frozen=True)
class Excitation:
    """A drive's excitation and the parameters it is expected to determine.

    Attributes:
        distance: travelled distance [m] (wheels, the given circumference).
        turning_share: share of the driving time with |yaw rate| > :data:`TURNING_YAW_RATE`.
        segments: calibration segments of the settings' length (none spanning a mask).
        turning_segments: of those, the ones that pass the yaw-rate selection.
        max_lateral_acceleration: largest |a_y| [m/s²] (1 s median) in those segments.
        expected: parameter name -> expected to be determined by the data.
    """

    distance: float
    turning_share: float
    segments: int
    turning_segments: int
    max_lateral_acceleration: float
    expected: dict[str, bool]

    def lines(self) -> list[str]:
        """Lines for a printout (``check`` and ``import``)."""
        seen = [name for name, ok in self.expected.items() if ok]
        unseen = [name for name, ok in self.expected.items() if not ok]
        verdict = ", ".join(seen) if seen else "none"
        if unseen:
            verdict += f"; not {', '.join(unseen)}"
        return [
            f"turning          {self.turning_share:.0%} of the driving time with |yaw rate| > "
            f"{TURNING_YAW_RATE:g} rad/s; max |a_y| {self.max_lateral_acceleration:.1f} m/s² in "
            "turning segments",
            f"observable       {verdict} (expected from the excitation; calibrate reports what "
            "the data determined)",
        ]


def drive_excitation(
    log: DriveLog,
    segment_length: float = 150.0,
    min_yaw_rate: float = 0.15,
    yaw_statistic: str = "mean",
    yaw_window: float = 1.0,
    wheel_circumference: float = 2.0,
) -> Excitation:
    """The excitation of ``log`` and the parameters it is expected to determine."""
    distance = float(log.travelled_distance(wheel_circumference)[-1])
    yaw_rate = np.abs(smoothed_yaw_rate(log, yaw_window))
    # Either wheel turning, either way: a robot spinning on the spot is driving too.
    moving = np.concatenate([np.abs(log.n_rl[:-1]) + np.abs(log.n_rr[:-1]) > 0, [False]])
    if log.masked is not None:
        moving &= ~log.masked
    turning_share = float((yaw_rate[moving] > TURNING_YAW_RATE).mean()) if moving.any() else 0.0
    segments = split_segments(log, segment_length, None, wheel_circumference)
    statistic = yaw_rate_statistic(log, segments, yaw_statistic, yaw_window)
    turning = segments.subset(np.flatnonzero(statistic > min_yaw_rate))
    max_ay = 0.0
    if len(turning):
        window = max(1, round(1.0 / log.dt))
        ay = np.abs(log.ay)
        smooth = np.convolve(ay, np.ones(window) / window, mode="same")
        peaks = np.maximum.reduceat(
            smooth, np.ravel(np.column_stack([turning.start, turning.stop]))
        )
        max_ay = float(peaks[::2].max())
    has_segment = len(segments) > 0
    expected = {
        "c_e": has_segment,
        "c_d": has_segment,
        "t_r": len(turning) > 0,
        "d": len(turning) > 0 and max_ay >= MIN_LATERAL_ACCELERATION,
    }
    return Excitation(
        distance=distance,
        turning_share=turning_share,
        segments=len(segments),
        turning_segments=len(turning),
        max_lateral_acceleration=max_ay,
        expected=expected,
    )
