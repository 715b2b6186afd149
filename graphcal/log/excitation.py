"""What a drive can tell about theta before any solve: its excitation.

c_e needs distance with positions; c_d needs the yaw the wheels' difference adds up to (any
drive long enough shows it, relative to t_r); t_r needs turning; d needs lateral
acceleration in those turns (docs/method.md, observability). This is the expectation from
the drive's motion; ``calibrate`` reports what the data actually determined from theta's
marginal covariance (:mod:`graphcal.graph.solution.observability`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.log.consistency import WHEEL_TURN_SCALES
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import (
    SegmentData,
    smoothed_yaw_rate,
    split_segments,
    yaw_rate_statistic,
)
from graphcal.model import step_increments

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
    theta: np.ndarray | None = None,
) -> Excitation:
    """The excitation of ``log`` and the parameters it is expected to determine (``theta``:
    the vehicle's nominal, for the wheels' yaw rate of a log without a heading)."""
    distance = float(log.travelled_distance(wheel_circumference)[-1])
    yaw_rate = np.abs(smoothed_yaw_rate(log, yaw_window, theta))
    # Either wheel turning, either way: a robot spinning on the spot is driving too.
    moving = np.concatenate([np.abs(log.n_rl[:-1]) + np.abs(log.n_rr[:-1]) > 0, [False]])
    if log.masked is not None:
        moving &= ~log.masked
    turning_share = float((yaw_rate[moving] > TURNING_YAW_RATE).mean()) if moving.any() else 0.0
    segments = split_segments(log, segment_length, None, wheel_circumference)
    statistic = yaw_rate_statistic(log, segments, yaw_statistic, yaw_window, theta)
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


def lever_arm_sigma(
    data: SegmentData,
    position_sigma: float,
    heading_sigma: float,
    prior_sigma: float,
    theta: np.ndarray | None = None,
) -> np.ndarray:
    """The σ [m] ``(2,)`` (ahead, left) a solve could at best give the GNSS antenna's lever
    arm on these segments, from their track alone: per segment, its fixes and headings fit
    by a free start pose (translation and rotation) and the lever arm, with the segment's
    path held at its track (θ and the wheels' errors are free in a solve, so a solve
    determines the arm less well, never better), under the arm's ``prior_sigma`` [m].

    A lever arm moves the antenna by ``R(ψ_k) · arm``: on a straight road that is a constant
    offset, the start pose's; only the heading's changes tell it apart. Without them an arm
    in the graph is a free direction, and with noisy fixes and no heading the solve uses it
    to follow the fixes' noise (turning the path through cheap wheel corrections at a tiny
    t_r: the real highway minute ran t_r to 0.04–0.5 m).

    The path's heading is the measured one's track; a log of positions only has for its
    track the course of its noisy fixes, whose wobble is no turn: given ``theta``, the
    wheels' turn is taken instead (:func:`wheel_track_heading`). The twin's straight road
    from 5 Hz fixes of 0.26 m: at best ±0.14 m from the course — an arm "showable" that the
    solve then crept 50 iterations on and found not observable — ±1.76 / ±0.37 m from the
    wheels."""
    fixes = data.position_fixes()
    psi = data.poses[..., 2]
    if theta is not None and not data.has_heading():
        psi = wheel_track_heading(data, theta)
    offset = data.poses[..., :2] - data.poses[:, :1, :2]
    cos, sin = np.cos(psi), np.sin(psi)
    zero, one = np.zeros_like(psi), np.ones_like(psi)
    # d antenna position / d [translation x, y, start rotation, arm ahead, arm left], (S, K, 2, 5)
    jacobian = np.stack(
        [
            np.stack([one, zero, -offset[..., 1], cos, -sin], axis=-1),
            np.stack([zero, one, offset[..., 0], sin, cos], axis=-1),
        ],
        axis=-2,
    )
    weights = fixes / position_sigma**2
    info = np.einsum("sk,skri,skrj->sij", weights, jacobian, jacobian)
    headings = data.headings_measured()
    info[:, 2, 2] += headings.sum(axis=1) / heading_sigma**2
    pose, arm = slice(0, 3), slice(3, 5)
    pose_info = info[:, pose, pose] + 1e-12 * np.eye(3)
    reduced = info[:, arm, arm] - info[:, arm, pose] @ np.linalg.solve(
        pose_info, info[:, pose, arm]
    )
    total = reduced.sum(axis=0) + np.eye(2) / prior_sigma**2
    return np.sqrt(np.diag(np.linalg.inv(total)))


def wheel_track_heading(data: SegmentData, theta: np.ndarray) -> np.ndarray:
    """``(S, K+1)`` heading [rad] of each segment's path as its wheels turn it (eq. 2b with
    ``theta``), scaled to the track's turn and at the track's mean heading: the shape of the
    path without the wobble of a course taken from noisy fixes. The scale is a least-squares
    fit of the turns from each segment's start, within
    :data:`~graphcal.log.consistency.WHEEL_TURN_SCALES` — not
    :func:`~graphcal.log.consistency.wheel_turn_scale`'s median of per-step ratios, which
    suits a measured heading: on a skid-steer robot's 2.5 Hz course it fell back to 1 where
    the fit finds 0.35 (a datasheet track half the effective one)."""
    _, omega = step_increments(data.inputs, theta)
    omega = np.where(data.valid[:, 1:], omega, 0.0)
    turned = np.zeros(data.poses.shape[:2])
    np.cumsum(omega, axis=1, out=turned[:, 1:])
    track = data.poses[..., 2] - data.poses[:, :1, 2]
    valid = data.valid
    wheels = np.sum(turned[valid] ** 2)
    scale = float(np.sum(turned[valid] * track[valid]) / wheels) if wheels > 0 else 1.0
    scale = float(np.clip(scale, *WHEEL_TURN_SCALES)) if scale > 0 else 1.0
    turned *= scale
    count = np.maximum(valid.sum(axis=1), 1)
    mean = np.sum(np.where(valid, data.poses[..., 2] - turned, 0.0), axis=1) / count
    return turned + mean[:, None]
