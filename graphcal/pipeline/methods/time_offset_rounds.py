"""Rounds of the wheels' time offsets: the whole-log solve repeated with each run's wheels
shifted by the whole samples of the offset it finds, until what is left is under a sample
(the graph's first-order shift covers that)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.log.segments import SegmentData, gather_segments
from graphcal.log.timing import shift_wheel_rotations, whole_samples
from graphcal.pipeline.methods.prepare import PreparedLog, runs_label
from graphcal.pipeline.methods.sensor_estimates import detected_offsets, sensor_estimates
from graphcal.pipeline.solvers.joint import JointCalibration, solve_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.residual_noise import ResidualNoise
from graphcal.pipeline.solvers.robust import RoundsStart
from graphcal.progress import say

#: Whole-log solves at most, each after shifting the wheels by the offset found so far.
OFFSET_ROUNDS = 4
#: A run's wheels are shifted again only when the offset its solve finds beyond their shift
#: exceeds this fraction of a sample interval: the graph's first-order shift covers less. A
#: rest near half a sample otherwise rounds up and down from round to round (the real robot's
#: run at +74.5 ms with 50 ms samples went 50 → 100 → 50 → 100 ms, four solves for one).
SHIFT_AGAIN_SAMPLES = 0.75


@dataclass(frozen=True)
class StoppedAt:
    """Where a whole-log solve stopped, for a solve of the same segments to go on from.

    Attributes:
        values: its solution (of the log shifted by ``shift``: every variable the next
            solve's start; after another shift, the graph-wide ones), or ``None``.
        shift: ``(runs,)`` whole-sample shift [s] of each run's wheels.
        rounds: where its robust rounds stopped, or ``None``.
    """

    values: gtsam.Values | None
    shift: np.ndarray
    rounds: RoundsStart | None


def rounds_start(whole: JointCalibration) -> RoundsStart:
    """Where ``whole``'s robust rounds stopped: its fix weights and theta's σ."""
    sigma = None if whole.covariance is None else whole.theta_sigma
    return RoundsStart(whole.fix_weights, sigma)


Solved = tuple[JointCalibration, gtsam.Values, SegmentData, np.ndarray]


def solve_with_time_offset(
    prepared: PreparedLog,
    settings: JointSettings,
    workers: int = 1,
    start: StoppedAt | None = None,
    rounds: int = OFFSET_ROUNDS,
    solved: tuple[JointCalibration, gtsam.Values] | None = None,
    stop_if: Callable[[ResidualNoise], bool] | None = None,
) -> Solved:
    """The whole-log solve; while it detects a wheel time offset, the wheels are shifted by
    the offset found so far, rounded to whole samples, and the solve repeated, so that the
    graph's first-order shift only covers the rest (at most about half a sample). A log of
    several runs has an offset per run, each run shifted by its own.

    Whole samples because a shift is exact only for them: between samples it averages
    neighbouring rotations, which smooths their noise (tick quantization above all) away
    from what the correction prior assumes. On a 24 km drive with 96-tick encoders, slow slip
    and 62.5 ms latency, fractional shifting moved t_r by 4.3σ (``docs/defects.md``).

    ``prepared``: the log, its selected segments gathered and the fixes' weights. Returns
    the last solve, its values, the segments it solved and the shift [s] of each run's
    wheels. Each solve after the first starts from the one before (its values and fix
    weights); the first from ``start`` (where a solve of the same segments under other noise
    levels stopped), if given; ``solved``: that solve itself, under these settings (the
    rounds go on from it). A run is shifted again only while its solve finds more than
    :data:`SHIFT_AGAIN_SAMPLES` of a sample beyond its shift; ``rounds`` solves at most.
    ``stop_if``: the first solve's (:func:`~graphcal.pipeline.solvers.joint.solve_joint`)."""
    log, selected, flagged = prepared.log, prepared.selected, prepared.fix_weights
    data = prepared.data
    start = start or StoppedAt(None, np.zeros(log.runs), None)
    shift = start.shift
    if shift.any():
        data = gather_segments(shift_wheel_rotations(log, shift), selected, flagged)
    if solved is None:
        whole, values = _whole_log_solve(
            data, settings, workers, start.values, start.rounds, True, stop_if
        )
    else:
        whole, values = solved
    for _ in range(rounds - 1):
        found = detected_offsets(
            sensor_estimates(whole.nuisance, settings.max_sigma_ratio), log.runs
        )
        again = np.abs(found) > SHIFT_AGAIN_SAMPLES * log.dt
        rounded = np.where(again, [whole_samples(s, log.dt) for s in shift + found], shift)
        if np.array_equal(rounded, shift):
            break  # what is left is less than a sample: the graph's first order covers it
        moved = np.rint(np.abs(rounded - shift) / log.dt)  # whole samples, each run
        screened = _screened_before(whole, settings, moved <= 1)
        shift = rounded
        shown = ", ".join(f"{s * 1e3:+.1f}" for s in shift)
        again = f"wheels shifted by {shown} ms{runs_label(log.runs)}"
        say(f"{again}; solved again from the shifted log")
        data = gather_segments(shift_wheel_rotations(log, shift), selected, flagged)
        round_settings = settings if screened is None else dataclasses.replace(settings, slip="on")
        whole, values = _whole_log_solve(data, round_settings, workers, values, rounds_start(whole))
        if screened is not None:
            whole = dataclasses.replace(whole, slip_test=screened.slip_test, noise=screened.noise)
    return whole, values, data, shift


def _screened_before(
    whole: JointCalibration, settings: JointSettings, by_a_sample: np.ndarray
) -> JointCalibration | None:
    """``whole``, if the next round keeps its slip verdict: its slip screen found slip, and
    no run's wheels move by more than a sample (``by_a_sample``, per run) — what the time
    offset's first-order term already covered as the screen ran, so the screen would find
    what it found. The next round then models slip from its start, with this screen's test
    and residual noise (before slip was modelled), instead of solving without slip, screening
    again and solving once more with it (the real robot's round after its one-sample shift:
    3 iterations, the screen and 3 more)."""
    if settings.slip != "auto" or not whole.slip_modelled or whole.slip_test is None:
        return None
    return whole if np.all(by_a_sample) else None


def _whole_log_solve(
    data: SegmentData,
    settings: JointSettings,
    workers: int,
    start: gtsam.Values | None = None,
    rounds_start: RoundsStart | None = None,
    same_segments: bool = False,
    stop_if: Callable[[ResidualNoise], bool] | None = None,
) -> tuple[JointCalibration, gtsam.Values]:
    """The joint solve over all ``data`` (its segments shared out among ``workers``
    processes; from the graph-wide variables of ``start`` — every variable, with
    ``same_segments``: ``start`` solved ``data`` itself — and the robust rounds from
    ``rounds_start``, if given; ``stop_if`` as :func:`solve_joint`'s), with the progress
    lines a user waits for, and the solution's values."""
    say(f"joint solve over all {len(data)} selected segments")
    result, values = solve_joint(
        data,
        settings,
        workers,
        start=start,
        rounds_start=rounds_start,
        same_segments=same_segments,
        stop_if=stop_if,
    )
    chi2 = result.chi2_per_dof
    fit = "" if chi2 is None else f", χ²/dof {chi2:.2f}"
    if result.outcome.crept:
        fit += " (stopped: it crept under weights far too tight for its residuals)"
    say(f"  {result.iterations} iterations{fit}")
    return result, values
