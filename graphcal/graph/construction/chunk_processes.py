"""The slowly varying quantities of a segment graph, one value per chunk (or chunk
boundary) under a Gauss–Markov chain (:mod:`graphcal.graph.construction.gauss_markov`): the rear
wheels' slip scales and the error the fixes share."""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.graph.construction import keys
from graphcal.graph.construction.chunking import chunk_bounds
from graphcal.graph.construction.gauss_markov import gauss_markov_step, stationary_prior
from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.graph.construction.slip import slip_prior_factor, slip_step_factor
from graphcal.log.segments import SegmentData


def add_slip_priors(
    graph: gtsam.NonlinearFactorGraph,
    s: int,
    bounds: np.ndarray,
    dt: float,
    spec: SegmentGraphSpec,
) -> None:
    """Priors of segment ``s``'s slip scales, one 2-vector per chunk of ``bounds`` (steps
    ``dt`` [s]; :mod:`graphcal.graph.construction.slip`: stationary at the first chunk, Gauss–Markov
    steps after)."""
    sigma = float(spec.slip_sigma)
    graph.add(slip_prior_factor(keys.segment_slip(s, 0), sigma))
    for j in range(1, len(bounds) - 1):
        duration = float((bounds[j] - bounds[j - 1]) * dt)
        graph.add(
            slip_step_factor(
                keys.segment_slip(s, j - 1),
                keys.segment_slip(s, j),
                duration,
                sigma,
                spec.slip_time,
            )
        )


def fix_error_keys(
    data: SegmentData, s: int, bounds: np.ndarray, tied_before: bool, chunk_steps: int | None
) -> list[int]:
    """Keys of the fixes' error at segment ``s``'s chunk boundaries ``bounds`` (its start,
    then each chunk's end): the first is the last of the segment before when the two are
    tied (``tied_before``; that one chunked by ``chunk_steps`` too)."""
    found = [keys.segment_fix_offset(s, j) for j in range(len(bounds))]
    if tied_before:
        before = len(chunk_bounds(int(data.n_steps[s - 1]), chunk_steps)) - 1
        found[0] = keys.segment_fix_offset(s - 1, before)
    return found


def add_fix_error_priors(
    graph: gtsam.NonlinearFactorGraph,
    nodes: list[int],
    bounds: np.ndarray,
    dt: float,
    tied_before: bool,
    spec: SegmentGraphSpec,
) -> None:
    """Priors of the error a segment's fixes share, a 2-vector at each chunk boundary
    (``nodes``, :func:`fix_error_keys`; linear between): a Gauss–Markov chain that goes on
    from the segment before when the two are tied (one trajectory), else starts
    stationary."""
    sigma, tau = float(spec.fix_error_sigma), float(spec.fix_error_time)
    if not tied_before:
        graph.add(stationary_prior(nodes[0], 2, sigma))
    for j, duration in enumerate(np.diff(bounds) * dt):
        graph.add(gauss_markov_step(nodes[j], nodes[j + 1], 2, float(duration), sigma, tau))
