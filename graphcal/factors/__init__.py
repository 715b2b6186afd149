"""GTSAM factors of the odometry model, usable in any ``gtsam.NonlinearFactorGraph``.

* :func:`wheel_odometry_factor` — one step between two Pose2 variables with theta (and an
  optional wheel-rotation correction) as variables;
* :func:`segment_odometry_factor`, :func:`odometry_chunk_factor` — many steps in one factor;
* :func:`pose_measurement_factor` — a measured pose with the paper's weights;
* :func:`correction_smoothness_factor`, :func:`correction_size_factor` — priors on corrections;
* :func:`theta_prior_factor` — a prior on theta.
"""

from graphcal.factors.corrections import (
    chunk_boundary_smoothness,
    chunk_correction_prior,
    correction_size_factor,
    correction_smoothness_factor,
    size_sigmas,
    theta_prior_factor,
)
from graphcal.factors.odometry import (
    OdometryChunkError,
    odometry_chunk_factor,
    segment_odometry_factor,
    wheel_odometry_factor,
)
from graphcal.factors.poses import (
    PAPER_POSE_WEIGHTS,
    body_to_world,
    pose2_from_state,
    pose_measurement_factor,
    pose_sigmas,
    state_from_pose2,
)

__all__ = [
    "PAPER_POSE_WEIGHTS",
    "OdometryChunkError",
    "body_to_world",
    "chunk_boundary_smoothness",
    "chunk_correction_prior",
    "correction_size_factor",
    "correction_smoothness_factor",
    "odometry_chunk_factor",
    "pose2_from_state",
    "pose_measurement_factor",
    "pose_sigmas",
    "segment_odometry_factor",
    "size_sigmas",
    "state_from_pose2",
    "theta_prior_factor",
    "wheel_odometry_factor",
]
