"""Batch calibration (paper §4.1, eqs. 10–11) as one GTSAM graph solved by Levenberg–Marquardt.

The graph holds the shared theta, one :func:`~graphcal.factors.segment_odometry_factor` per
segment and, when start poses are estimated, a Pose2 variable per segment under a prior at its
measured pose. A weak prior on theta at the nominal values keeps elimination well posed when a
batch does not excite every parameter (e.g. d needs lateral acceleration).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.errors import GraphcalError, check_settings
from graphcal.factors import (
    PAPER_POSE_WEIGHTS,
    pose2_from_state,
    pose_sigmas,
    segment_odometry_factor,
    state_from_pose2,
)
from graphcal.model import THETA_NOMINAL
from graphcal.pipeline.solve import marginal_covariance, solve_lm

THETA_KEY = gtsam.symbol("t", 0)


def start_key(segment: int) -> int:
    """Key of segment ``segment``'s start Pose2."""
    return gtsam.symbol("x", segment)


@dataclass(frozen=True)
class BatchSettings:
    """Settings of a batch calibration solve (SI).

    Attributes:
        theta_initial: initial guess, the nominal theta of the paper by default.
        theta_prior_sigmas: standard deviations of the weak prior on theta at ``theta_initial``.
        pose_weights: the paper's W (§4.4); with ``position_sigma`` they give the pose sigmas.
        position_sigma: standard deviation of the measured position [m].
        estimate_start_poses: free each segment's start pose under its measurement prior;
            ``False`` holds it at the measurement, as the paper's Step 1.
        max_iterations: Levenberg–Marquardt iteration limit.
    """

    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.01, 0.2, 0.01]))
    pose_weights: tuple[float, float, float] = PAPER_POSE_WEIGHTS
    position_sigma: float = 0.2
    estimate_start_poses: bool = True
    max_iterations: int = 20

    def __post_init__(self) -> None:
        check_settings(
            "calibration",
            positive_vectors={
                "theta_prior_sigmas": self.theta_prior_sigmas,
                "pose_weights": self.pose_weights,
            },
            finite_vectors={"theta_initial": self.theta_initial},
            positive={"position_sigma": self.position_sigma},
            at_least_one={"max_iterations": self.max_iterations},
        )


@dataclass(frozen=True)
class BatchCalibration:
    """Result of one batch solve.

    Attributes:
        theta: estimated ``[c_e, c_d, t_r, d]`` (SI).
        covariance: 4×4 marginal covariance of theta (SI), from the graph's information at the
            solution (assumes the pose weights are true inverse variances).
        start_states: estimated (or held) start state of each segment, ``(S, 3)``.
        iterations: Levenberg–Marquardt iterations used.
        initial_error, final_error: graph error (half the weighted squared residual).
    """

    theta: np.ndarray
    covariance: np.ndarray
    start_states: np.ndarray
    iterations: int
    initial_error: float
    final_error: float

    @property
    def theta_sigma(self) -> np.ndarray:
        """Standard deviation of each parameter (SI)."""
        return np.sqrt(np.diag(self.covariance))


class CalibrationFailed(GraphcalError, RuntimeError):
    """A batch solve that did not produce a finite estimate."""


#: Plausible ranges of theta (SI) for a road vehicle; outside them the data is almost surely in
#: wrong units (e.g. sideslip in degrees) rather than the vehicle unusual.
PLAUSIBLE_THETA = np.array([[0.5, 5.0], [-0.1, 0.1], [0.5, 3.0], [-0.05, 0.05]])


def check_plausible(theta: np.ndarray) -> None:
    """Raise :class:`CalibrationFailed` if theta lies outside :data:`PLAUSIBLE_THETA`."""
    outside = (theta < PLAUSIBLE_THETA[:, 0]) | (theta > PLAUSIBLE_THETA[:, 1])
    if outside.any():
        names = ("c_e", "c_d", "t_r", "d")
        bad = ", ".join(f"{names[i]} = {theta[i]:.4g}" for i in np.flatnonzero(outside))
        raise CalibrationFailed(
            f"the solve gave an implausible theta ({bad}, SI units); check the units of the "
            "wheel rotations (rev per sample), sideslip (rad) and lateral acceleration (m/s²)"
        )


def build_batch_graph(
    data: SegmentData, settings: BatchSettings
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The batch graph over ``data``'s segments and its initial values."""
    sigmas = pose_sigmas(settings.pose_weights, settings.position_sigma)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    theta0 = np.asarray(settings.theta_initial, dtype=float)
    values.insert(THETA_KEY, theta0)
    graph.add(
        gtsam.PriorFactorVector(
            THETA_KEY, theta0, gtsam.noiseModel.Diagonal.Sigmas(settings.theta_prior_sigmas)
        )
    )
    start_noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
    for i, k in enumerate(data.n_steps):
        poses, inputs = data.poses[i, : k + 1], data.inputs[i, :k]
        if settings.estimate_start_poses:
            pose0 = pose2_from_state(poses[0])
            values.insert(start_key(i), pose0)
            graph.add(gtsam.PriorFactorPose2(start_key(i), pose0, start_noise))
            graph.add(segment_odometry_factor(THETA_KEY, poses, inputs, sigmas, start_key(i)))
        else:
            graph.add(segment_odometry_factor(THETA_KEY, poses, inputs, sigmas))
    return graph, values


def calibrate_batch(data: SegmentData, settings: BatchSettings | None = None) -> BatchCalibration:
    """Estimate theta from the segments in ``data`` (one batch, eq. 11) with Levenberg–Marquardt.

    Raises:
        CalibrationFailed: if the solve diverges or the system is singular.
    """
    settings = settings or BatchSettings()
    graph, values = build_batch_graph(data, settings)
    initial_error = graph.error(values)
    result, iterations = solve_lm(
        graph, values, settings.max_iterations, 1e-10, "batch solve", CalibrationFailed
    )
    covariance = marginal_covariance(graph, result, THETA_KEY, "batch solve", CalibrationFailed)
    theta = result.atVector(THETA_KEY)
    if not np.all(np.isfinite(theta)):
        raise CalibrationFailed("batch solve produced a non-finite theta")
    check_plausible(theta)
    if settings.estimate_start_poses:
        starts = np.array(
            [
                state_from_pose2(result.atPose2(start_key(i)), data.poses[i, 0, 2])
                for i in range(len(data))
            ]
        )
    else:
        starts = data.poses[:, 0].copy()
    return BatchCalibration(
        theta=theta,
        covariance=covariance,
        start_states=starts,
        iterations=iterations,
        initial_error=float(initial_error),
        final_error=float(graph.error(result)),
    )
