"""The whole-log solve: the joint graph over all selected segments, with what it finds about
the sensors, corrected in the log for everything after it.

Top-down, :func:`solve_whole_log` runs:

0. each run's wheels shifted by the whole samples they lag the measured heading's turns
   (:func:`~graphcal.log.timing.wheel_lag_from_turns`), where the time offset is estimated:
   what the time-offset rounds of step 2 would otherwise find one whole-log solve at a time
   (the real robot's run at +329 ms: a third solve);
1. the joint solve (:func:`~graphcal.pipeline.solvers.joint.solve_joint`: warm start, robust
   reweighting of the fixes, slip screen) under the settings' noise levels;
2. the noise its residuals show (:func:`~graphcal.pipeline.methods.noise_levels.with_noise_levels`:
   the fixes' white noise and the error they share, the heading's, the wheels') and, for a
   log whose lateral acceleration comes from the wheels (and whose d is estimated), that
   acceleration derived again with the solved theta — from a solution: after a first solve
   stopped under far wrong fix weights, with the next solve's theta, and the log solved
   again (a creeping first solve's c_e −1.7 m, t_r 0.56 m made a_y 252 m/s² in turns,
   which pinned d at σ 0.006 mm·s²/m, 199σ from the truth; campaign seed 43's shape 192);
   then time-offset rounds
   (:func:`~graphcal.pipeline.methods.time_offset_rounds.solve_with_time_offset`: the
   wheels shifted by whole samples while the solve finds an offset) under the noise found
   (a profile's RTK 0.05 m on fixes of 1.9 m put a delivery robot's wheels 350 ms late);
   the noise judged once more, and the log solved again if it changed, where the first
   solve fitted far wrong fix weights or held a lever arm left out since. A solve after
   far wrong fix weights only reads the noise for the next (its χ² to
   :data:`NOISE_READING_TOLERANCE`, no time-offset rounds), which then solves to the end
   with its rounds. A parameter that runs out of its plausible range in any of these
   solves is held at its prior and judged (:mod:`~graphcal.pipeline.methods.runaways`);
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

import numpy as np

from graphcal.graph.construction.moved_values import renumbered
from graphcal.graph.solution.reduced_systems import ReducedSystems
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, gather_segments, spread
from graphcal.log.timing import whole_samples
from graphcal.model import wheel_lateral_acceleration
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.methods.agreement import (
    Agreement,
    agreement_line,
    segment_agreement,
    with_agreement,
)
from graphcal.pipeline.methods.held_at_prior import (
    judged_with_what_is_held,
    without_an_unseen_lever_arm,
)
from graphcal.pipeline.methods.joint_batches import segment_systems
from graphcal.pipeline.methods.noise_levels import (
    fixes_reweighted,
    noise_levels_change,
    with_noise_levels,
)
from graphcal.pipeline.methods.prepare import PreparedLog, runs_label
from graphcal.pipeline.methods.runaways import FreeSolve, holding_runaways
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
from graphcal.pipeline.methods.time_offset_rounds import (
    OFFSET_ROUNDS,
    Solved,
    StoppedAt,
    rounds_start,
)
from graphcal.pipeline.methods.whole_log_lines import estimate_lines, report_whole_log
from graphcal.pipeline.solvers.joint import JointCalibration, always_stop
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.progress import say
from graphcal.units import length_unit

#: A solve whose residuals only set the noise levels of the next one (it fitted under far
#: wrong fix weights) stops where an iteration lowers χ² by less than this share: the noise
#: read there is the converged solve's to 0.01 %, and fixes that share an error make such a
#: solve creep (a robot's 50 Hz fixes sharing 1.4 m: 55 iterations to 1e-7, the last 45
#: lowering χ² by 2e-4 to 1e-7 each; campaign seed 41's shape 36).
NOISE_READING_TOLERANCE = 1e-4
#: ... and after this many iterations at most: a robot's 50 Hz fixes sharing 1.2 m over 24 s,
#: weighted white, crept 50 iterations (χ² 30,848 → 18,084, theta drifting all the way
#: towards the misfit's own minimum: t_r 0.18 → 0.13 m, 2σ of its prior); after 15 the
#: white noise reads 0.508 m for 0.486, the error they share the same (1.9 m over 60 s), and
#: the solve under it ends at the same theta in 13 iterations for 21 (campaign seed 54's
#: shape 71).
NOISE_READING_ITERATIONS = 15
#: Segments the model check predicts at most, spread over the selected ones
#: (:mod:`~graphcal.pipeline.methods.model_check`): a model's fit does not need every segment.
#: The whole-log solution of these is kept (:attr:`WholeLog.check_start`).
CHECK_SEGMENTS = 64


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
        check_start: the solution's values of the :func:`check_segments`, renumbered in
            their order, and its graph-wide variables, with its wheels' shift: where the
            model check's folds start.
    """

    whole: JointCalibration
    estimated: dict[str, SensorEstimate]
    down_weighted: DownWeightedFixes
    solved_log: DriveLog
    corrected: PreparedLog
    systems: ReducedSystems | None = None
    agreement: Agreement | None = None
    check_start: StoppedAt | None = None

    def defects_found(self) -> tuple[str, ...]:
        """What the defect model found: a time offset or lever arm detected, the rear tyres'
        slip detected, slow wheel slip modelled (what the model check is run for)."""
        found = []
        if detected_offsets(self.estimated, self.solved_log.runs).any():
            found.append("time offset")
        sides = ("longitudinal", "lateral")
        arm = [self.estimated.get(f"lever_arm_{side}") for side in sides]
        if any(e is not None and e.detected for e in arm):
            found.append("lever arm")
        gain = self.estimated.get("rear_slip_gain")
        if gain is not None and gain.detected:
            found.append("rear tyre slip")
        if self.whole.slip_modelled:
            found.append("slow wheel slip")
        return tuple(found)

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
    """The whole-log procedure of the module docstring on ``prepared``, step by step.

    Raises:
        CalibrationFailed: if a solve fails or gives an implausible theta.
    """
    held = dict(prepared.held)  # what each solve holds at its prior, and why
    settings, solved = _first_solve(prepared, held, workers)  # steps 0 and 1
    prepared, settings, solved, left_out = _solved_under_found_noise(  # step 2
        prepared, settings, held, solved, workers
    )
    whole, values, data, offset = solved
    whole = judged_with_what_is_held(whole, settings.joint, held)  # step 3
    log = prepared.log
    estimated = _with_total_offset(  # step 4
        sensor_estimates(whole.nuisance, settings.joint.max_sigma_ratio), offset
    )
    estimated.update(not_estimated(left_out))
    estimated = measured_from(estimated, log.position_reference())
    down_weighted = DownWeightedFixes.from_solve(data, whole.fix_weights, log.t)
    lines = estimate_lines(estimated, log, length_unit(settings.vehicle.theta_nominal[2]))
    report_whole_log(whole, lines, down_weighted, settings.joint)
    weights = prepared.fix_weights  # step 5
    if whole.fix_weights is not None:
        weights = log_weights(data, whole.fix_weights, len(log.t))
    corrected = _corrected(prepared, log, settings, weights, estimated, prepared.validation)
    solved_log = WholeLog(whole, estimated, down_weighted, log, corrected)
    systems = segment_systems(solved_log.batch_data(), solved_log.batch_settings(), values, workers)
    check_start = None
    if settings.joint.model_check and solved_log.defects_found():  # a check follows
        kept = renumbered(values, check_segments(len(prepared.selected)))
        check_start = StoppedAt(kept, offset, None)
    del values, solved  # the whole log's solution, most of the memory of a long log
    agreement = segment_agreement(systems, len(prepared.selected))
    say(agreement_line(agreement))
    return dataclasses.replace(
        solved_log,
        whole=with_agreement(whole, agreement, settings.joint),
        systems=systems,
        agreement=agreement,
        check_start=check_start,
    )


