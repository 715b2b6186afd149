"""Parameters that run out of their plausible range in a free whole-log solve: held at their
prior and judged on what the data determine under the weak prior
(:func:`~graphcal.pipeline.methods.held_at_prior.data_determine`) — held where the data do
not, the recording refused where they put it there (wrong units, not a weak direction)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.graph.solution.plausibility import ImplausibleTheta
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.methods.held_at_prior import data_determine
from graphcal.pipeline.methods.noise_levels import (
    fixes_reweighted,
    noise_levels_change,
    with_noise_levels,
)
from graphcal.pipeline.methods.prepare import PreparedLog
from graphcal.pipeline.methods.time_offset_rounds import (
    OFFSET_ROUNDS,
    Solved,
    StoppedAt,
    solve_with_time_offset,
)
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.residual_noise import ResidualNoise
from graphcal.progress import say

#: Why a parameter that left its plausible range in a solve is held at its prior.
RUNAWAY_REASON = "it left its plausible range in a free solve; held at its prior"


@dataclass(frozen=True)
class FreeSolve:
    """How a free whole-log solve runs (:func:`solve_with_time_offset`'s arguments): from
    where (``start``), going on from which solve under these settings (``solved``), with
    how many time-offset rounds, and when its first robust round ends it (``stop_if``)."""

    start: StoppedAt | None = None
    solved: tuple[JointCalibration, gtsam.Values] | None = None
    rounds: int = OFFSET_ROUNDS
    stop_if: Callable[[ResidualNoise], bool] | None = None


def holding_runaways(
    prepared: PreparedLog,
    settings: Settings,
    held: dict[str, str],
    workers: int,
    free: FreeSolve = FreeSolve(),
    noisier_judged: bool = False,
) -> tuple[Settings, Solved]:
    """:func:`solve_with_time_offset` of ``prepared`` as ``free`` says; parameters that run
    out of their plausible range are held at their prior (:func:`_holding_a_runaway`,
    recorded in ``held``) and the settings holding them returned; a runaway whose held solve
    shows far noisier fixes is solved again free under their noise, once
    (``noisier_judged``: that was done; a runaway that then shows far noisier fixes again
    stays held: fixes of 2 m that the solves read as 0.05, 0.38 and 2.4 m, one after the other,
    do not say a parameter the data determine went out of range — exit 2 "check the units"
    before, nothing calibrated now, campaign seed 41's shape 103)."""
    start, rounds = free.start, free.rounds
    try:
        return settings, solve_with_time_offset(
            prepared, settings.joint, workers, start, rounds, free.solved, free.stop_if
        )
    except ImplausibleTheta as runaway:
        shift = None if start is None else start.shift
        runaway, holding, outcome = _holding_a_runaway(
            prepared, settings.joint, runaway, workers, shift
        )
        if not any(data_determine(outcome[0], holding, runaway.names)):
            held.update(dict.fromkeys(runaway.names, RUNAWAY_REASON))
            if rounds > 1:  # kept held: its time-offset rounds, going on from it
                go_on, solved = StoppedAt(None, outcome[3], None), outcome[:2]
                outcome = solve_with_time_offset(prepared, holding, workers, go_on, rounds, solved)
            return dataclasses.replace(settings, joint=holding), outcome
        has_heading, dt = prepared.data.has_heading(), prepared.log.dt
        noise = with_noise_levels(outcome[0], holding, has_heading, dt)
        # a held solve stopped creeping under far too tight weights is no solution to judge
        # units by (a robot's fixes sharing 0.23 m over 46 s: χ²/dof 26, its fixes read as
        # 0.094 m, t_r "determined" out of range: exit 2 "check the units", campaign seed
        # 44's shape 162): solved free again under the noise it shows, as far noisier fixes
        crept = outcome[0].outcome.crept
        # nor is one under white weights where its residuals show an error the fixes share
        # (a robot's 5 Hz fixes sharing 1 m over 43 s, weighted as 1.69 m white: t_r
        # "determined" at 0.006 m, exit 2 "check the units", campaign seed 53's shape 68)
        shared = noise.fix_error_sigma > 0.0 and not holding.fix_error_sigma
        if not fixes_reweighted(holding, noise) and not crept and not shared:
            raise runaway from None  # the data put it there: wrong units, not a weak direction
        if noisier_judged:  # solved free under their noise, and still far noisier: held
            held.update(dict.fromkeys(runaway.names, RUNAWAY_REASON))
            return dataclasses.replace(settings, joint=holding), outcome
        why = (
            "stopped creeping under"
            if crept
            else "shows an error the fixes share beyond"
            if shared
            else "shows the fixes far noisier than"
        )
        say(
            f"  the held solve {why} the weights it took: the free solve again under the "
            "noise its residuals show, before the runaway is judged"
        )
        joint = dataclasses.replace(noise, held_at_prior=settings.joint.held_at_prior)
        settings = dataclasses.replace(settings, joint=joint)
        unshifted = StoppedAt(None, start.shift, None) if start is not None else None
        again = FreeSolve(unshifted, rounds=rounds)
        return holding_runaways(prepared, settings, held, workers, again, noisier_judged=True)


def _holding_a_runaway(
    prepared: PreparedLog,
    settings: JointSettings,
    runaway: ImplausibleTheta,
    workers: int,
    shift: np.ndarray | None = None,
) -> tuple[ImplausibleTheta, JointSettings, Solved]:
    """The whole-log solve under ``settings`` holding the parameters that ran out of their
    plausible range in a solve (``runaway``) at their prior, for :func:`holding_runaways`
    to judge whether the data determine them (then the data put them there: wrong units,
    not a weak direction): the runaway with every parameter held, the settings holding them
    and the solve. One solve: its time-offset rounds only where the runaway stays held (seed
    29's shape 82 ran three, 165 s, before the solve was dropped for the fixes' own noise);
    a parameter that runs away in the held solve is held with the others, and that solved
    again (a robot's 17-tick wheels under fixes sharing 2 m: t_r, then c_d ran out; exit 2
    for "wrong units" before, campaign seed 41's shape 103).

    A direction the data barely determine drifts where the misfit pulls it under a weak
    prior (a 2 km straight road of fixes without heading drove t_r to 0.49 m, its prior
    1.5 ± 0.2 m). Whether it is determined is read from the held solve's covariance with
    the weak prior put back (:func:`~graphcal.graph.solution.observability.with_prior_sigmas`)
    under noise levels that fit: where its residuals show fixes :data:`REWEIGHTED
    <graphcal.pipeline.methods.noise_levels.REWEIGHTED>` times noisier than weighted, the
    free solve is repeated under them first (a delivery robot's fixes wandering by 0.74 m
    weighted as 0.05 m: c_e and t_r "determined" at χ²/dof 7.2)."""
    start = None if shift is None else StoppedAt(None, shift, None)
    while True:
        them = "it" if len(runaway.names) == 1 else "them"
        say(
            f"{', '.join(runaway.names)} left the plausible range in a solve: solved again "
            f"held at the prior, to see whether the data determine {them}"
        )
        holding = settings.holding(runaway.names)
        # under fixes far noisier than weighted it stops creeping, for their noise to be read
        changes = noise_levels_change(holding, prepared.data.has_heading(), prepared.log.dt)
        try:
            solved = solve_with_time_offset(prepared, holding, workers, start, 1, stop_if=changes)
            return runaway, holding, solved
        except ImplausibleTheta as more:
            names = set(runaway.names) | set(more.names)
            if names == set(runaway.names):
                raise  # a held parameter out of range: what holds it did not
            both = tuple(name for name in PARAMETER_NAMES if name in names)
            runaway = ImplausibleTheta(str(more), both)
