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

import gtsam
import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.errors import GraphcalError, check_settings
from graphcal.factors import (
    OdometryChunkError,
    chunk_boundary_smoothness,
    chunk_correction_prior,
    odometry_chunk_factor,
    pose2_from_state,
    pose_sigmas,
    state_from_pose2,
    theta_prior_factor,
)
from graphcal.model import THETA_NOMINAL, integrate
from graphcal.pipeline.batch_calibration import THETA_KEY, check_plausible
from graphcal.pipeline.input_estimation import chunk_bounds
from graphcal.pipeline.observability import (
    DEFAULT_MAX_SIGMA_RATIO,
    Observability,
    assess_observability,
)
from graphcal.pipeline.solve import marginal_covariance, solve_lm


@dataclass(frozen=True)
class JointSettings:
    """Settings of the joint solve (SI).

    Attributes:
        theta_initial, theta_prior_sigmas: start and weak prior of theta.
        pose_weights, position_sigma: the paper's W with the position noise give the pose
            sigmas of the measurement and tracking residuals.
        wheel_noise: sigma [rev] of the measured wheel rotations: the corrections' prior.
        smoothness_weight: R on the change of corrected rotations; 0 leaves it out (with
            white rotation noise it adds nothing measurable, ``NOTES.md``).
        chunk_steps: steps per Python factor.
        continuity_sigmas: chunk-boundary continuity [m, m, rad].
        max_iterations: Levenberg–Marquardt iteration limit.
        max_sigma_ratio: a parameter counts as calibrated when the data shrink its prior
            sigma to at most this fraction (:mod:`graphcal.pipeline.observability`).
    """

    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.01, 0.2, 0.01]))
    pose_weights: tuple[float, float, float] = (1.0, 1.0, 50.0)
    position_sigma: float = 0.2
    wheel_noise: float = 0.0005
    smoothness_weight: float = 0.0
    chunk_steps: int = 50
    continuity_sigmas: tuple[float, float, float] = (1e-3, 1e-3, 1e-4)
    max_iterations: int = 30
    max_sigma_ratio: float = DEFAULT_MAX_SIGMA_RATIO

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
                "max_sigma_ratio": self.max_sigma_ratio,
            },
            non_negative={"smoothness_weight": self.smoothness_weight},
            at_least_one={"chunk_steps": self.chunk_steps, "max_iterations": self.max_iterations},
        )


@dataclass(frozen=True)
class JointCalibration:
    """Result of a joint solve (SI).

    Attributes:
        theta: ``[c_e, c_d, t_r, d]``.
        covariance: 4×4 marginal covariance of theta (start poses and wheel-rotation
            corrections marginalized), from the graph's information at the solution.
        start_states: ``(S, 3)`` estimated start states.
        iterations, initial_error, final_error: of the Levenberg–Marquardt run.
        observability: which parameters the data determined (from ``covariance``).
    """

    theta: np.ndarray
    covariance: np.ndarray
    start_states: np.ndarray
    iterations: int
    initial_error: float
    final_error: float
    observability: Observability

    @property
    def theta_sigma(self) -> np.ndarray:
        """Standard deviation of each parameter (SI)."""
        return np.sqrt(np.diag(self.covariance))


def _start_key(segment: int) -> int:
    return gtsam.symbol("s", segment)


def _boundary_key(segment: int, chunk: int) -> int:
    return gtsam.symbol("b", segment * 10_000 + chunk)


def _correction_key(segment: int, chunk: int) -> int:
    return gtsam.symbol("c", segment * 10_000 + chunk)


