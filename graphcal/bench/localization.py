"""Benchmark of the localization factors: the smoothing example with each kind of odometry factor.

A Python factor inside GTSAM's optimizers costs ~20–50 µs plus a copy of the optimizer's
``Values`` per call (``docs/performance.md``), so in a graph of N keyframes an iteration grows
as N². The items solve the same GNSS + wheel-odometry smoothing graph (5 Hz keyframes over a
40 Hz drive) with:

* ``"reintegrating"`` — one Python factor per interval that integrates the raw inputs at
  every call (:class:`~graphcal.factors.ChunkOdometryFactor` with no measured poses: what
  graphcal's keyframe factor was before the preintegration);
* ``"preintegrated"`` — :class:`~graphcal.factors.WheelOdometryFactor` (theta a variable);
* ``"between"`` — theta fixed: built-in ``gtsam.BetweenFactorPose2`` from the preintegration.

Each solve runs under GTSAM's own Levenberg–Marquardt optimizer (``driver="gtsam"``, where the
``Values`` copies show) or driven from Python (``driver="python"``, what graphcal's smoothing
uses; :func:`graphcal.graph.optimization.solve.solve_lm`).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.factors import ChunkOdometryFactor, OdometryChunk, theta_prior_factor
from graphcal.factors.preintegration import DEFAULT_FLOOR_SIGMAS
from graphcal.graph.construction.keyframes import gnss_keyframes
from graphcal.graph.construction.keys import THETA, keyframe
from graphcal.graph.optimization.solve import Driver, solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.localization.keyframe_odometry import keyframe_odometry_factors, odometry_covariance
from graphcal.localization.values import insert_states, states_from_values
from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_PRIOR_SIGMAS

FACTOR_KINDS = ("reintegrating", "preintegrated", "between")


@dataclass(frozen=True)
class SmoothingTiming:
    """One solve of the smoothing graph: wall time [s], LM iterations, smoothed states."""

    seconds: float
    iterations: int
    states: np.ndarray
    theta: np.ndarray


def _reintegrating_factors(
    log: DriveLog, keyframes: np.ndarray, keys: list[int], theta_key: int | None, theta
) -> list[gtsam.CustomFactor]:
    """Per interval one Python factor that integrates the raw inputs at every call; world-frame
    error with the propagated covariance."""
    out = []
    for i, (a, b) in enumerate(itertools.pairwise(keyframes)):
        inputs = log.inputs[a:b]
        start = np.array([0.0, 0.0, log.psi[a]])
        covariance = odometry_covariance(start, inputs, theta, floor_sigmas=DEFAULT_FLOOR_SIGMAS)
        chunk = OdometryChunk(inputs, reference_heading=float(log.psi[a]))
        slot = theta if theta_key is None else theta_key
        factor = ChunkOdometryFactor(chunk, keys[i], slot, end=keys[i + 1])
        noise = gtsam.noiseModel.Gaussian.Covariance(covariance)
        out.append(gtsam.CustomFactor(noise, factor.keys, factor))
    return out


def solve_smoothing(
    log: DriveLog,
    kind: str,
    theta: np.ndarray,
    estimate_theta: bool,
    gnss_rate_hz: float = 5.0,
    gnss_sigma: float = 0.2,
    driver: Driver = "gtsam",
) -> SmoothingTiming:
    """Build and solve the smoothing graph with odometry factors of ``kind`` under the
    Levenberg–Marquardt ``driver``; time it."""
    if kind not in FACTOR_KINDS:
        raise ValueError(f"kind must be one of {FACTOR_KINDS}, got {kind!r}")
    if kind == "between" and estimate_theta:
        raise ValueError("a BetweenFactorPose2 needs theta fixed")
    start = time.perf_counter()
    keyframes = gnss_keyframes(log, gnss_rate_hz)
    keys = [keyframe(i) for i in range(len(keyframes))]
    theta = np.asarray(theta, float)
    theta_key = THETA if estimate_theta else None
    graph = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Isotropic.Sigma(2, gnss_sigma)
    for key, k in zip(keys, keyframes, strict=True):
        graph.add(gtsam.PoseTranslationPrior2D(key, gtsam.Point2(log.px[k], log.py[k]), noise))
    if kind == "reintegrating":
        factors = _reintegrating_factors(log, keyframes, keys, theta_key, theta)
    else:
        factors = keyframe_odometry_factors(log, keyframes, keys, theta_key, theta=theta)
    for factor in factors:
        graph.add(factor)
    values = gtsam.Values()
    insert_states(values, keys, log.poses[keyframes])
    if estimate_theta:
        values.insert(THETA, theta)
        graph.add(theta_prior_factor(THETA, THETA_PRIOR_SIGMAS, theta))
    options = SolveOptions(50, 1e-8, f"smoothing ({kind})")
    result, outcome = solve_lm(graph, values, options, driver=driver)
    seconds = time.perf_counter() - start
    states = states_from_values(result, keys, float(log.psi[keyframes[0]]))
    solved_theta = np.asarray(result.atVector(THETA)) if estimate_theta else theta
    return SmoothingTiming(seconds, outcome.iterations, states, solved_theta)
