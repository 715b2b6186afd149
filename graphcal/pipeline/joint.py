"""One joint graph per batch: compensation and calibration in a single solve.

The paper needs five stages because its optimal control assumes a known theta and a correct
initial pose. In a factor graph all of them can be variables at once:

* theta, a 4-vector under a weak prior at the nominal values;
* per segment, its start pose (Pose2) under the measured pose (world-frame position and
  heading priors, the paper's W);
* the segment cut into chunks of ``chunk_steps`` steps; one Python factor per chunk integrates
  eq. (1) from the chunk's start pose with the corrected wheel rotations and theta and tracks
  the measured poses; Pose2 variables at chunk boundaries carry a near-hard continuity
  residual;
* per chunk, one vector of wheel-rotation corrections under their noise prior (the measured
  rotation is the true one plus noise, so the correction is minus the noise: zero-mean with
  the wheel-noise sigma), optionally with the paper's smoothness prior on Δu.

Levenberg–Marquardt solves it once from the nominal theta: an errors-in-variables maximum-
likelihood estimate of theta, start poses and true rotations together.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.errors import check_settings
from graphcal.factors import PAPER_POSE_WEIGHTS, pose_sigmas
from graphcal.graph.observability import (
    DEFAULT_MAX_SIGMA_RATIO,
    Observability,
    assess_observability,
)
from graphcal.graph.segment_graph import (
    CorrectionPrior,
    SegmentGraphSpec,
    ThetaEstimate,
    solve_segment_graph,
)
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS


@dataclass(frozen=True)
class JointSettings:
    """Settings of the joint solve (SI).

    Attributes:
        theta_initial, theta_prior_sigmas: start and weak prior of theta.
        pose_weights, position_sigma: the paper's W with the position noise give the pose
            sigmas of the measurement and tracking residuals.
        wheel_noise: sigma [rev] of the measured wheel rotations: the corrections' prior.
        smoothness_weight: R on the change of corrected rotations; 0 leaves it out (with
            white rotation noise it adds nothing measurable, ``docs/method.md``).
        chunk_steps: steps per Python factor.
        continuity_sigmas: chunk-boundary continuity [m, m, rad].
        max_iterations: Levenberg–Marquardt iteration limit.
        max_sigma_ratio: a parameter counts as calibrated when the data shrink its prior
            sigma to at most this fraction (:mod:`graphcal.graph.observability`).
        slip_sigma: stationary sigma of a relative slip scale of each rear wheel per chunk
            (slow, coloured slip; e.g. 0.0015 = 0.15 %), or 0 for none (the default).
        slip_time: correlation time [s] of the slip scales from chunk to chunk.
    """

    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    pose_weights: tuple[float, float, float] = PAPER_POSE_WEIGHTS
    position_sigma: float = 0.2
    wheel_noise: float = 0.0005
    smoothness_weight: float = 0.0
    chunk_steps: int = 50
    continuity_sigmas: tuple[float, float, float] = (1e-3, 1e-3, 1e-4)
    max_iterations: int = 30
    max_sigma_ratio: float = DEFAULT_MAX_SIGMA_RATIO
    slip_sigma: float = 0.0
    slip_time: float = 5.0

    def __post_init__(self) -> None:
        check_settings(
            "joint",
            positive_vectors={
                "theta_prior_sigmas": self.theta_prior_sigmas,
                "pose_weights": self.pose_weights,
                "continuity_sigmas": self.continuity_sigmas,
            },
            finite_vectors={"theta_initial": self.theta_initial},
            positive={
                "position_sigma": self.position_sigma,
                "wheel_noise": self.wheel_noise,
                "slip_time": self.slip_time,
                "max_sigma_ratio": self.max_sigma_ratio,
            },
            non_negative={
                "smoothness_weight": self.smoothness_weight,
                "slip_sigma": self.slip_sigma,
            },
            at_least_one={"chunk_steps": self.chunk_steps, "max_iterations": self.max_iterations},
        )

    def graph_spec(self, theta_prior: bool = True) -> SegmentGraphSpec:
        """The joint segment graph; ``theta_prior=False`` leaves out the weak prior on theta
        (the measurements' information alone, as the Cramér–Rao bound needs)."""
        sigmas = pose_sigmas(self.pose_weights, self.position_sigma)
        smooth = self.smoothness_weight > 0
        return SegmentGraphSpec(
            theta=np.asarray(self.theta_initial, float),
            tracking_sigmas=sigmas,
            theta_prior_sigmas=np.asarray(self.theta_prior_sigmas, float) if theta_prior else None,
            start_prior_sigmas=sigmas,
            chunk_steps=self.chunk_steps,
            continuity_sigmas=np.asarray(self.continuity_sigmas, float),
            corrections=CorrectionPrior(
                sigma=self.wheel_noise,
                smoothness_sigma=1.0 / np.sqrt(self.smoothness_weight) if smooth else None,
            ),
            slip_sigma=self.slip_sigma if self.slip_sigma > 0 else None,
            slip_time=self.slip_time,
        )


@dataclass(frozen=True)
class JointCalibration(ThetaEstimate):
    """Result of a joint solve (SI): a theta estimate whose covariance has the
    start poses and wheel-rotation corrections marginalized, and its verdict.

    Attributes:
        observability: which parameters the data determined (from ``covariance``).
    """

    observability: Observability


def calibrate_joint(data: SegmentData, settings: JointSettings | None = None) -> JointCalibration:
    """Estimate theta, start poses and wheel-rotation corrections of a batch in one solve.

    Raises:
        CalibrationFailed: if the solve fails or gives an implausible theta.
    """
    settings = settings or JointSettings()
    solved = solve_segment_graph(
        data, settings.graph_spec(), settings.max_iterations, 1e-7, "joint solve"
    )
    observability = assess_observability(
        solved.covariance, settings.theta_prior_sigmas, settings.max_sigma_ratio
    )
    return JointCalibration(
        solved.theta,
        solved.covariance,
        solved.start_states,
        solved.iterations,
        solved.initial_error,
        solved.final_error,
        observability,
        degrees_of_freedom=solved.degrees_of_freedom,
    )
