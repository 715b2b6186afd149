"""One joint graph per batch: compensation and calibration in a single solve.

The paper needs five stages because its optimal control assumes a known theta and a correct
initial pose. In a factor graph all of them can be variables at once:

* theta, a 4-vector under a weak prior at the nominal values;
* per segment, its start pose (Pose2) under the measured pose (world-frame position and
  heading priors, the paper's W);
* the segment cut into chunks of ``chunk_steps`` steps, one factor each: eq. (1) from the
  chunk's start pose, tracking the measured poses, continuous at the chunk boundaries;
* per chunk, one vector of wheel-rotation corrections under their noise prior (minus the
  noise: zero-mean), optionally with the paper's smoothness prior on Δu.

Levenberg–Marquardt solves it once: theta, start poses and true rotations together.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.graph.construction.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.optimization.solve_options import FAR_OFF_CHI2, SolveOptions
from graphcal.graph.solution.covariance import with_covariance
from graphcal.graph.solution.estimates import SolvedGraph, ThetaEstimate
from graphcal.graph.solution.observability import (
    Observability,
)
from graphcal.graph.solution.segment_solve import BuilderStart
from graphcal.log.segments import SegmentData
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.residual_noise import ResidualNoise, residual_noise
from graphcal.pipeline.solvers.robust import FirstRound, RoundsStart, solve_segment_graph_robust
from graphcal.pipeline.solvers.slip_screen import SlipTest, UnseenSlip, with_slip_if_shown
from graphcal.pipeline.solvers.warm_start import warm_start_solution
from graphcal.progress import Progress, reports_progress, say

#: A first solve whose noise levels are read again after it (``stop_if``) stops where it
#: creeps at a χ²/dof above this (residuals 5× their weights' σ;
#: :class:`~graphcal.graph.optimization.levenberg_marquardt.CreepWatch`): a point to read
#: the noise at, not a minimum to judge.
MISWEIGHTED_CHI2 = 25.0
#: ... and stops where an iteration lowers χ² by less than this share while its χ²/dof is
#: far above 1 (:func:`~graphcal.graph.optimization.levenberg_marquardt.noise_read`): where
#: the noise its residuals show is read. Where that noise changes nothing, it goes on.
NOISE_READ_TOLERANCE = 1e-3


def always_stop(noise: ResidualNoise) -> bool:
    """A :func:`solve_joint` ``stop_if`` that ends the solve at its first robust round
    whatever its noise: its caller solves again in any case."""
    return True


@dataclass(frozen=True)
class JointCalibration(ThetaEstimate):
    """Result of a joint solve (SI): a theta estimate whose covariance has the
    start poses and wheel-rotation corrections marginalized, and its verdict.

    Attributes:
        observability: which parameters the data determined (from ``covariance``).
        fix_weights: ``(S, K+1)`` robust weight of each measured pose of the segments, or
            ``None`` if every fix kept weight 1.
        slip_modelled: the solve has slip scales.
        slip_test: with ``slip = "auto"``, the slip screen's test on the screened segments
            (all, or :data:`~graphcal.pipeline.solvers.slip_screen.SLIP_SCREEN_SEGMENTS` spread over
            a longer log; ``None`` otherwise).
        noise: the noise the residuals show (:class:`ResidualNoise`), before slip was
            modelled: variance components of the solve. The fixes' RMS is the true σ within
            4 % at 1–10 Hz on 12 km simulated drives, whatever the settings assumed.
    """

    observability: Observability
    fix_weights: np.ndarray | None = None
    slip_modelled: bool = False
    slip_test: SlipTest | None = None
    noise: ResidualNoise = field(default_factory=lambda: ResidualNoise())

    @property
    def position_noise(self) -> float | None:
        """The RMS per axis [m] of the fixes' position residuals (:attr:`noise`)."""
        return self.noise.position


@reports_progress
def calibrate_joint(
    data: SegmentData,
    settings: JointSettings | None = None,
    workers: int = 1,
    progress: Progress | None = None,
) -> JointCalibration:
    """Estimate theta, start poses and wheel-rotation corrections of a batch in one solve
    (with the time offset, lever arm and heading biases, and robust fix weights, if the
    settings ask for them). ``workers``: processes the segments are shared out among (the
    result does not depend on it); ``progress`` gets a line per iteration of a long solve.

    Raises:
        CalibrationFailed: if the solve fails or gives an implausible theta.
    """
    return solve_joint(data, settings, workers)[0]