def build_joint_graph(
    data: SegmentData, settings: JointSettings, theta_prior: bool = True
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The joint graph over ``data``'s segments and its initial values (``theta_prior=False``
    leaves out the weak prior on theta: the measurements' information alone)."""
    sigmas = pose_sigmas(settings.pose_weights, settings.position_sigma)
    position_noise = gtsam.noiseModel.Isotropic.Sigma(2, float(sigmas[0]))
    heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, float(sigmas[2]))
    continuity = np.asarray(settings.continuity_sigmas, float)
    smooth = settings.smoothness_weight > 0
    smooth_sigma = 1.0 / np.sqrt(settings.smoothness_weight) if smooth else None
    theta0 = np.asarray(settings.theta_initial, float)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    values.insert(THETA_KEY, theta0)
    if theta_prior:
        graph.add(theta_prior_factor(THETA_KEY, np.asarray(settings.theta_prior_sigmas), theta0))
    for s, n_steps in enumerate(data.n_steps):
        poses, inputs = data.poses[s, : n_steps + 1], data.inputs[s, :n_steps]
        nominal = integrate(poses[0], inputs, theta0)
        values.insert(_start_key(s), pose2_from_state(poses[0]))
        graph.add(
            gtsam.PoseTranslationPrior2D(_start_key(s), gtsam.Point2(*poses[0, :2]), position_noise)
        )
        graph.add(gtsam.PoseRotationPrior2D(_start_key(s), gtsam.Rot2(poses[0, 2]), heading_noise))
        bounds = chunk_bounds(int(n_steps), settings.chunk_steps)
        n_chunks = len(bounds) - 1
        for j in range(n_chunks):
            a, b = int(bounds[j]), int(bounds[j + 1])
            last = j == n_chunks - 1
            size = np.full((b - a, 2), settings.wheel_noise)
            values.insert(_correction_key(s, j), np.zeros(2 * (b - a)))
            graph.add(
                chunk_correction_prior(_correction_key(s, j), inputs[a:b, :2], size, smooth_sigma)
            )
            if smooth and not last:
                c = int(bounds[j + 2])
                graph.add(
                    chunk_boundary_smoothness(
                        _correction_key(s, j),
                        b - a,
                        inputs[b - 1, :2],
                        _correction_key(s, j + 1),
                        c - b,
                        inputs[b, :2],
                        smooth_sigma,
                    )
                )
            start = _start_key(s) if j == 0 else _boundary_key(s, j)
            if not last:
                values.insert(_boundary_key(s, j + 1), pose2_from_state(nominal[b]))
            error = OdometryChunkError(
                inputs[a:b],
                poses[a : b + 1],
                reference_heading=float(nominal[a, 2]),
                has_end=not last,
                has_corrections=True,
                corrections_as_vector=True,
            )
            keys = [start] + ([] if last else [_boundary_key(s, j + 1)])
            keys += [_correction_key(s, j), THETA_KEY]
            graph.add(odometry_chunk_factor(error, keys, sigmas, continuity))
    return graph, values


def calibrate_joint(data: SegmentData, settings: JointSettings | None = None) -> JointCalibration:
    """Estimate theta, start poses and wheel-rotation corrections of a batch in one solve.

    Raises:
        GraphcalError: if the solve fails or gives an implausible theta.
    """
    settings = settings or JointSettings()
    graph, values = build_joint_graph(data, settings)
    initial_error = graph.error(values)
    result, iterations = solve_lm(graph, values, settings.max_iterations, 1e-7, "joint solve")
    theta = result.atVector(THETA_KEY)
    if not np.all(np.isfinite(theta)):
        raise GraphcalError("joint solve produced a non-finite theta")
    check_plausible(theta)
    covariance = marginal_covariance(graph, result, THETA_KEY, "joint solve")
    starts = np.array(
        [
            state_from_pose2(result.atPose2(_start_key(s)), data.poses[s, 0, 2])
            for s in range(len(data))
        ]
    )
    observability = assess_observability(
        covariance, settings.theta_prior_sigmas, settings.max_sigma_ratio
    )
    return JointCalibration(
        theta,
        covariance,
        starts,
        iterations,
        float(initial_error),
        float(graph.error(result)),
        observability,
    )


def values_at_truth(
    data: SegmentData, truth: SegmentData, theta_true: np.ndarray, settings: JointSettings
) -> gtsam.Values:
    """Values of :func:`build_joint_graph`'s variables at the truth of a synthetic drive.

    Start and boundary poses are the true poses, each chunk's corrections are the true minus
    the measured wheel rotations, theta is ``theta_true``.
    """
    values = gtsam.Values()
    values.insert(THETA_KEY, np.asarray(theta_true, float))
    for s, n_steps in enumerate(data.n_steps):
        true_poses = truth.poses[s, : n_steps + 1]
        correction = truth.inputs[s, :n_steps, :2] - data.inputs[s, :n_steps, :2]
        values.insert(_start_key(s), pose2_from_state(true_poses[0]))
        bounds = chunk_bounds(int(n_steps), settings.chunk_steps)
        for j in range(len(bounds) - 1):
            a, b = int(bounds[j]), int(bounds[j + 1])
            values.insert(_correction_key(s, j), correction[a:b].ravel())
            if j < len(bounds) - 2:
                values.insert(_boundary_key(s, j + 1), pose2_from_state(true_poses[b]))
    return values


def cramer_rao_bound(
    data: SegmentData,
    truth: SegmentData,
    theta_true: np.ndarray,
    settings: JointSettings | None = None,
    graph: gtsam.NonlinearFactorGraph | None = None,
) -> np.ndarray:
    """The Cramér–Rao bound of theta for ``data``: 4×4, SI.

    The theta block of the inverse Fisher information of the measurements — the joint graph
    without the weak prior on theta, linearized at the true values of every variable
    (:func:`values_at_truth`). No unbiased estimate from these measurements can have a
    smaller covariance. ``graph`` reuses an already built
    ``build_joint_graph(data, settings, theta_prior=False)``.

    Raises:
        GraphcalError: if theta is not identifiable from ``data`` (a straight drive): the
            information matrix is singular and there is no finite bound.
    """
    settings = settings or JointSettings()
    if graph is None:
        graph, _ = build_joint_graph(data, settings, theta_prior=False)
    values = values_at_truth(data, truth, theta_true, settings)
    return marginal_covariance(graph, values, THETA_KEY, "Cramér–Rao bound")
