"""GTSAM factors of the odometry model, usable in any ``gtsam.NonlinearFactorGraph``."""

from graphcal.factors.segment import (
    PAPER_POSE_WEIGHTS,
    SegmentOdometryError,
    pose2_from_state,
    pose_sigmas,
    segment_odometry_factor,
    state_from_pose2,
)

__all__ = [
    "PAPER_POSE_WEIGHTS",
    "SegmentOdometryError",
    "pose2_from_state",
    "pose_sigmas",
    "segment_odometry_factor",
    "state_from_pose2",
]
