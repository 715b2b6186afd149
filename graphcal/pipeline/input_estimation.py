"""Input estimation of one segment (paper §4.2, eqs. 12–14) as a GTSAM graph.

The paper's optimal-control problem — find wheel rotations that make the model, started from
the measured first pose with theta fixed, track the measured poses (weight Q) with smooth
inputs (weight R on Δu) inside ±5 % of the measurement — becomes a least-squares graph:

* the segment cut into chunks of ``chunk_steps`` steps; one Python factor per chunk
  integrates the model from the chunk's start pose and tracks the measured poses (Q); Pose2
  variables at the chunk boundaries are tied to the prediction by a near-hard continuity
  residual (multiple shooting), so elimination works on a chain and stays linear in K;
* the wheel-rotation corrections of a chunk are one vector variable, under a smoothness
  prior on consecutive steps (R) and a size prior (the ±5 % bound, softened), both linear
  C++ factors. One variable per chunk rather than per step keeps the elimination and the
  optimizer's per-call copies of the values small (``NOTES.md``).

Levenberg–Marquardt starts from zero corrections (the measured inputs), as the paper's QP
solver does.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import GraphcalError, check_settings
from graphcal.factors import (
    OdometryChunkError,
    chunk_boundary_smoothness,
    chunk_correction_prior,
    odometry_chunk_factor,
    pose2_from_state,
    size_sigmas,
)
from graphcal.model import integrate
from graphcal.pipeline.solve import solve_lm


def correction_key(chunk: int) -> int:
    """Key of the ``2L``-vector of wheel-rotation corrections of ``chunk``."""
    return gtsam.symbol("c", chunk)


def boundary_key(chunk: int) -> int:
    """Key of the Pose2 at the start of ``chunk`` (chunk 0 starts at the held first pose)."""
    return gtsam.symbol("b", chunk)


@dataclass(frozen=True)
class InputEstimationSettings:
    """Weights and limits of the input estimation (paper §4.4).

    Attributes:
        tracking_weights: Q = diag(q_px, q_py, q_psi); the paper uses (1, 1, 1) in Step 2 and
            (1, 1, 10) in Step 4.
        smoothness_weight: R on the change of each corrected wheel rotation (paper: 1000).
        input_bound: relative bound on the corrections (paper: inputs within ±5 %); used as the
            sigma of the size prior.
        chunk_steps: steps per Python factor.
        continuity_sigmas: sigmas ``[m, m, rad]`` of the chunk-boundary continuity. Tight next
            to the tracking sigmas (1 m for q = 1), but not so tight that millimetre
            mismatches after a nonlinear step make Levenberg–Marquardt reject it: measured on
            24 km of synthetic segments, 1 cm / 1 mrad reaches the optimum of 0.1 mm / 0.01
            mrad within 0.3 % in 3 iterations instead of 14.
        max_iterations: Levenberg–Marquardt iteration limit (paper: 10).
    """

    tracking_weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    smoothness_weight: float = 1000.0
    input_bound: float = 0.05
    chunk_steps: int = 50
    continuity_sigmas: tuple[float, float, float] = (1e-2, 1e-2, 1e-3)
    max_iterations: int = 10

    def __post_init__(self) -> None:
        check_settings(
            "input_estimation",
            positive_vectors={
                "tracking_weights": self.tracking_weights,
                "continuity_sigmas": self.continuity_sigmas,
            },
            positive={"smoothness_weight": self.smoothness_weight, "input_bound": self.input_bound},
            at_least_one={"chunk_steps": self.chunk_steps, "max_iterations": self.max_iterations},
        )


@dataclass(frozen=True)
class InputEstimate:
    """Result of one input estimation.

    Attributes:
        corrections: ``(K, 2)`` corrections [rev] to ``[n_rl, n_rr]``.
        states: ``(K+1, 3)`` model states driven by the corrected inputs from the held start.
        iterations: Levenberg–Marquardt iterations used.
    """

    corrections: np.ndarray
    states: np.ndarray
    iterations: int


def chunk_bounds(n_steps: int, chunk_steps: int) -> np.ndarray:
    """Chunk boundaries ``[0, ..., n_steps]``; the last chunk absorbs a short remainder."""
    bounds = [*range(0, n_steps, chunk_steps), n_steps]
    if len(bounds) > 2 and bounds[-1] - bounds[-2] < chunk_steps // 2:
        bounds.pop(-2)
    return np.asarray(bounds)


def build_input_estimation_graph(
    poses: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    settings: InputEstimationSettings,
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, np.ndarray]:
    """The graph of :func:`estimate_inputs`, its initial values and the chunk bounds."""
    n_steps = len(inputs)
    tracking_sigmas = 1.0 / np.sqrt(np.asarray(settings.tracking_weights, float))
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    measured = inputs[:, :2]
    smooth_sigma = 1.0 / np.sqrt(settings.smoothness_weight)
    sizes = size_sigmas(measured, settings.input_bound)
    nominal = integrate(poses[0], inputs, theta)  # the paper's nominal trajectory
    bounds = chunk_bounds(n_steps, settings.chunk_steps)
    n_chunks = len(bounds) - 1
    for j in range(n_chunks):
        a, b = int(bounds[j]), int(bounds[j + 1])
        last = j == n_chunks - 1
        values.insert(correction_key(j), np.zeros(2 * (b - a)))
        graph.add(
            chunk_correction_prior(correction_key(j), measured[a:b], sizes[a:b], smooth_sigma)
        )
        if not last:
            c = int(bounds[j + 2])
            graph.add(
                chunk_boundary_smoothness(
                    correction_key(j),
                    b - a,
                    measured[b - 1],
                    correction_key(j + 1),
                    c - b,
                    measured[b],
                    smooth_sigma,
                )
            )
        if j > 0:
            values.insert(boundary_key(j), pose2_from_state(nominal[a]))
        error = OdometryChunkError(
            inputs[a:b],
            poses[a : b + 1],
            start_state=poses[0] if j == 0 else None,
            reference_heading=float(nominal[a, 2]),
            has_end=not last,
            has_corrections=True,
            theta=theta,
            corrections_as_vector=True,
        )
        keys = [] if j == 0 else [boundary_key(j)]
        keys += [] if last else [boundary_key(j + 1)]
        keys.append(correction_key(j))
        graph.add(
            odometry_chunk_factor(
                error, keys, tracking_sigmas, np.asarray(settings.continuity_sigmas, float)
            )
        )
    return graph, values, bounds


def estimate_inputs(
    poses: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    settings: InputEstimationSettings | None = None,
) -> InputEstimate:
    """Estimate the wheel rotations of one segment with theta fixed (paper eq. 14).

    Args:
        poses: measured states ``(K+1, 3)``; row 0 is the held initial state.
        inputs: measured inputs ``(K, 4)``.
        theta: the fixed parameters ``[c_e, c_d, t_r, d]`` (SI).
        settings: weights and limits.

    Raises:
        GraphcalError: if the solve fails numerically.
    """
    settings = settings or InputEstimationSettings()
    poses, inputs = np.asarray(poses, float), np.asarray(inputs, float)
    graph, values, bounds = build_input_estimation_graph(poses, inputs, theta, settings)
    result, iterations = solve_lm(graph, values, settings.max_iterations, 1e-6, "input estimation")
    corrections = np.concatenate(
        [result.atVector(correction_key(j)) for j in range(len(bounds) - 1)]
    ).reshape(-1, 2)
    if not np.all(np.isfinite(corrections)):
        raise GraphcalError("input estimation produced non-finite corrections")
    corrected = inputs.copy()
    corrected[:, :2] += corrections
    states = integrate(poses[0], corrected, theta)
    return InputEstimate(corrections, states, iterations)