def check_segments(count: int) -> np.ndarray:
    """Indices of the segments of ``count`` selected ones the model check predicts:
    :data:`CHECK_SEGMENTS` spread over them (every one of a shorter log)."""
    return spread(count, CHECK_SEGMENTS)


def _first_solve(
    prepared: PreparedLog, held: dict[str, str], workers: int
) -> tuple[Settings, Solved]:
    """Steps 0 and 1: the wheels shifted by the lag of their turns, and the joint solve under
    the settings' noise levels. It stops at its first robust round where another solve
    certainly follows: a_y derived again, or noise levels its residuals change."""
    settings = prepared.settings
    first = StoppedAt(None, _wheel_lag(prepared), None)
    rederive = prepared.log.ay_from_wheels and "d" not in settings.joint.held_at_prior
    changes = noise_levels_change(settings.joint, prepared.data.has_heading(), prepared.log.dt)
    stop_if = always_stop if rederive else changes
    return holding_runaways(
        prepared, settings, held, workers, FreeSolve(first, rounds=1, stop_if=stop_if)
    )


def _solved_under_found_noise(
    prepared: PreparedLog, settings: Settings, held: dict[str, str], first: Solved, workers: int
) -> tuple[PreparedLog, Settings, Solved, dict[str, float]]:
    """Step 2: the noise the first solve's residuals show, a lever arm it did not see left
    out, a_y derived again with its theta; the log solved again under them with its
    time-offset rounds (or, after far wrong fix weights, only to read the noise at), and the
    noise judged once more where that solve differs. The log as solved (its a_y derived
    again), the settings, the solve and the variables left out of the graph."""
    whole, values, _, offset = first
    has_heading = prepared.data.has_heading()
    joint = with_noise_levels(whole, settings.joint, has_heading, prepared.log.dt)
    joint, left_out = without_an_unseen_lever_arm(whole, joint, prepared)
    rederive = prepared.log.ay_from_wheels and "d" not in settings.joint.held_at_prior
    # a_y derived with the nominal theta: again with a solved one (not a misweighted stop's)
    later = rederive and whole.outcome.crept
    rederive = rederive and not later
    if rederive:
        prepared = _with_lateral_acceleration(prepared, whole.theta)
    reweighted = fixes_reweighted(settings.joint, joint)
    again = joint is not settings.joint or rederive
    settings = dataclasses.replace(settings, joint=joint)  # the fixes' own noise
    start = StoppedAt(values, offset, rounds_start(whole))
    rounds, tolerance, stop_if = OFFSET_ROUNDS, settings.joint.tolerance, None
    limit = settings.joint.max_iterations
    if reweighted:  # fitted under far wrong fix weights: no start for the right ones
        start = StoppedAt(None, offset, None)
        # The noise is judged again after this solve: a point to read it at — its first
        # robust round, without the slip screen (the misfit of an error the fixes share not
        # modelled yet reads as slip: a robot's 10 s solve with slip scales, then dropped);
        # its time-offset rounds under the noise that follows.
        rounds, stop_if = 1, always_stop
        settings = _with_tolerance(
            settings, max(tolerance, NOISE_READING_TOLERANCE), min(limit, NOISE_READING_ITERATIONS)
        )
    free = FreeSolve(start, None if again else (whole, values), rounds=rounds, stop_if=stop_if)
    settings, solved = holding_runaways(prepared, settings, held, workers, free)
    settings = _with_tolerance(settings, tolerance, limit)
    if later:
        prepared = _with_lateral_acceleration(prepared, solved[0].theta)
    arm_left_out = "lever_arm" in left_out and "lever_arm" not in prepared.left_out
    # A first solve that crept under too tight weights left an unfinished fit's residuals:
    # its fixes were weighted white at their RMS, and whether they share an error is read
    # after the solve under that (with_noise_levels). A car's 1.4 km straight road, fixes
    # sharing 0.44 m over 17 s, weighted as 0.565 m white: c_e "calibrated" 12.5σ off
    # (campaign seed 63's shape 5).
    crept = whole.outcome.crept
    if reweighted or arm_left_out or later or crept:
        settings, solved = _noise_judged_again(
            prepared, settings, held, workers, solved, reweighted, later
        )
    return prepared, settings, solved, left_out


