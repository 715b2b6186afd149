"""GTSAM factors of the odometry model, usable in any ``gtsam.NonlinearFactorGraph``.

Written the way GTSAM writes its own: a measurement object that accumulates the signals and
a small factor class that consumes it, its error with the Jacobians beside it.

* :class:`PreintegratedWheelOdometry` + :class:`WheelOdometryFactor` — wheel steps between
  two Pose2 keyframes, theta a variable (as ``PreintegratedImuMeasurements`` + ``ImuFactor``);
  with theta fixed, :func:`wheel_odometry_between_factor` gives a built-in
  ``BetweenFactorPose2``;
* :class:`OdometryChunk` + :class:`ChunkOdometryFactor` — a chunk of steps tracking measured
  poses, for the calibration graphs (a graph's chunk factors share a :class:`ChunkBatch`
  that evaluates them in one vectorized pass); :func:`segment_odometry_factor` for a whole
  segment;
* :func:`pose_measurement_factor` — a measured pose with the paper's weights;
  :class:`MeasuredPoseFactor` — a measured pose through the antenna's lever arm
  and a heading bias;
* :func:`chunk_correction_prior`, :func:`chunk_boundary_smoothness` — priors on corrections;
* :func:`theta_prior_factor` — a prior on theta.
"""

from graphcal.factors.chunk import CONTINUITY_SIGMAS, ChunkError, OdometryChunk, chunk_errors
from graphcal.factors.chunk_batch import ChunkBatch
from graphcal.factors.chunk_factor import (
    ChunkNoise,
    ChunkOdometryFactor,
    DefectKeys,
    segment_odometry_factor,
)
from graphcal.factors.chunk_inputs import DefectValues, StackedChunks
from graphcal.factors.corrections import (
    chunk_boundary_smoothness,
    chunk_correction_prior,
    theta_prior_factor,
)
from graphcal.factors.measured_pose import MeasuredPoseFactor
from graphcal.factors.poses import (
    PAPER_POSE_WEIGHTS,
    body_to_world,
    pose2_from_state,
    pose_measurement_factor,
    pose_sigmas,
    state_from_pose2,
)
from graphcal.factors.preintegration import PreintegratedWheelOdometry
from graphcal.factors.wheel_odometry import (
    WheelOdometryFactor,
    preintegrate,
    wheel_odometry_between_factor,
)

__all__ = [
    "CONTINUITY_SIGMAS",
    "PAPER_POSE_WEIGHTS",
    "ChunkBatch",
    "ChunkError",
    "ChunkNoise",
    "ChunkOdometryFactor",
    "DefectKeys",
    "DefectValues",
    "MeasuredPoseFactor",
    "OdometryChunk",
    "PreintegratedWheelOdometry",
    "StackedChunks",
    "WheelOdometryFactor",
    "body_to_world",
    "chunk_boundary_smoothness",
    "chunk_correction_prior",
    "chunk_errors",
    "pose2_from_state",
    "pose_measurement_factor",
    "pose_sigmas",
    "preintegrate",
    "segment_odometry_factor",
    "state_from_pose2",
    "theta_prior_factor",
    "wheel_odometry_between_factor",
]
