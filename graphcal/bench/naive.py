"""The naive GTSAM formulation of a batch calibration, kept as the benchmark's baseline.

The same least-squares problem as :func:`graphcal.pipeline.batch_calibration.calibrate_batch`
with held start poses (the paper's Step 1), written the way one would first write it in
GTSAM: a Pose2 variable per sample, one Python odometry factor per step between consecutive
poses and theta (the model equation as a tight constraint), and world-frame position and
heading priors per sample (built-in C++ factors). It reproduces the segment formulation's
theta as the odometry sigma goes to zero, and is slow because each of its thousands of Python
factors costs ~50 µs plus a copy of the optimizer's values per call (``NOTES.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.factors import OdometryChunkError, odometry_chunk_factor, pose_sigmas
from graphcal.model import integrate
from graphcal.pipeline.batch_calibration import THETA_KEY, BatchSettings

#: Sigmas [m, m, rad] of the per-step model equation: tight enough that theta agrees with the
#: segment formulation to ~1e-7 relative, loose enough for Levenberg–Marquardt to converge.
ODOMETRY_SIGMAS = np.array([1e-4, 1e-4, 1e-5])


def pose_key(segment: int, step: int) -> int:
    """Key of the Pose2 of ``segment`` at sample ``step`` (step >= 1; step 0 is held)."""
    return gtsam.symbol("p", segment * 100_000 + step)


@dataclass(frozen=True)
class NaiveGraph:
    """The per-step graph of a batch and its initial values."""

    graph: gtsam.NonlinearFactorGraph
    values: gtsam.Values
    python_factors: int


def build_naive_graph(
    data: SegmentData,
    settings: BatchSettings,
    odometry_sigmas: np.ndarray = ODOMETRY_SIGMAS,
) -> NaiveGraph:
    """Per-step factors for the segments in ``data``; poses start on the nominal odometry."""
    sigmas = pose_sigmas(settings.pose_weights, settings.position_sigma)
    position_noise = gtsam.noiseModel.Isotropic.Sigma(2, float(sigmas[0]))
    heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, float(sigmas[2]))
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    theta0 = np.asarray(settings.theta_initial, float)
    values.insert(THETA_KEY, theta0)
    graph.add(
        gtsam.PriorFactorVector(
            THETA_KEY, theta0, gtsam.noiseModel.Diagonal.Sigmas(settings.theta_prior_sigmas)
        )
    )
    python_factors = 0
    for s, n_steps in enumerate(data.n_steps):
        poses, inputs = data.poses[s, : n_steps + 1], data.inputs[s, :n_steps]
        nominal = integrate(poses[0], inputs, theta0)
        for k in range(n_steps):
            values.insert(pose_key(s, k + 1), gtsam.Pose2(*nominal[k + 1]))
            error = OdometryChunkError(
                inputs[k : k + 1],
                start_state=poses[0] if k == 0 else None,
                reference_heading=float(nominal[k, 2]),
                has_end=True,
            )
            keys = ([] if k == 0 else [pose_key(s, k)]) + [pose_key(s, k + 1), THETA_KEY]
            graph.add(odometry_chunk_factor(error, keys, continuity_sigmas=odometry_sigmas))
            python_factors += 1
            x, y, psi = poses[k + 1]
            graph.add(
                gtsam.PoseTranslationPrior2D(pose_key(s, k + 1), gtsam.Point2(x, y), position_noise)
            )
            graph.add(gtsam.PoseRotationPrior2D(pose_key(s, k + 1), gtsam.Rot2(psi), heading_noise))
    return NaiveGraph(graph, values, python_factors)


def naive_optimizer(naive: NaiveGraph, max_iterations: int) -> gtsam.LevenbergMarquardtOptimizer:
    """A Levenberg–Marquardt optimizer on the naive graph, ready to ``iterate()``."""
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setDiagonalDamping(True)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-12)
    return gtsam.LevenbergMarquardtOptimizer(naive.graph, naive.values, params)


#: Odometry sigmas of the penalty continuation: each solve starts from the previous one, so
#: the tight final constraint converges in a few iterations.
CONTINUATION = (1e-4, 1e-5, 1e-6)


def solve_naive(
    data: SegmentData,
    settings: BatchSettings,
    sigmas: tuple[float, ...] = CONTINUATION,
    max_iterations: int = 100,
) -> tuple[np.ndarray, int]:
    """Theta of the naive formulation, converged by a continuation over the odometry sigma.

    Each stage tightens the per-step model equation (position sigma ``s``, heading ``s / 10``)
    and starts from the previous stage's solution; the first starts from nominal odometry.
    Measured on 3 segments (2249 steps): theta agrees with the segment formulation to 2.4e-3
    relative at 1e-4, 5.6e-5 at 1e-5 and 5.6e-7 at 1e-6.

    Returns:
        theta and the total number of Levenberg–Marquardt iterations.
    """
    values = None
    iterations = 0
    for sigma in sigmas:
        naive = build_naive_graph(data, settings, np.array([sigma, sigma, sigma / 10]))
        if values is not None:
            naive = NaiveGraph(naive.graph, values, naive.python_factors)
        optimizer = naive_optimizer(naive, max_iterations)
        values = optimizer.optimize()
        iterations += optimizer.iterations()
    return values.atVector(THETA_KEY), iterations