def _noise_judged_again(
    prepared: PreparedLog,
    settings: Settings,
    held: dict[str, str],
    workers: int,
    solved: Solved,
    reweighted: bool,
    changed: bool = False,
) -> tuple[Settings, Solved]:
    """The noise judged again where the ``solved`` it was judged from differs: it fitted far
    wrong fix weights (``reweighted``: the heading's and the wheels' noise, under the fixes'
    own), it crept under too tight ones (the fixes weighted white at an unfinished fit's
    RMS: whether they share an error, read after the solve under that), or a lever arm it
    held was left out since (the fixes' too: a 0.38 m arm across a
    straight road, not observable, took a fifth of their residuals' variance — 0.228 m kept
    as the profile's 0.2 m, within tolerance, then 0.256 m without it: χ²/dof 1.67, "not to
    be trusted"); the log solved again, with its time-offset rounds, if the noise changed,
    ``solved`` only read it (:data:`NOISE_READING_TOLERANCE`) or the log ``changed`` since
    (its a_y derived again)."""
    whole, values, _, offset = solved
    has_heading, dt = prepared.data.has_heading(), prepared.log.dt
    joint = with_noise_levels(whole, settings.joint, has_heading, dt, fixes=not reweighted)
    if joint is settings.joint and not reweighted and not changed:
        return settings, solved
    settings = dataclasses.replace(settings, joint=joint)
    start = StoppedAt(values, offset, rounds_start(whole))
    return holding_runaways(prepared, settings, held, workers, FreeSolve(start))


