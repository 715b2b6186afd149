"""The Levenberg–Marquardt rules every graphcal solve driven from Python follows.

One place for the damping λ and its update, the judgement of a trial step (gain ratio,
accept or damp more or stop) and the convergence test, with GTSAM's
``LevenbergMarquardtParams`` defaults: the whole-graph solve
(:func:`graphcal.graph.optimization.solve.solve_lm`'s Python driver) and the part-by-part
solve (:mod:`graphcal.graph.optimization.partitioned_lm`) both use them.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.graph.optimization.solve_options import FAR_OFF_CHI2, SolveOptions, SolveStatus

#: GTSAM's LevenbergMarquardtParams defaults, which the Python drivers follow (its λ
#: factor 10 is the most an accepted step lowers λ by: :class:`Damping`).
LAMBDA_INITIAL = 1e-5
LAMBDA_FACTOR = 10.0
LAMBDA_UPPER_BOUND = 1e5
MIN_MODEL_FIDELITY = 1e-3
#: Smallest λ after a decrease.
LAMBDA_LOWER_BOUND = 1e-12
#: Diagonal damping clamps each variable's Hessian diagonal to this range (GTSAM's).
MIN_DIAGONAL, MAX_DIAGONAL = 1e-6, 1e32
#: An error decrease this small [graph error] ends the solve, whatever the relative one.
ABSOLUTE_ERROR_TOL = 1e-12
#: A predicted decrease at most this small counts as a perfect prediction (gain ratio 1).
NEGLIGIBLE_PREDICTION = 1e-20
#: After a step whose error decrease is within this fraction of its linearization's
#: prediction, the drivers take undamped (Gauss–Newton) steps (:func:`gauss_newton_next`).
GAUSS_NEWTON_FIDELITY = 0.1
#: A solve creeps (:class:`CreepWatch`) when this many iterations in a row each lower the
#: error by less than :data:`CREEP_SHARE` of it.
CREEP_ITERATIONS = 3
CREEP_SHARE = 0.1
#: A solve runs away (:class:`RunawayWatch`) when this many iterations in a row each leave
#: its graph-wide variables beyond their plausible range and not :data:`RETURN_SHARE` nearer.
RUNAWAY_ITERATIONS = 3
#: An iteration out of range counts as running away unless it comes back by at least this
#: share of its distance: a solve that returns does so in a few steps.
RETURN_SHARE = 0.1


@dataclass
class CreepWatch:
    """Whether a solve creeps at a χ²/dof above ``limit`` (``SolveOptions.misweighted_chi2``;
    0: never): :data:`CREEP_ITERATIONS` iterations in a row each lower the error by less
    than :data:`CREEP_SHARE`, above it. Weights far tighter than the misfit make the solve's
    linearization a poor model of its steps: a differential robot's 50 Hz fixes wandering by
    1.7 m, weighted as the profile's RTK 0.05 m, crept from χ²/dof 187 to 171 in 36
    iterations (10 s) before its residuals set the noise and the solve under it took 7."""

    limit: float
    dof: int
    slow: int = 0
    noise_read_tolerance: float = 0.0
    noise_read_chi2: float = FAR_OFF_CHI2

    @classmethod
    def of(cls, options: SolveOptions, dof: int) -> CreepWatch:
        """The watch ``options`` ask for (its creep limit and noise read) over ``dof``."""
        return cls(
            options.misweighted_chi2,
            dof,
            noise_read_tolerance=options.noise_read_tolerance,
            noise_read_chi2=options.noise_read_chi2,
        )

    @property
    def watching(self) -> bool:
        """Whether it watches at all (a limit or a noise-reading tolerance): only then does
        it need :attr:`dof`."""
        return self.limit > 0 or self.noise_read_tolerance > 0

    def stopped(self, error: float, new_error: float) -> SolveStatus | None:
        """After the iteration from ``error`` to ``new_error`` (½χ²): whether the solve
        stops where its noise is read (:func:`noise_read` at ``noise_read_tolerance``) or
        because it creeps (:meth:`creeping`, counted only when it does not stop so)."""
        tolerance = self.noise_read_tolerance
        above = self.noise_read_chi2
        if noise_read(error - new_error, error, new_error, self.dof, tolerance, above):
            return SolveStatus.NOISE_READ
        return SolveStatus.MISWEIGHTED if self.creeping(error, new_error) else None

    def above(self, error: float) -> bool:
        """The graph ``error`` (½χ²) is a χ²/dof above the limit (never without one)."""
        return self.limit > 0 and 2.0 * error / max(self.dof, 1) > self.limit

    def creeping(self, error: float, new_error: float) -> bool:
        """Count the iteration from ``error`` to ``new_error`` (graph errors, ½χ²); whether
        the solve now creeps."""
        if self.limit <= 0:
            return False
        high = self.above(new_error)
        self.slow = self.slow + 1 if high and error - new_error < CREEP_SHARE * error else 0
        return self.slow >= CREEP_ITERATIONS


@dataclass
class RunawayWatch:
    """Whether a solve's graph-wide variables run out of their plausible range: ``beyond``
    (``SolveOptions.runaway``; ``None``: never) out of it, and not :data:`RETURN_SHARE`
    nearer than before, after each of :data:`RUNAWAY_ITERATIONS` iterations in a row. Such a
    solve ended out of range and was judged a runaway — after its 50 iterations: a 1.9 km
    straight road's t_r (prior 1.55 ± 0.2 m) left its range [0.5, 3] m at the third
    iteration (0.37 m) and crept on to 0.006 m, 10 s for a verdict the fifth iteration
    gives; a 2.9 km one's first step took t_r to −0.05 m, whence it crept back by 0.1–1 %
    of the way per iteration for 50 (campaign seed 40's shape 160). Not counted where the solve
    runs far above its noise (:meth:`CreepWatch.above`): under weights far too tight, theta
    wanders where the misfit pulls it (a robot's t_r out and back in while its fixes of 1.7 m
    were weighted as 0.05 m); the creep watch stops such a solve for its noise to be read."""

    beyond: Callable[[gtsam.Values], float] | None
    farther: int = 0
    last: float = 0.0

    def running_away(self, values: gtsam.Values, judged: bool = True) -> bool:
        """Count the iteration that ended at ``values`` (not ``judged``: under weights far too
        tight, the count starts again); whether the solve now runs away."""
        if self.beyond is None:
            return False
        if not judged:
            self.farther, self.last = 0, 0.0
            return False
        distance = float(self.beyond(values))
        returning = distance < (1.0 - RETURN_SHARE) * self.last  # (≥ 0 both)
        self.farther = self.farther + 1 if distance > 0.0 and not returning else 0
        self.last = distance
        return self.farther >= RUNAWAY_ITERATIONS


@dataclass
class Damping:
    """The damping λ, updated by the gain ratio ρ (Nielsen's rule, as Ceres and MINPACK's
    successors use it, with GTSAM's tenth as its floor instead of Nielsen's third): after an
    accepted step λ × max(1/:data:`LAMBDA_FACTOR`, 1 − (2ρ − 1)³) (a step its linearization
    predicted exactly lowers λ tenfold, as GTSAM's; one of ρ ½ keeps it); after a rejected
    one λ × ν, ν doubling from 2 with each rejection in a row (up to
    :data:`LAMBDA_UPPER_BOUND`). GTSAM's ×10 / ÷10 rejects every other step where the
    graph is nearly degenerate along a direction its linearization mispredicts: a differential
    robot's last solve alternated λ 1e-8 (rejected) and 1e-7 (accepted, a fifth of the
    decrease left) for 50 iterations (campaign seed 45's shape 61)."""

    lam: float = LAMBDA_INITIAL
    nu: float = 2.0

    def can_increase(self) -> bool:
        """λ may still be raised (once more is below the upper bound)."""
        return self.lam * self.nu < LAMBDA_UPPER_BOUND

    def increase(self) -> None:
        """λ × ν, ν doubled (a rejected step, or an indeterminate system)."""
        self.lam *= self.nu
        self.nu *= 2.0

    def decrease(self, gain_ratio: float = 1.0) -> None:
        """λ × max(1/:data:`LAMBDA_FACTOR`, 1 − (2ρ − 1)³) after an accepted step of
        ``gain_ratio`` ρ, at least :data:`LAMBDA_LOWER_BOUND`; ν back to 2."""
        factor = max(1.0 / LAMBDA_FACTOR, 1.0 - (2.0 * gain_ratio - 1.0) ** 3)
        self.lam = max(self.lam * factor, LAMBDA_LOWER_BOUND)
        self.nu = 2.0

    def roots(self, scale: np.ndarray) -> np.ndarray:
        """Square roots of the diagonal damping ``λ · clamp(scale, 1e-6, 1e32)``."""
        return np.sqrt(self.lam * np.clip(scale, MIN_DIAGONAL, MAX_DIAGONAL))


def raised_scale(scale: np.ndarray | None, diagonal: np.ndarray) -> np.ndarray:
    """The damping's scale: the Hessian ``diagonal`` of the first linearization, raised to
    the largest seen (as MINPACK scales)."""
    return diagonal if scale is None else np.maximum(scale, diagonal)


class Verdict(enum.Enum):
    """What a trial step leads to."""

    ACCEPT = "accept"
    #: No step lowers the error: the current values are the minimum.
    AT_MINIMUM = "at minimum"
    DAMP_MORE = "damp more"


@dataclass(frozen=True)
class Judgement:
    """A trial step's verdict and its gain ratio (actual over predicted decrease)."""

    verdict: Verdict
    gain_ratio: float


def error_tolerance(error: float, relative_error_tol: float) -> float:
    """The error change [graph error] below which a solve at ``error`` stops."""
    return max(relative_error_tol * error, ABSOLUTE_ERROR_TOL)


def last_step_tolerance(error: float, relative_error_tol: float, step_sigmas: float) -> float:
    """The predicted decrease [graph error] at most which a Gauss–Newton step from ``error``
    is a solve's last: :func:`error_tolerance`, or ½ · ``step_sigmas``² where that is larger
    (``SolveOptions.last_step_sigmas``). A Gauss–Newton step δ predicts the decrease ½ δᵀHδ,
    and |δᵢ| ≤ √(δᵀHδ) · σᵢ for every variable (σᵢ its marginal σ, from H⁻¹): a step
    predicted to lower the error by at most ½ s² moves none by more than s of its σ. The
    relative tolerance alone asks less of a long log than of a short one (10⁻⁷ of a 12 km
    drive's ½χ² of 10,731 is a move of 0.05σ: it took another iteration after a step of
    0.05σ, whose successor moved 0.007σ)."""
    return max(error_tolerance(error, relative_error_tol), 0.5 * step_sigmas**2)


def judge_step(
    error: float,
    new_error: float,
    predicted: float,
    damping: Damping,
    relative_error_tol: float,
) -> Judgement:
    """Judge a step from ``error`` to ``new_error`` whose linearization predicted a decrease
    of ``predicted``: accepted when the error falls by at least :data:`MIN_MODEL_FIDELITY` of
    the prediction; else the values are at the minimum when the error barely changes
    (:func:`error_tolerance`, as GTSAM stops searching λ) or λ cannot rise, else damp more."""
    change = error - new_error
    ratio = change / predicted if predicted > NEGLIGIBLE_PREDICTION else 1.0
    if predicted >= 0 and ratio > MIN_MODEL_FIDELITY and change >= 0:
        return Judgement(Verdict.ACCEPT, ratio)
    if abs(change) < error_tolerance(error, relative_error_tol) or not damping.can_increase():
        return Judgement(Verdict.AT_MINIMUM, ratio)
    return Judgement(Verdict.DAMP_MORE, ratio)


def gauss_newton_next(undamped: bool, lam: float, gain_ratio: float) -> bool:
    """An accepted step leads to undamped (Gauss–Newton) steps: it was one, or needed no more
    damping ``lam`` than the first, and its linearization predicted its decrease within
    :data:`GAUSS_NEWTON_FIDELITY` (the part-by-part driver's rule,
    :mod:`graphcal.graph.optimization.partitioned_lm`)."""
    return (undamped or lam <= LAMBDA_INITIAL) and abs(gain_ratio - 1.0) <= GAUSS_NEWTON_FIDELITY


def noise_read(
    decrease: float,
    error: float,
    new_error: float,
    dof: int,
    tolerance: float,
    above_chi2: float = FAR_OFF_CHI2,
) -> bool:
    """Whether a solve whose caller reads the noise from its residuals has come to where that
    noise is read: at a χ²/dof (``new_error``, ½χ², over ``dof``) above ``above_chi2``, the
    iteration from ``error`` lowered it by at most ``tolerance`` of it (0: never). The noise
    read from a χ² within 0.1 % of its minimum is the minimum's to 0.05 %; the solve under
    weights 4.3 times too tight went on for nine more iterations (a car's 0.86 m fixes as
    0.2 m, χ²/dof 10.3355 → 10.3353; campaign seed 56's shape 67). A first solve whose caller
    solves again where the noise changed reads it near χ²/dof 1 too (``above_chi2`` 0): the
    12 km drive with every defect, χ²/dof 1.0741 through its last three iterations
    (predicted decreases 0.064 and 0.0013 of 10,731), the real fused car's last six."""
    far = 2.0 * new_error / max(dof, 1) > above_chi2
    return tolerance > 0 and far and converged(decrease, error, tolerance)


def converged(decrease: float, error: float, relative_error_tol: float) -> bool:
    """An iteration that lowered the error from ``error`` by ``decrease`` ends the solve: by
    at most ``relative_error_tol`` relatively or :data:`ABSOLUTE_ERROR_TOL` absolutely."""
    return decrease <= ABSOLUTE_ERROR_TOL or decrease <= relative_error_tol * error
