"""Robust pose measurements: outlying GNSS fixes down-weighted by iterative reweighting.

A multipath fix 10–50 m off pulls a least-squares calibration by millimetres of
circumference. graphcal's chunk factors track hundreds of fixes each, so a GTSAM robust noise
model (which weights a whole factor) would drop good fixes with the bad one; instead each
fix's position sigma gets its own weight, found by iteratively reweighted least squares
(what ``gtsam.noiseModel.Robust`` does per factor, here per fix):

* solve; take each fix's position residual ``r`` (predicted antenna position minus measured)
  in units of the residuals' own scale ``σ̂`` (the larger of the configured position sigma
  and a robust estimate: median |r| / 1.1774, the median of a 2-D Gaussian's norm);
* weight ``w = 1`` for ``|r| ≤ k σ̂`` and ``w = (k σ̂ / |r|)²`` beyond — a quadratic core
  with a Cauchy-like tail, whose influence ``w r`` falls as ``1/|r|``, so a gross outlier
  has almost none (Huber's stays at ``k σ̂``);
* solve again from the last solution with those weights, until no weight changes by more
  than :data:`WEIGHT_TOLERANCE` (at most ``rounds`` solves).

Weights the data came with (``SegmentData.fix_weights``: spikes the loader flagged) are
upper bounds: a fix keeps the smaller of its given and its residual's weight.

A drive without fixes beyond ``k σ̂`` is solved once, exactly as without robust weights.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.graph.optimization.solve_options import SolveOptions, SolveStatus
from graphcal.graph.solution.covariance import covariance_from_information, with_covariance
from graphcal.graph.solution.estimates import SolvedGraph
from graphcal.graph.solution.segment_solve import BuilderStart, ValuesStart, solve_segment_graph
from graphcal.log.segments import SegmentData

#: Median of the norm of a 2-D standard Gaussian, sqrt(2 ln 2).
RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))
#: Reweighting stops when no fix's weight changes by more than this.
WEIGHT_TOLERANCE = 0.02
#: ... or when a round moved no parameter of theta by more than this share of its σ (known
#: from an earlier solve of the same segments): a few of 15,000 fixes of a real robot,
#: neighbours in a spike, trade weight from round to round for five rounds while theta moves
#: by 0.02σ.
THETA_TOLERANCE = 0.05


@dataclass(frozen=True)
class RoundsStart:
    """Where the robust rounds of a solve start, from a solve of the same segments (a
    shifted log, other noise levels).

    Attributes:
        weights: ``(S, K+1)`` the fix weights it found: the first round's.
        theta_sigma: ``(4,)`` its theta's σ, or ``None``: rounds stop once one moves no
            parameter by more than :data:`THETA_TOLERANCE` of it.
    """

    weights: np.ndarray | None
    theta_sigma: np.ndarray | None = None


@dataclass(frozen=True)
class FirstRound:
    """What the caller of a robust solve does after its first solve.

    Attributes:
        ends: ``ends(solved, weights)``: whether the rounds end after the first (a solve
            under other settings follows; :func:`solve_robust`'s ``stop_after_first``).
        options: the first solve's options (``SolveOptions.misweighted_chi2`` and
            ``noise_read_tolerance`` set: it may stop creeping under too tight weights, or
            where its noise is read), or ``None``:
            every solve's.
        reweights: ``reweights(solved, segments)``: after a first solve that stopped so,
            whether the caller solves again under the noise its residuals show (else that
            solve goes on to its minimum).
    """

    ends: Callable[[SolvedGraph, np.ndarray | None], bool]
    options: SolveOptions | None = None
    reweights: Callable[[SolvedGraph, SegmentData], bool] | None = None


def residual_scale(residuals: np.ndarray, valid: np.ndarray, floor: float) -> float:
    """The position residuals' scale σ̂ [m]: ``floor``, or the robust per-axis sigma of the
    residual norms ``(S, K+1, 2)`` over ``valid`` samples if that is larger."""
    norms = np.linalg.norm(residuals, axis=-1)[valid]
    if not len(norms):
        return floor
    return max(floor, float(np.median(norms)) / RAYLEIGH_MEDIAN)


def fix_weights(residuals: np.ndarray, scale: float, threshold: float) -> np.ndarray:
    """Weights ``(S, K+1)`` in (0, 1] of fixes with position residuals ``(S, K+1, 2)``: 1
    within ``threshold · scale``, ``(threshold · scale / |r|)²`` beyond."""
    norms = np.linalg.norm(residuals, axis=-1)
    limit = threshold * scale
    with np.errstate(divide="ignore"):
        return np.where(norms <= limit, 1.0, (limit / np.maximum(norms, limit)) ** 2)


def solve_robust(
    data: SegmentData,
    spec: SegmentGraphSpec,
    solve: Callable[..., SolvedGraph],
    threshold: float,
    rounds: int = 5,
    start: RoundsStart | None = None,
    stop_after_first: Callable[[SolvedGraph, np.ndarray | None], bool] | None = None,
) -> tuple[SolvedGraph, np.ndarray | None, np.ndarray | None]:
    """Solve ``spec`` over ``data`` with robust fix weights.

    Args:
        data, spec: the segments and the graph's shape.
        solve: ``solve(data, initial) -> SolvedGraph`` without covariance (e.g. a bound
            :func:`~graphcal.graph.solution.segment_solve.solve_segment_graph`; ``initial`` is
            ``None`` or the last solution's values).
        threshold: ``k``: fixes within ``k σ̂`` keep weight 1.
        rounds: most solves.
        start: where an earlier solve of the same segments left the rounds
            (:class:`RoundsStart`): its weights the first solve's (each at most the given
            one), so that the rounds go on from where it stopped, not from weight 1.
        stop_after_first: given the first solve and the weights its residuals give (the
            second round's), whether the rounds end there: a solve under other settings
            follows and goes on from those weights (returned, though not yet solved with),
            or ``None``.

    Returns:
        The last solution, the weights ``(S, K+1)`` it used (``None``: every fix kept
        weight 1 and the drive was solved once; the given weights if none changed) and the
        fixes' position residuals ``(S, K+1, 2)`` at it, if the last round computed them
        there (else ``None``).
    """
    floor = float(spec.tracking_sigmas[0])
    given = np.ones(data.valid.shape) if data.fix_weights is None else data.fix_weights
    weights = data.fix_weights
    start = start or RoundsStart(None)
    if start.weights is not None:
        weights = np.minimum(given, start.weights)
        data = dataclasses.replace(data, fix_weights=weights)
    solution = solve(data, None)
    theta_sigma = start.theta_sigma
    if theta_sigma is None:
        theta_sigma = _known_theta_sigma(solution)
    residuals = None
    for round_ in range(rounds - 1):
        residuals = solution.built.fix_residuals(solution.result, solution.partitioned)
        # The scale from fixes not flagged already (samples between fixes have none).
        usable = data.position_fixes() & (given >= 1.0)
        scale = residual_scale(residuals, usable, floor)
        new = np.where(data.valid, np.minimum(given, fix_weights(residuals, scale, threshold)), 1.0)
        old = given if weights is None else weights
        if np.max(np.abs(new - old)) <= WEIGHT_TOLERANCE:
            return solution, weights, residuals  # computed at this solution
        if round_ == 0 and stop_after_first is not None and stop_after_first(solution, new):
            return solution, new, None  # the next round's weights, for the solve after
        weights = new
        before = solution.theta
        solution = solve(dataclasses.replace(data, fix_weights=weights), solution.result)
        if _theta_settled(solution.theta - before, theta_sigma):
            return solution, weights, None
    return solution, weights, None


def _known_theta_sigma(solution: SolvedGraph) -> np.ndarray | None:
    """Theta's σ from the information the solve's last Gauss–Newton step left, where it
    left one (``None`` otherwise: computing it would cost a linearization). The first solve
    of a drive has no earlier σ: with this one, its rounds stop as a later solve's do (the
    real robot's first solve took 4 rounds of 0.5 s each, theta moving by under 0.05σ)."""
    partitioned = solution.partitioned
    information = None if partitioned is None else partitioned.known_information()
    if information is None:
        return None
    covariance = covariance_from_information(0.5 * (information + information.T))
    sigma = np.sqrt(np.diag(covariance)[:4])
    return sigma if np.all(np.isfinite(sigma)) else None


def _theta_settled(moved: np.ndarray, sigma: np.ndarray | None) -> bool:
    """A round ``moved`` theta by at most :data:`THETA_TOLERANCE` of ``sigma`` (never
    without one)."""
    if sigma is None or not np.all(np.isfinite(sigma)):
        return False
    return bool(np.all(np.abs(moved) <= THETA_TOLERANCE * np.asarray(sigma)))


def solve_segment_graph_robust(
    data: SegmentData,
    spec: SegmentGraphSpec,
    options: SolveOptions,
    threshold: float,
    *,
    covariance: bool = True,
    start: BuilderStart | None = None,
    rounds_start: RoundsStart | None = None,
    first_round: FirstRound | None = None,
) -> tuple[SolvedGraph, np.ndarray | None, np.ndarray | None]:
    """:func:`~graphcal.graph.solution.segment_solve.solve_segment_graph` (each solve as ``options``
    say) with robust fix weights (:func:`solve_robust`, whose three results it returns);
    ``threshold`` 0 solves once without them. ``start``: where the first solve starts (e.g.
    a warm start's graph-wide variables; default: the builder's values); ``rounds_start``:
    where the rounds start, as :func:`solve_robust`'s; ``first_round``: what the caller does
    after the first solve (:class:`FirstRound`)."""
    first = start or BuilderStart()
    first_round = first_round or FirstRound(lambda *_: False)
    reweights = first_round.reweights

    def solve(segments: SegmentData, initial) -> SolvedGraph:
        head = options
        if initial is None and first_round.options is not None:
            head = first_round.options
        solved = solve_segment_graph(
            segments,
            spec,
            head,
            start=first if initial is None else ValuesStart(initial),
            covariance=False,
        )
        if not solved.outcome.stopped_for_noise:
            return solved
        if reweights is not None and reweights(solved, segments):
            return solved
        # on from there: the graph as built, and undamped after a noise read's accepted
        # Gauss–Newton steps (a creeping solve's damping starts again)
        on = ValuesStart(
            solved.result, solved.built, solved.outcome.status is SolveStatus.NOISE_READ
        )
        rest = solve_segment_graph(segments, spec, options, start=on, covariance=False)
        return dataclasses.replace(rest, outcome=solved.outcome.then(rest.outcome))

    if threshold <= 0:
        solution, weights, residuals = solve(data, None), data.fix_weights, None
    else:
        solution, weights, residuals = solve_robust(
            data, spec, solve, threshold, start=rounds_start, stop_after_first=first_round.ends
        )
    if covariance:
        solution = with_covariance(solution, options.label, options.workers)
    return solution, weights, residuals
