"""Parameters held at their prior, and judged all the same on the data's information under
the weak prior: one that ran out of its plausible range in the first solve is solved again
held at ``theta_initial`` by a tight prior (:meth:`JointSettings.holding`); a lever arm the
solve found not observable is left out of the graph."""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.graph.solution.observability import with_prior_sigmas
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.methods.prepare import PreparedLog
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.progress import say


def weak_prior_covariance(whole: JointCalibration, settings: JointSettings) -> np.ndarray:
    """``(4, 4)`` theta's covariance of ``whole`` (solved under ``settings``, which may hold
    parameters at their prior by a tight one) under the weak prior ``theta_prior_sigmas``:
    the tight prior's information taken out
    (:func:`~graphcal.graph.solution.observability.with_prior_sigmas`)."""
    return with_prior_sigmas(
        whole.covariance, settings.solve_prior_sigmas(), settings.theta_prior_sigmas
    )


def data_determine(
    whole: JointCalibration, settings: JointSettings, names: tuple[str, ...]
) -> list[bool]:
    """Whether the data of ``whole`` (solved under ``settings``, which may hold parameters
    at their prior) determine each parameter of ``names``: its verdict under the weak prior,
    the tight one's information taken out of the covariance
    (:func:`weak_prior_covariance`)."""
    weak = dataclasses.replace(settings, held_at_prior=())
    calibrated = weak.observability(weak_prior_covariance(whole, settings)).calibrated
    return [bool(calibrated[PARAMETER_NAMES.index(name)]) for name in names]


def judged_with_what_is_held(
    whole: JointCalibration, settings: JointSettings, held: dict[str, str]
) -> JointCalibration:
    """``whole`` (solved under ``settings``, which may hold parameters at their prior by a
    tight one) judged under the weak prior: its covariance with the tight prior's information
    taken out — every other parameter's σ then includes what a held one leaves open — its
    verdicts from that covariance, and each ``held`` parameter (name → why) not calibrated.
    A parameter a tight prior holds (``held_at_prior``, the vehicle's ``fix_d``) is written
    at ``theta_initial`` exactly, not the 1e-11 from it that the tight prior leaves."""
    tight = settings.held() | np.isin(PARAMETER_NAMES, settings.held_at_prior)
    if tight.any():
        theta = np.where(tight, np.asarray(settings.theta_initial, float), whole.theta)
        whole = dataclasses.replace(whole, theta=theta)
    if not settings.held_at_prior:
        return whole
    covariance = weak_prior_covariance(whole, settings)
    weak = dataclasses.replace(settings, held_at_prior=())
    observability = weak.observability(covariance)
    for name in settings.held_at_prior:
        reason = held.get(name, "the data did not determine it")
        observability = observability.without(name, reason)
    return dataclasses.replace(whole, covariance=covariance, observability=observability)


def without_an_unseen_lever_arm(
    whole: JointCalibration, settings: JointSettings, prepared: PreparedLog
) -> tuple[JointSettings, dict[str, float]]:
    """``settings`` without the lever arm, and the variables left out of the graph, when
    ``whole`` found neither of the arm's components observable (else ``settings`` and
    ``prepared.left_out``). Kept by :func:`~graphcal.pipeline.methods.prepare.prepare_log` because
    its segments could show the arm at best, it is, on a drive that does not, a constant
    offset every segment's start position takes as well: a 6 km straight road from plain
    fixes took 24–46 iterations to converge with it and 4 without, and 24 km did not
    converge in 50."""
    estimate = whole.nuisance.get("lever_arm")
    if estimate is None or estimate.observable(settings.max_sigma_ratio).any():
        return settings, prepared.left_out
    say(
        f"lever arm of the {prepared.log.position_sensor()} not observable from this drive: "
        "solved again without it"
    )
    left_out = {**prepared.left_out, "lever_arm": estimate.prior_sigma}
    gain = whole.nuisance.get("rear_slip_gain")
    if gain is not None:  # it moves the model's point as the arm does: left out with it
        left_out["rear_slip_gain"] = gain.prior_sigma
    replaced = dataclasses.replace(settings, lever_arm_sigma=0.0, rear_slip_gain_sigma=0.0)
    return replaced, left_out
