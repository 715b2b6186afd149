"""Batch calibration (paper §4.1, eqs. 10–11): theta from a batch of measured segments.

The segment graph (:mod:`graphcal.graph.construction.builder`) with one chunk per segment and no
correction variables: the shared theta under a weak prior at the nominal values (it keeps
elimination well posed when a batch does not excite every parameter, e.g. d needs lateral
acceleration) and, when start poses are estimated, a Pose2 per segment under its measurement.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graphcal.errors import check_settings
from graphcal.factors import PAPER_POSE_WEIGHTS, pose_sigmas
from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.estimates import ThetaEstimate
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.segments import SegmentData
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS


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
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
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

    def graph_spec(self) -> SegmentGraphSpec:
        """The segment graph of a batch solve."""
        sigmas = pose_sigmas(self.pose_weights, self.position_sigma)
        return SegmentGraphSpec(
            theta=np.asarray(self.theta_initial, float),
            tracking_sigmas=sigmas,
            theta_prior_sigmas=np.asarray(self.theta_prior_sigmas, float),
            start_prior_sigmas=sigmas if self.estimate_start_poses else None,
        )


def calibrate_batch(data: SegmentData, settings: BatchSettings | None = None) -> ThetaEstimate:
    """Estimate theta from the segments in ``data`` (one batch, eq. 11) with Levenberg–Marquardt.

    Raises:
        CalibrationFailed: if the solve diverges, the system is singular or theta implausible.
    """
    settings = settings or BatchSettings()
    options = SolveOptions(settings.max_iterations, 1e-10, "batch solve")
    solved = solve_segment_graph(data, settings.graph_spec(), options)
    return solved.estimate()
