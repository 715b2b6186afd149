"""Do the segments agree? A truth-free test of the σ the whole-log solve reports.

The selected segments are cut into :data:`GROUPS` groups of consecutive segments, and each
group's theta is solved from the segments' systems at the whole-log solution
(:func:`~graphcal.pipeline.methods.joint_batches.segment_systems`: one Gauss–Newton step on the sum
of its members', as the linearized batches are). When the model and its noise levels are right,
each group's estimate differs from the whole log's by its own noise alone: for parameter i,

    T_i = Σ_k (θ_k,i − θ_i)² / Σ_k,ii  ~  χ² with K − 1 degrees of freedom

(independent estimates about their information-weighted mean; each group's own prior counts
little beside its data, and a parameter a group does not determine stays near that mean and
adds next to nothing, which only makes the test cautious). A defect the model lacks — wheels
late against the pose, an antenna off the reference point, slip — moves the groups'
estimates apart in proportion to what each group's driving does with it, far beyond their σ.
Where ``T_i`` exceeds the χ² quantile of ``1 −`` :data:`ALPHA` (the statistic's own null
distribution, not a value read off one drive), the σ of parameter i is scaled by
``√(T_i / (K − 1))`` — the scatter the groups show (a Birge ratio, as the Particle Data
Group scales inconsistent measurements) — and its verdict judged on the scaled σ
(:func:`with_agreement`). A σ the segments contradict is never reported; an estimate that is
good but less sure than the noise model says keeps its use.

Measured (8 km simulated city drives, 17 segments, 8 groups, 7 degrees of freedom): clean,
T = 3.5–5.3; wheels 50 ms late solved without the defect model, T = 101–160 for c_e, t_r
and d, whose errors were 2.7–5.4σ (the batches' IQR check of the joint method had passed
t_r at 4.8σ), within 1.1 of their scaled σ. The real highway minute's fused pose: c_e at
T = 25 on 5 degrees of freedom.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.graph.solution.reduced_systems import ReducedSystems
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.progress import say
from graphcal.statistics import chi2_quantile, chi2_survival

#: Groups of consecutive segments the log is cut into (fewer with fewer segments).
GROUPS = 8
#: False-alarm probability of each parameter's test.
ALPHA = 1e-3


@dataclass(frozen=True)
class Agreement:
    """How far the groups' estimates of each parameter are from the whole log's, in σ.

    Attributes:
        statistic: ``(4,)`` T_i (module docstring).
        dof: its degrees of freedom (groups − 1).
        p_value: ``(4,)`` P(χ²_dof > T_i) when the σ are honest.
    """

    statistic: np.ndarray
    dof: int
    p_value: np.ndarray

    @property
    def disagreeing(self) -> np.ndarray:
        """``(4,)`` True where the groups disagree beyond :data:`ALPHA`."""
        return self.p_value < ALPHA

    @property
    def sigma_scale(self) -> np.ndarray:
        """``(4,)`` what each parameter's σ is multiplied by: the groups' scatter in their
        σ, ``√(T_i / dof)``, where they disagree; 1 elsewhere."""
        return np.where(self.disagreeing, np.sqrt(self.statistic / self.dof), 1.0)

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {
            "groups": self.dof + 1,
            "chi2": {n: float(t) for n, t in zip(PARAMETER_NAMES, self.statistic, strict=True)},
            "dof": self.dof,
            "p_value": {n: float(p) for n, p in zip(PARAMETER_NAMES, self.p_value, strict=True)},
            "alpha": ALPHA,
            "sigma_scale": {
                n: float(k) for n, k in zip(PARAMETER_NAMES, self.sigma_scale, strict=True)
            },
        }


def segment_agreement(systems: ReducedSystems, segments: int) -> Agreement | None:
    """The agreement of groups of the ``segments`` (their systems: ``systems``) with the
    whole log; ``None`` with fewer than 3 segments (two groups test next to nothing) or
    where a group's information is singular."""
    if segments < 3:
        return None
    groups = np.array_split(np.arange(segments), min(GROUPS, segments))
    whole = systems.solve_groups([np.arange(segments)])
    parts = systems.solve_groups(groups)
    if not (whole.solved.all() and parts.solved.all()):
        return None
    variance = np.diagonal(parts.covariance[:, :4, :4], axis1=1, axis2=2)
    statistic = ((parts.values[:, :4] - whole.values[0, :4]) ** 2 / variance).sum(axis=0)
    dof = len(groups) - 1
    p_value = np.array([chi2_survival(float(t), dof) for t in statistic])
    return Agreement(statistic, dof, p_value)


def agreement_line(agreement: Agreement | None) -> str:
    """One progress line: the test's largest statistic, or why there is none."""
    if agreement is None:
        return "segments' agreement: too few segments to test"
    worst = int(np.argmax(agreement.statistic))
    limit = chi2_quantile(1.0 - ALPHA, agreement.dof)
    return (
        f"segments' agreement: groups differ from the whole log by χ² "
        f"{agreement.statistic[worst]:.1f} on {agreement.dof} degrees of freedom at most "
        f"({PARAMETER_NAMES[worst]}; {limit:.1f} at a false-alarm rate of {ALPHA:g})"
    )


def with_agreement(
    whole: JointCalibration, agreement: Agreement | None, settings: JointSettings
) -> JointCalibration:
    """``whole`` (its covariance under the weak prior of ``settings``) with each parameter's
    σ scaled by the groups' scatter where they disagree (:attr:`Agreement.sigma_scale`, a
    progress line each) and its verdicts judged on the scaled σ (those it left out for a
    reason stay out)."""
    if agreement is None or not agreement.disagreeing.any():
        return whole
    scale = agreement.sigma_scale
    for name, k, t in zip(PARAMETER_NAMES, scale, agreement.statistic, strict=True):
        if k > 1.0:
            say(
                f"{name}: σ scaled {k:.1f}×: groups of segments scatter beyond it (χ² {t:.0f} "
                f"on {agreement.dof} degrees of freedom): a defect the model lacks, or noise "
                "levels set too low"
            )
    covariance = whole.covariance * np.outer(scale, scale)
    observability = dataclasses.replace(settings, held_at_prior=()).observability(covariance)
    for name, reason in whole.observability.reasons.items():
        observability = observability.without(name, reason)
    return dataclasses.replace(whole, covariance=covariance, observability=observability)
