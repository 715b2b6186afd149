"""The whole-log solve: the joint graph over all selected segments, with what it finds about
the sensors, corrected in the log for everything after it.

Top-down, :func:`solve_whole_log` runs:

1. time-offset rounds (:func:`solve_with_time_offset`): the joint solve
   (:func:`~graphcal.pipeline.solvers.joint.solve_joint`: warm start, robust reweighting of the
   fixes, slip screen), repeated with the wheels shifted by whole samples while it finds a time
   offset;
2. the noise the residuals show (:func:`~graphcal.pipeline.methods.noise_levels.with_noise_levels`:
   the fixes' white noise and the error they share, the heading's, the wheels') and, for a
   log whose lateral acceleration comes from the wheels (and whose d is estimated), that
   acceleration derived again with the solved theta; the rounds again if either changed the
   graph;
3. theta judged under the weak prior
   (:func:`~graphcal.pipeline.methods.held_at_prior.judged_with_what_is_held`): every parameter its
   posterior with its marginal σ, what the settings held at its prior
   (the vehicle's, the preparation's or a runaway's) not calibrated, its uncertainty in the
   others' σ;
4. the sensor estimates (time offset, lever arm; :mod:`graphcal.pipeline.methods.sensor_estimates`),
   the down-weighted fixes and the slip verdict, reported;
5. the log corrected by the estimates, and its segments gathered again with the solve's fix
   weights: what validation and the batches work on.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.graph.solution.plausibility import ImplausibleTheta
from graphcal.graph.solution.reduced_systems import ReducedSystems
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, Segments, gather_segments
from graphcal.log.timing import shift_wheel_rotations, whole_samples
from graphcal.model import wheel_lateral_acceleration
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.methods.agreement import (
    Agreement,
    agreement_line,
    segment_agreement,
    with_agreement,
)
from graphcal.pipeline.methods.held_at_prior import (
    data_determine,
    judged_with_what_is_held,
    without_an_unseen_lever_arm,
)
from graphcal.pipeline.methods.joint_batches import segment_systems
from graphcal.pipeline.methods.noise_levels import with_noise_levels
from graphcal.pipeline.methods.prepare import PreparedLog
from graphcal.pipeline.methods.sensor_estimates import (
    DownWeightedFixes,
    SensorEstimate,
    component_names,
    correct_log,
    detected_offsets,
    log_weights,
    measured_from,
    not_estimated,
    run_of,
    sensor_estimates,
)
from graphcal.pipeline.solvers.joint import JointCalibration, JointSettings, solve_joint
from graphcal.pipeline.solvers.robust import RoundsStart
from graphcal.progress import say
from graphcal.units import LengthUnit, length_unit

#: Whole-log solves at most, each after shifting the wheels by the offset found so far.
OFFSET_ROUNDS = 4
#: A run's wheels are shifted again only when the offset its solve finds beyond their shift
#: exceeds this fraction of a sample interval: the graph's first-order shift covers less. A
#: rest near half a sample otherwise rounds up and down from round to round (the real robot's
#: run at +74.5 ms with 50 ms samples went 50 → 100 → 50 → 100 ms, four solves for one).
SHIFT_AGAIN_SAMPLES = 0.75
#: Why a parameter that left its plausible range in the first solve is held at its prior.
RUNAWAY_REASON = "it left its plausible range in a free solve; held at its prior"


@dataclass(frozen=True)
class StoppedAt:
    """Where a whole-log solve stopped, for a solve of the same segments to go on from.

    Attributes:
        values: its solution (the graph-wide variables are taken), or ``None``.
        shift: ``(runs,)`` whole-sample shift [s] of each run's wheels.
        rounds: where its robust rounds stopped, or ``None``.
    """

    values: gtsam.Values | None
    shift: np.ndarray
    rounds: RoundsStart | None


def _rounds_start(whole: JointCalibration) -> RoundsStart:
    """Where ``whole``'s robust rounds stopped: its fix weights and theta's σ."""
    sigma = None if whole.covariance is None else whole.theta_sigma
    return RoundsStart(whole.fix_weights, sigma)


@dataclass(frozen=True)
class WholeLog:
    """The whole-log solve and the log it corrected (SI).

    Attributes:
        whole: the last whole-log joint solve.
        estimated: the sensor quantities it estimated with theta, the time offset the total
            (``"time_offset"`` [s], ``"lever_arm_longitudinal"``, ``"lever_arm_lateral"``
            [m]).
        down_weighted: the fixes it down-weighted as outliers.
        solved_log: the log it solved (its a_y derived again if from the wheels), uncorrected.
        corrected: what comes after it works on: the log corrected by the observable
            estimates, the settings with the fixes' noise it found, the fix weights it used
            (per sample of the log) and the segments gathered again from that log.
        systems: every selected segment reduced to the shared variables at the solution, in
            the batches' settings (:meth:`batch_data`, :meth:`batch_settings`): what the
            linearized batches and the agreement test are solved from.
        agreement: whether groups of the segments agree within their σ
            (:mod:`graphcal.pipeline.methods.agreement`); theta's σ are scaled by it.
    """

    whole: JointCalibration
    estimated: dict[str, SensorEstimate]
    down_weighted: DownWeightedFixes
    solved_log: DriveLog
    corrected: PreparedLog
    systems: ReducedSystems | None = None
    agreement: Agreement | None = None

    def batch_settings(self) -> JointSettings:
        """The joint settings of batches of this log: its fixes weighted as the solve found
        them (no robust rounds), its slip verdict, the rest of its time offset their prior,
        each segment on its own (its system reduced alone; a batch is any set of them)."""
        return dataclasses.replace(
            self.corrected.settings.joint,
            **_batch_time_offset(self.estimated, self.corrected.log.dt),
            robust_threshold=0.0,
            slip="on" if self.whole.slip_modelled else "off",
            tie_segments=False,
        )

    def batch_data(self) -> SegmentData:
        """The selected segments for batches whose graph has the time offset and lever arm
        as variables: the wheels shifted by the whole samples of the time offset (its rest the
        batches' prior), the antenna left where it is."""
        batch_log = correct_log(
            self.solved_log, self.estimated, in_whole_samples=True, move_antenna=False
        )
        return gather_segments(batch_log, self.corrected.selected, self.corrected.fix_weights)


def solve_whole_log(prepared: PreparedLog, workers: int) -> WholeLog:
    """The whole-log procedure of the module docstring on ``prepared``.

    Raises:
        CalibrationFailed: if a solve fails or gives an implausible theta.
    """
    log, settings = prepared.log, prepared.settings
    gathered, validation = prepared.data, prepared.validation
    held = dict(prepared.held)
    try:
        whole, values, data, offset = solve_with_time_offset(
            log, gathered, prepared.selected, prepared.fix_weights, settings.joint, workers
        )
    except ImplausibleTheta as runaway:
        settings = dataclasses.replace(settings, joint=settings.joint.holding(runaway.names))
        whole, values, data, offset = _holding_a_runaway(prepared, settings.joint, runaway, workers)
        held.update(dict.fromkeys(runaway.names, RUNAWAY_REASON))
    joint = with_noise_levels(whole, settings.joint, gathered.has_heading(), log.dt)
    joint, left_out = without_an_unseen_lever_arm(whole, joint, prepared)
    rederive = log.ay_from_wheels and "d" not in settings.joint.held_at_prior
    if rederive:  # a_y derived with the nominal theta: again with the solved one
        log = dataclasses.replace(
            log, ay=wheel_lateral_acceleration(log.n_rl, log.n_rr, whole.theta, log.dt)
        )
        gathered = gather_segments(log, prepared.selected, prepared.fix_weights)
        validation = gather_segments(log, prepared.validation_segments)
        say("lateral acceleration of the wheels derived again with the solved theta")
    if joint is not settings.joint or rederive:
        settings = dataclasses.replace(settings, joint=joint)  # the fixes' own noise
        whole, values, data, offset = solve_with_time_offset(
            log,
            gathered,
            prepared.selected,
            prepared.fix_weights,
            settings.joint,
            workers,
            StoppedAt(values, offset, _rounds_start(whole)),
        )
    whole = judged_with_what_is_held(whole, settings.joint, held)
    estimated = _with_total_offset(
        sensor_estimates(whole.nuisance, settings.joint.max_sigma_ratio), offset
    )
    estimated.update(not_estimated(left_out))
    estimated = measured_from(estimated, log.position_reference())
    down_weighted = DownWeightedFixes.from_solve(data, whole.fix_weights, log.t)
    lines = estimate_lines(estimated, log, length_unit(settings.vehicle.theta_nominal[2]))
    _report(whole, lines, down_weighted, settings.joint)
    weights = prepared.fix_weights
    if whole.fix_weights is not None:
        weights = log_weights(data, whole.fix_weights, len(log.t))
    corrected = _corrected(prepared, log, settings, weights, estimated, validation)
    solved = WholeLog(whole, estimated, down_weighted, log, corrected)
    systems = segment_systems(solved.batch_data(), solved.batch_settings(), values, workers)
    del values  # the whole log's solution, most of the memory of a long log
    agreement = segment_agreement(systems, len(prepared.selected))
    say(agreement_line(agreement))
    return dataclasses.replace(
        solved,
        whole=with_agreement(whole, agreement, settings.joint),
        systems=systems,
        agreement=agreement,
    )


def _holding_a_runaway(
    prepared: PreparedLog,
    settings: JointSettings,
    runaway: ImplausibleTheta,
    workers: int,
) -> tuple[JointCalibration, gtsam.Values, SegmentData, np.ndarray]:
    """The whole-log solve under ``settings``, which hold the parameters that ran out of
    their plausible range in the first solve (``runaway``) at their prior; ``runaway``
    raised again when the data determine one of them (then the data put it there: wrong
    units, not a weak direction).

    A direction the data barely determine drifts where the model's misfit pulls it, a long
    way under a weak prior: a 2 km straight road from 10 Hz fixes without heading drove t_r
    to 0.49 m (its prior 1.5 ± 0.2 m) in 50 iterations, and "check the units" ended a valid
    recording. Whether a direction is determined is read from the held solve's covariance
    with the weak prior put back
    (:func:`~graphcal.graph.solution.observability.with_prior_sigmas`)."""
    them = "it" if len(runaway.names) == 1 else "them"
    say(
        f"{', '.join(runaway.names)} left the plausible range in the first solve: solved again "
        f"held at the prior, to see whether the data determine {them}"
    )
    whole, values, data, offset = solve_with_time_offset(
        prepared.log, prepared.data, prepared.selected, prepared.fix_weights, settings, workers
    )
    if any(data_determine(whole, settings, runaway.names)):
        raise runaway
    return whole, values, data, offset


def solve_with_time_offset(
    log: DriveLog,
    data: SegmentData,
    selected: Segments,
    flagged: np.ndarray | None,
    settings: JointSettings,
    workers: int = 1,
    start: StoppedAt | None = None,
) -> tuple[JointCalibration, gtsam.Values, SegmentData, np.ndarray]:
    """The whole-log solve; while it detects a wheel time offset, the wheels are shifted by
    the offset found so far, rounded to whole samples, and the solve repeated, so that the
    graph's first-order shift only covers the rest (at most about half a sample). A log of
    several runs has an offset per run, each run shifted by its own.

    Whole samples because a shift is exact only for them: between samples it averages
    neighbouring rotations, which smooths their noise (tick quantization above all) away
    from what the correction prior assumes. On a 24 km drive with 96-tick encoders, slow slip
    and 62.5 ms latency, fractional shifting moved t_r by 4.3σ (``docs/defects.md``).

    ``data`` are ``selected`` gathered from ``log`` with the ``flagged`` fix weights. Returns
    the last solve, its values, the segments it solved and the shift [s] of each run's
    wheels. Each solve after the first starts from the one before (its values and fix
    weights); the first from ``start`` (where a solve of the same segments under other noise
    levels stopped), if given. A run is shifted again only while its solve finds more than
    :data:`SHIFT_AGAIN_SAMPLES` of a sample beyond its shift."""
    start = start or StoppedAt(None, np.zeros(log.runs), None)
    shift = start.shift
    if shift.any():
        data = gather_segments(shift_wheel_rotations(log, shift), selected, flagged)
    whole, values = _whole_log_solve(data, settings, workers, start.values, start.rounds)
    for _ in range(OFFSET_ROUNDS - 1):
        found = detected_offsets(
            sensor_estimates(whole.nuisance, settings.max_sigma_ratio), log.runs
        )
        again = np.abs(found) > SHIFT_AGAIN_SAMPLES * log.dt
        rounded = np.where(again, [whole_samples(s, log.dt) for s in shift + found], shift)
        if np.array_equal(rounded, shift):
            break  # what is left is less than a sample: the graph's first order covers it
        shift = rounded
        shown = ", ".join(f"{s * 1e3:+.1f}" for s in shift)
        say(f"wheels shifted by {shown} ms{_per_run(log.runs)}; solved again from the shifted log")
        data = gather_segments(shift_wheel_rotations(log, shift), selected, flagged)
        whole, values = _whole_log_solve(data, settings, workers, values, _rounds_start(whole))
    return whole, values, data, shift


def _per_run(runs: int) -> str:
    """`` (runs 0–3)`` after a list of one value per run; empty for one run."""
    return "" if runs == 1 else f" (runs 0–{runs - 1})"


def _whole_log_solve(
    data: SegmentData,
    settings: JointSettings,
    workers: int,
    start: gtsam.Values | None = None,
    rounds_start: RoundsStart | None = None,
) -> tuple[JointCalibration, gtsam.Values]:
    """The joint solve over all ``data`` (its segments shared out among ``workers``
    processes; from the graph-wide variables of ``start`` and the robust rounds from
    ``rounds_start``, if given), with the progress lines a user waits for, and the
    solution's values."""
    say(f"joint solve over all {len(data)} selected segments")
    result, values = solve_joint(data, settings, workers, start=start, rounds_start=rounds_start)
    chi2 = result.chi2_per_dof
    fit = "" if chi2 is None else f", χ²/dof {chi2:.2f}"
    say(f"  {result.iterations} iterations{fit}")
    return result, values


def _with_total_offset(
    estimates: dict[str, SensorEstimate], offset: np.ndarray
) -> dict[str, SensorEstimate]:
    """``estimates`` with each run's time offset the total: the ``offset`` [s] its wheels
    were shifted by, plus what the last solve found."""
    out = dict(estimates)
    names = component_names("time_offset", len(offset))
    for name, shift in zip(names, offset, strict=True):
        found = out.get(name)
        if found is not None and shift != 0.0:
            out[name] = dataclasses.replace(found, value=found.value + float(shift))
    return out


def _corrected(
    prepared: PreparedLog,
    log: DriveLog,
    settings: Settings,
    weights: np.ndarray | None,
    estimated: dict[str, SensorEstimate],
    validation: SegmentData,
) -> PreparedLog:
    """``prepared`` after the whole-log solve: ``log`` (as solved) corrected exactly by the
    ``estimated`` sensor quantities, the solve's ``settings`` and fix ``weights``, and the
    segments gathered again (the validation segments only if the log changed: ``validation``
    are those of ``log``)."""
    exact = correct_log(log, estimated)
    if exact is not log:
        validation = gather_segments(exact, prepared.validation_segments)
    return dataclasses.replace(
        prepared,
        log=exact,
        settings=settings,
        fix_weights=weights,
        data=gather_segments(exact, prepared.selected, weights),
        validation=validation,
    )


def _report(
    whole: JointCalibration,
    estimate_lines: list[str],
    down_weighted: DownWeightedFixes,
    settings: JointSettings,
) -> None:
    """The progress lines of what the whole-log solve found: the sensor estimates (their
    lines: :func:`estimate_lines`), the fixes it down-weighted and slow wheel slip."""
    for line in estimate_lines:
        say(line)
    if whole.fix_weights is not None:
        say(down_weighted.summary())
    if whole.slip_test is not None:
        say(slip_line(whole, settings))


def slip_line(whole: JointCalibration, settings: JointSettings) -> str:
    """One line: whether the whole-log solve found slow wheel slip and modelled it."""
    test = whole.slip_test.describe()
    if whole.slip_modelled:
        return f"slow wheel slip found ({test}): modelled; σ includes it"
    return f"no slow wheel slip ({test}; limit at a false-alarm rate of {settings.slip_alpha:g})"


def estimate_lines(
    estimated: dict[str, SensorEstimate], log: DriveLog, unit: LengthUnit
) -> list[str]:
    """One progress line per sensor estimate: the time offset in ms, the lever arm of the
    log's position sensor (:meth:`~graphcal.log.drive_log.DriveLog.position_sensor`) from
    its reference point (:meth:`~graphcal.log.drive_log.DriveLog.position_reference`) in the
    vehicle's length ``unit``."""
    sensor, point = log.position_sensor(), log.position_reference()
    labels = {
        "time_offset": "time offset: wheels late against the pose",
        "lever_arm_longitudinal": f"{sensor} ahead of the {point}",
        "lever_arm_lateral": f"{sensor} left of the {point}",
    }
    lines = []
    for name, e in estimated.items():
        base, run = run_of(name)
        label = labels[base]
        if run is not None:
            label = f"{label} (run {run})"
        if not e.observable:
            lines.append(f"{label}: not observable from this drive")
        elif base == "time_offset":
            lines.append(f"{label}: {e.value * 1e3:+.1f} ± {e.sigma * 1e3:.1f} ms; {e.verdict}")
        else:
            lines.append(
                f"{label}: {unit.format(e.value, sign=True)} ± {unit.spread(e.sigma)} "
                f"{unit.name}; {e.verdict}"
            )
    return lines


def models_sensors(settings: JointSettings) -> bool:
    """The joint settings estimate a time offset or lever arm, or weight outliers."""
    return max(settings.time_offset_sigma, settings.lever_arm_sigma, settings.robust_threshold) > 0


def _batch_time_offset(estimated: dict[str, SensorEstimate], dt: float) -> dict:
    """The joint batches' time-offset prior: what the whole-log estimate of each run leaves
    beyond the whole-sample shift of its log, with their largest σ (no variable if the
    whole-log solve had none)."""
    found = [e for e in estimated.values() if run_of(e.name)[0] == "time_offset"]
    if not found:
        return {"time_offset_sigma": 0.0}
    rest = [e.value - (whole_samples(e.value, dt) if e.detected else 0.0) for e in found]
    return {"time_offset_sigma": max(e.sigma for e in found), "time_offset_means": tuple(rest)}