def _with_tolerance(settings: Settings, tolerance: float, max_iterations: int) -> Settings:
    """``settings`` whose joint solves stop at relative χ² decrease ``tolerance`` or after
    ``max_iterations``."""
    joint = settings.joint
    if joint.tolerance == tolerance and joint.max_iterations == max_iterations:
        return settings
    joint = dataclasses.replace(joint, tolerance=tolerance, max_iterations=max_iterations)
    return dataclasses.replace(settings, joint=joint)


def _with_lateral_acceleration(prepared: PreparedLog, theta: np.ndarray) -> PreparedLog:
    """``prepared`` whose lateral acceleration, derived from the wheels with the nominal
    theta, is derived again with ``theta`` (SI)."""
    log = prepared.log
    log = dataclasses.replace(log, ay=wheel_lateral_acceleration(log.n_rl, log.n_rr, theta, log.dt))
    say("lateral acceleration of the wheels derived again with the solved theta")
    return dataclasses.replace(
        prepared,
        log=log,
        data=gather_segments(log, prepared.selected, prepared.fix_weights),
        validation=gather_segments(log, prepared.validation_segments),
    )


def _wheel_lag(prepared: PreparedLog) -> np.ndarray:
    """Each run's whole-sample shift [s] for the wheels before the first solve: the lag
    at which their turns fit the measured heading's (found as the log was prepared,
    :func:`~graphcal.log.timing.wheel_lag_from_turns`), where the wheels' time offset is
    estimated; else none."""
    log = prepared.log
    lag = prepared.wheel_lag
    if lag is None or not prepared.settings.joint.time_offset_sigma:
        return np.zeros(log.runs)
    if lag.any():
        shown = ", ".join(f"{s * 1e3:+.1f}" for s in lag)
        say(
            f"wheels shifted by {shown} ms{runs_label(log.runs)} before the first solve: "
            "their lag behind the measured heading's turns"
        )
    return lag


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


def models_sensors(settings: JointSettings) -> bool:
    """The joint settings estimate a time offset or lever arm, or weight outliers."""
    return max(settings.time_offset_sigma, settings.lever_arm_sigma, settings.robust_threshold) > 0


def _batch_time_offset(estimated: dict[str, SensorEstimate], dt: float) -> dict:
    """The joint batches' time-offset prior: what the whole-log estimate of each run leaves
    beyond the whole-sample shift of its log (0 where none was detected: the log is not
    corrected for it, and an offset the drive does not show may lie anywhere — a robot's
    ran to −1.4 s through the time-offset rounds, beyond what the settings take), with
    their largest σ (no variable if the whole-log solve had none)."""
    found = [e for e in estimated.values() if run_of(e.name)[0] == "time_offset"]
    if not found:
        return {"time_offset_sigma": 0.0}
    rest = [e.value - whole_samples(e.value, dt) if e.detected else 0.0 for e in found]
    return {"time_offset_sigma": max(e.sigma for e in found), "time_offset_means": tuple(rest)}