@reports_progress
def solve_joint(
    data: SegmentData,
    settings: JointSettings | None = None,
    workers: int = 1,
    progress: Progress | None = None,
    start: gtsam.Values | None = None,
    rounds_start: RoundsStart | None = None,
    same_segments: bool = False,
    stop_if: Callable[[ResidualNoise], bool] | None = None,
) -> tuple[JointCalibration, gtsam.Values]:
    """:func:`calibrate_joint`, with the solution's value of every variable of the graph (the
    point the joint batches linearize at). ``start``: a solution of the same segments under
    other settings whose graph-wide variables the solve starts from, not a warm start's
    (with ``same_segments``, a solution of these very segments: every variable; the real
    robot's re-solve 4 → 3 iterations); ``rounds_start``: its fix weights and theta's σ
    (:func:`~graphcal.pipeline.solvers.robust.solve_robust`); ``stop_if``: given the first
    robust round's residual noise, whether the solve ends there, without more rounds or the
    slip screen, because the caller solves again under other settings (the real robot's first
    solve: 4 more rounds and the screen, 2.3 s).

    The steps: the warm start (:mod:`graphcal.pipeline.solvers.warm_start`), the solve with robust
    fix weights (:mod:`graphcal.pipeline.solvers.robust`), the fixes' noise in its residuals, with
    ``slip = "auto"`` the slip screen (:mod:`graphcal.pipeline.solvers.slip_screen`), and theta's
    observability."""
    settings = settings or JointSettings()
    auto = settings.slip == "auto"
    limit, tolerance = settings.max_iterations, settings.tolerance
    options = SolveOptions(limit, tolerance, "joint solve", workers, report_iterations=True)
    # A solve whose noise is read again after it stops where it creeps under too tight weights
    head = options
    if stop_if is not None:
        # where the caller solves again only if the noise read changes, read it near χ²/dof 1
        # too: the next solve's optimum moves then anyway (one that always follows, as after
        # a reading solve, starts from this one's polish)
        above = FAR_OFF_CHI2 if stop_if is always_stop else 0.0
        head = dataclasses.replace(
            options,
            misweighted_chi2=MISWEIGHTED_CHI2,
            noise_read_tolerance=NOISE_READ_TOLERANCE,
            noise_read_chi2=above,
        )
    held = settings.held_names()
    first = _first_start(data, settings.graph_spec(), head, start, same_segments, held)
    solved, weights, noise, stopped = _robust_solve(
        data, settings, options, head, first, rounds_start, stop_if
    )
    statistic = None
    if auto and stopped:  # solved again under other settings: no slip screen here
        solved = with_covariance(solved, options.label, options.workers)
    elif auto:
        slip = settings.graph_spec(slip=True)
        unseen = UnseenSlip(settings.unseen_slip_sigma, settings.unseen_slip_time)
        solved, statistic = with_slip_if_shown(
            solved, data, weights, slip, settings.slip_alpha, options, unseen
        )
    observability = settings.observability(solved.covariance)
    calibration = JointCalibration(
        solved.theta,
        solved.covariance,
        solved.start_states,
        solved.outcome,
        solved.initial_error,
        solved.final_error,
        observability,
        weights,
        solved.built.spec.slip_sigma is not None,
        statistic,
        noise,
        degrees_of_freedom=solved.degrees_of_freedom,
        nuisance=solved.nuisance,
    )
    return calibration, solved.result


def _first_start(
    data: SegmentData,
    spec: SegmentGraphSpec,
    options: SolveOptions,
    start: gtsam.Values | None,
    same_segments: bool,
    held: tuple[str, ...] = (),
) -> BuilderStart:
    """Where :func:`solve_joint` starts: a warm start's (graph-wide variables, and its
    solution where it solved every segment; the parameters ``held`` at their prior), or
    ``start``'s."""
    if start is None:
        shared, solution = warm_start_solution(data, spec, options, held)
    else:
        shared = {k: np.asarray(start.atVector(k)) for k in shared_keys(spec) if start.exists(k)}
        solution = start if same_segments else None
        say(f"  start: the previous solve's {'solution' if same_segments else 'theta'}")
    if solution is None:
        return BuilderStart.warm(shared)
    return BuilderStart(shared or {}, gauss_newton_first=True, solution=solution)


def _robust_solve(
    data: SegmentData,
    settings: JointSettings,
    options: SolveOptions,
    head: SolveOptions,
    first: BuilderStart,
    rounds_start: RoundsStart | None,
    stop_if: Callable[[ResidualNoise], bool] | None,
) -> tuple[SolvedGraph, np.ndarray | None, ResidualNoise, bool]:
    """:func:`solve_joint`'s robust solve from ``first`` (``options``: every solve's; ``head``:
    the first's): the solution (its covariance unless the slip screen follows), weights, residual
    noise, and whether ``stop_if`` ended it."""
    stopped: list[bool] = []

    def first_round_ends(solved: SolvedGraph, weights: np.ndarray | None) -> bool:
        stopped.append(stop_if is not None and stop_if(residual_noise(solved, data, weights)))
        return stopped[-1]

    def reweights(solved: SolvedGraph, segments: SegmentData) -> bool:
        return stop_if(residual_noise(solved, segments, segments.fix_weights))

    solved, weights, _ = solve_segment_graph_robust(
        data,
        settings.graph_spec(),
        options,
        settings.robust_threshold,
        covariance=settings.slip != "auto",
        start=first,
        rounds_start=rounds_start,
        first_round=None if stop_if is None else FirstRound(first_round_ends, head, reweights),
    )
    noise = residual_noise(solved, data, weights)
    if stop_if is not None and not stopped:  # solved once, without robust rounds
        stopped.append(stop_if(noise))
    return solved, weights, noise, any(stopped)
