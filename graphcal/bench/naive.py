"""The naive GTSAM formulation of a batch calibration, kept as the benchmark's baseline.

The same least-squares problem as
:func:`graphcal.pipeline.solvers.batch_calibration.calibrate_batch` with held start poses
(the paper's Step 1), written the way one would first write it in GTSAM: a Pose2 variable
per sample and one Python odometry factor per step — the segment graph
(:mod:`graphcal.graph.construction.builder`) with chunks of one step, the model equation as a tight
continuity constraint. It reproduces the segment formulation's theta as the continuity
sigma goes to zero, and is slow because each of its thousands of Python factors costs
~50 µs plus a copy of the optimizer's values per call (``docs/performance.md``).
"""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np

from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.log.segments import SegmentData
from graphcal.pipeline.solvers.batch_calibration import BatchSettings

#: Sigmas [m, m, rad] of the per-step model equation: tight enough that theta agrees with the
#: segment formulation to ~1e-7 relative, loose enough for Levenberg–Marquardt to converge.
ODOMETRY_SIGMAS = np.array([1e-4, 1e-4, 1e-5])


def build_naive_graph(
    data: SegmentData,
    settings: BatchSettings,
    odometry_sigmas: np.ndarray = ODOMETRY_SIGMAS,
) -> BuiltGraph:
    """One Python factor per step of the segments in ``data`` (start held at its measurement);
    poses start on the nominal odometry."""
    spec = dataclasses.replace(
        settings.graph_spec(),
        start_prior_sigmas=None,
        chunk_steps=1,
        continuity_sigmas=np.asarray(odometry_sigmas, float),
    )
    return build_segment_graph(data, spec)


def naive_optimizer(
    naive: BuiltGraph, max_iterations: int, values: gtsam.Values | None = None
) -> gtsam.LevenbergMarquardtOptimizer:
    """A Levenberg–Marquardt optimizer on the naive graph, ready to ``iterate()``."""
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setDiagonalDamping(True)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-12)
    start = naive.values if values is None else values
    return gtsam.LevenbergMarquardtOptimizer(naive.graph, start, params)


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

    Returns:
        theta and the total number of Levenberg–Marquardt iterations.
    """
    values = None
    iterations = 0
    for sigma in sigmas:
        naive = build_naive_graph(data, settings, np.array([sigma, sigma, sigma / 10]))
        optimizer = naive_optimizer(naive, max_iterations, values)
        values = optimizer.optimize()
        iterations += optimizer.iterations()
    return values.atVector(keys.THETA), iterations
