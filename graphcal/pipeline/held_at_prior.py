"""What the data do not determine, held at its prior: a direction a weak prior lets drift
is solved again held at ``theta_initial`` by a tight prior (:meth:`JointSettings.holding`),
and judged all the same on the data's information under the weak prior; a lever arm the
solve found not observable is left out of the graph."""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.graph.observability import with_prior_sigmas
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.joint import JointCalibration, JointSettings
from graphcal.pipeline.prepare import PreparedLog
from graphcal.progress import say


def weak_prior_covariance(whole: JointCalibration, settings: JointSettings) -> np.ndarray:
    """``(4, 4)`` theta's covariance of ``whole`` (solved under ``settings``, which may hold
    parameters at their prior by a tight one) under the weak prior ``theta_prior_sigmas``:
    the tight prior's information taken out
    (:func:`~graphcal.graph.observability.with_prior_sigmas`)."""
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


def holding_what_is_not_observable(
    whole: JointCalibration, settings: JointSettings
) -> JointSettings:
    """``settings`` holding the parameters ``whole`` left not observable at their prior
    (:meth:`JointSettings.holding`; else ``settings`` itself): a direction the data do not
    determine goes where a weak prior lets it (t_r 1.04–1.54 m on the real highway minute
    for its prior sigma ×4 to ×½, a_y derived from the wheels with it), and the calibrated
    parameters, linearized there, followed it, their verdicts with them. Slow slip stays as
    ``whole`` decided: a held parameter off its truth leaves a misfit that slip scales would
    take (and c_d with it) on a 4 km day where the free solve showed none."""
    names = whole.observability.not_calibrated
    if not names:
        return settings
    say(
        f"{', '.join(names)} not observable: solved again with "
        f"{'it' if len(names) == 1 else 'them'} held at the prior"
    )
    if settings.slip == "auto":
        settings = dataclasses.replace(settings, slip="on" if whole.slip_modelled else "off")
    return settings.holding(names)


def still_not_calibrated(
    whole: JointCalibration, first: JointCalibration, settings: JointSettings
) -> JointCalibration:
    """``whole`` (solved under ``settings``, with the parameters the ``first`` solve left not
    observable held at their prior) with those parameters not calibrated, for ``first``'s
    reasons where it gave one, ``first``'s slip statistic where ``whole`` had slip decided
    for it, and its covariance under the weak prior (the tight one taken out): what the
    parameters' uncertainty is, and what a fleet's day-to-day comparison combines."""
    if not settings.held_at_prior:
        return whole
    observability = whole.observability
    for name in first.observability.not_calibrated:
        reason = first.observability.reasons.get(name)
        if reason is not None or observability.calibrated[PARAMETER_NAMES.index(name)]:
            observability = observability.without(name, reason or "the data did not determine it")
    statistic = whole.slip_statistic
    if statistic is None:
        statistic = first.slip_statistic
    return dataclasses.replace(
        whole,
        covariance=weak_prior_covariance(whole, settings),
        observability=observability,
        slip_statistic=statistic,
    )


def without_an_unseen_lever_arm(
    whole: JointCalibration, settings: JointSettings, prepared: PreparedLog
) -> tuple[JointSettings, dict[str, float]]:
    """``settings`` without the lever arm, and the variables left out of the graph, when
    ``whole`` found neither of the arm's components observable (else ``settings`` and
    ``prepared.left_out``). Kept by :func:`~graphcal.pipeline.prepare.prepare_log` because
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
    return dataclasses.replace(settings, lever_arm_sigma=0.0), left_out
