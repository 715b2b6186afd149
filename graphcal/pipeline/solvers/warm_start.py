"""Where a long log's whole-log solve starts: theta solved on a spread-out sample of it.

From the nominal theta a whole-log solve needs two Levenberg–Marquardt iterations before its
linearization is good (the datasheet theta is millimetres off, and the poses of every chunk
boundary start on the odometry of that theta). Each iteration linearizes every segment. A
sample of :data:`WARM_START_SEGMENTS` segments spread over the route determines theta to
within a few of the whole log's σ, at a fraction of one whole-log iteration; from there, with
the boundary poses on the odometry of that theta, the whole log's first step is already in
its quadratic range. The optimum is the whole log's either way: only the path to it changes.

Before it, a coarse search (:func:`coarse_theta`) scales the nominal c_e and t_r over a grid
and keeps the one whose odometry fits the fixes best: a nominal far off (a skid-steer
robot's datasheet track, half its effective one) is a start a local solver does not leave.
"""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np

from graphcal.errors import GraphcalError
from graphcal.graph.construction import keys
from graphcal.graph.construction.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.plausibility import ImplausibleTheta
from graphcal.graph.solution.segment_solve import BuilderStart, SolvedGraph, solve_segment_graph
from graphcal.log.segments import SegmentData, spread
from graphcal.model import PARAMETER_NAMES, StepInputs, integrate_steps
from graphcal.progress import say
from graphcal.vehicle import held_prior_sigmas

#: Segments of the sample a warm start solves.
WARM_START_SEGMENTS = 32
#: Most iterations of the warm start's solve: a start, not a result (the whole log's solve
#: goes on from it). Untied segments of a robot's 50 Hz fixes sharing an error crept 37
#: iterations, 27 s, each lowering χ² by 0.1–0.7 % (campaign seed 36's shape 106).
WARM_START_ITERATIONS = 10
#: The warm start's tolerance: it stops where its next (Gauss–Newton) step would lower χ²
#: by less than this share, and the whole-log solve's first step takes the rest (a 24 km
#: city drive's 44 segments: 3 iterations, not 4, the whole-log solve's 2 and its theta the
#: same).
WARM_START_TOLERANCE = 1e-2
#: A warm start's parameters farther than this many prior σ from the nominal are held at it
#: and the sample solved again; if theta is still that far it is not used (the start is the
#: nominal or the coarse search's theta): short segments on their own, each
#: with its own start heading fitted from positions, fit noise with theta (a robot's six
#: 19 m segments of 5 Hz fixes of 0.5 m put t_r at 0.08 m, its prior 0.2 ± 0.025 m; the
#: whole-log solve from there crept 50 iterations into a minimum at χ²/dof 4.8, exit 3 —
#: from the nominal, 29 iterations, χ²/dof 1.06, every parameter within 1σ; campaign seed
#: 41's shape 188).
WARM_START_PRIOR_SPAN = 3.0
#: Logs with fewer selected segments than this start from the nominal theta: the sample would
#: not save a whole-log iteration's worth.
WARM_START_MIN_SEGMENTS = 3 * WARM_START_SEGMENTS
#: The coarse search's scales of the nominal c_e and t_r (log-spaced about 1, which is among
#: them): tyres and a datasheet leave c_e within 25 %; a skid-steer vehicle's effective track
#: is 1.5–2.5 times its physical one, the datasheet's.
COARSE_C_E = 1.25 ** np.linspace(-1.0, 1.0, 9)
COARSE_T_R = 3.0 ** np.linspace(-1.0, 1.0, 13)
#: The coarse search moves the start only where the best grid point's misfit is below this
#: fraction of the nominal's: integrated from noisy wheel rotations, a path drifts, and a
#: shrunken one fits its fixes slightly better (the sample drive: c_e ×0.946 of a nominal
#: 0.75 % off, misfit 0.81× the nominal's); a nominal grossly off misfits many times over.
COARSE_MIN_GAIN = 0.5


def warm_start(
    data: SegmentData, spec: SegmentGraphSpec, options: SolveOptions, held: tuple[str, ...] = ()
) -> dict[int, np.ndarray] | None:
    """:func:`warm_start_solution`'s graph-wide variables alone."""
    return warm_start_solution(data, spec, options, held)[0]


def warm_start_solution(
    data: SegmentData, spec: SegmentGraphSpec, options: SolveOptions, held: tuple[str, ...] = ()
) -> tuple[dict[int, np.ndarray] | None, gtsam.Values | None]:
    """The graph-wide variables (theta, time offset, lever arm, by key) solved on
    :data:`WARM_START_SEGMENTS` of ``data``'s segments spread over the log, each on its own
    (untied), for the whole-log solve to start from. A shorter log whose segments the whole
    solve ties into chains gets its theta from all of them: a chain integrated with the
    nominal theta drifts metres from its fixes (the sample drive's first solve took 11
    iterations from χ²/dof 7087), one with a solved theta is moved onto them as one body.
    With a measured heading that theta is the paper's Step 1 over all segments, each held at
    its measured start (:func:`_held_start_theta`: one chunk per segment, no corrections,
    about a tenth of an untied iteration's cost); else, or where that fails or ends beyond
    :data:`WARM_START_PRIOR_SPAN` prior σ, each segment solved on its own (untied).
    ``None`` for a shorter log without ties, a graph without theta, or a sample that cannot
    be solved (the whole log starts from ``spec`` then); a shorter log of positions only
    starts from the nominal theta with each segment's odometry moved onto its fixes (a
    robot's start heading from 2 Hz fixes of 1 m noise left its solve at χ²/dof 7 after 100
    iterations). The sample is solved as ``options``
    say, without a line per iteration; the parameters ``held`` (at their prior already) are
    never judged far from it.

    Also returns the sample's solution where the sample is every segment of ``data`` (a
    shorter log whose segments the whole solve ties): a start for every variable of the tied
    solve, not only the graph-wide ones (else ``None``)."""
    if not spec.estimate_theta:
        return None, None
    sample = spread(len(data), WARM_START_SEGMENTS)
    coarse = coarse_theta(data.take(sample), np.asarray(spec.theta, float), spec.tracking_sigmas)
    if coarse is not None:
        scale = coarse[[0, 2]] / np.asarray(spec.theta, float)[[0, 2]]
        say(
            f"  start: c_e ×{scale[0]:.3g}, t_r ×{scale[1]:.3g} of the nominal fit the fixes "
            "best (a coarse search)"
        )
    quiet = dataclasses.replace(
        options,
        label="warm start",
        report_iterations=False,
        max_iterations=min(options.max_iterations, WARM_START_ITERATIONS),
        relative_error_tol=max(options.relative_error_tol, WARM_START_TOLERANCE),
    )
    start = BuilderStart.warm(None if coarse is None else {keys.THETA: coarse})
    if len(data) >= WARM_START_MIN_SEGMENTS:
        say(f"  start: theta from {len(sample)} segments spread over the log")
    elif spec.tied(data).any():
        theta = _held_start_theta(data, spec, quiet, start, held) if data.has_heading() else None
        if theta is not None:
            say("  start: theta from the segments, each from its measured start (Step 1)")
            return {keys.THETA: theta}, None
        sample = np.arange(len(data))
        say("  start: theta from the segments each on its own")
    elif coarse is not None:
        return {keys.THETA: coarse}, None
    elif not data.has_heading():  # positions only: a start heading from noisy fixes is poor
        say("  start: each segment's odometry moved onto its fixes (no heading measured)")
        return {keys.THETA: np.asarray(spec.theta, float)}, None
    else:
        return None, None
    try:
        solved = _solved_sample(data.take(sample), spec, quiet, start, held)
    except GraphcalError:
        return (None if coarse is None else {keys.THETA: coarse}), None
    shared = {key: np.asarray(solved.result.atVector(key)) for key in shared_keys(spec)}
    if _far_names(shared[keys.THETA], np.asarray(spec.theta, float), spec.theta_prior_sigmas, held):
        say(
            "  start: the segments on their own put theta beyond "
            f"{WARM_START_PRIOR_SPAN:g} prior σ: from the "
            + ("nominal theta" if coarse is None else "coarse search's theta")
        )
        return (None if coarse is None else {keys.THETA: coarse}), None
    return shared, solved.result if len(sample) == len(data) else None


def _held_start_theta(
    data: SegmentData,
    spec: SegmentGraphSpec,
    options: SolveOptions,
    start: BuilderStart,
    held: tuple[str, ...],
) -> np.ndarray | None:
    """Theta of all of ``data``'s segments, each integrated from its measured start pose
    with the measured wheel rotations (the paper's Step 1: one chunk per segment, no
    corrections, no sensor terms), or ``None`` where that solve fails or ends beyond
    :data:`WARM_START_PRIOR_SPAN` prior σ. Biased by the wheels' noise, as Step 1 is, but
    near enough for the whole-log solve's first Gauss–Newton step: the 24 km city drive's
    44 segments 1.3 s against 7 s untied, its whole-log solve 2 → 3 iterations."""
    try:
        solved = solve_segment_graph(
            data, spec.held_start(), options, start=start, covariance=False
        )
    except GraphcalError:  # a runaway (ImplausibleTheta) among them
        return None
    if _far_names(solved.theta, np.asarray(spec.theta, float), spec.theta_prior_sigmas, held):
        return None
    return solved.theta


def _solved_sample(
    sample: SegmentData,
    spec: SegmentGraphSpec,
    options: SolveOptions,
    start: BuilderStart,
    held: tuple[str, ...],
) -> SolvedGraph:
    """The warm start's ``sample`` solved untied; where the segments on their own run a
    parameter out of its plausible range, or end it beyond :data:`WARM_START_PRIOR_SPAN`
    prior σ, solved again with it held (:func:`_holding`): they do not show it. (A straight
    road's t_r stopped at 0.63 m, prior 1.55 ± 0.2 m, where the steps of a gentler damping
    ended short of the range's edge: campaign seed 37's shape 11.)"""
    untied = dataclasses.replace(spec, tie_segments=False)
    try:
        solved = solve_segment_graph(sample, untied, options, start=start, covariance=False)
    except ImplausibleTheta as runaway:
        hold = tuple(name for name in runaway.names if name not in held)
        if not hold:
            raise
    else:
        theta, sigmas = np.asarray(spec.theta, float), spec.theta_prior_sigmas
        hold = _far_names(solved.theta, theta, sigmas, held)
        if not hold:
            return solved
    return solve_segment_graph(
        sample, _holding(untied, hold), options, start=start, covariance=False
    )


def _far_names(
    theta: np.ndarray, start: np.ndarray, sigmas: np.ndarray | None, held: tuple[str, ...] = ()
) -> tuple[str, ...]:
    """The parameters of ``theta`` beyond :data:`WARM_START_PRIOR_SPAN` of the prior
    ``sigmas`` from ``start``, of those not ``held`` already (a held parameter's σ is
    10⁻⁴ of its prior's: held again, GTSAM takes it as a constraint and fails; none without
    a prior)."""
    if sigmas is None:
        return ()
    span = WARM_START_PRIOR_SPAN * np.abs(np.asarray(sigmas, float))
    far = np.abs(np.asarray(theta, float) - start) > span
    names = zip(PARAMETER_NAMES, far, strict=True)
    return tuple(name for name, out in names if out and name not in held)


def _holding(spec: SegmentGraphSpec, names: tuple[str, ...]) -> SegmentGraphSpec:
    """``spec`` with the parameters ``names`` held at its theta (their prior σ
    :data:`~graphcal.vehicle.HELD_SIGMA_SCALE` times as wide). On its own each 150 m
    segment of a straight road runs t_r out of range (0.12 m): without a warm start the
    tied log of a 2 km road was integrated with the nominal c_d, its heading drifted 0.3 rad
    and its positions 390 m from the fixes, and the solve never recovered (exit 2)."""
    if spec.theta_prior_sigmas is None:
        return spec
    return dataclasses.replace(
        spec, theta_prior_sigmas=held_prior_sigmas(spec.theta_prior_sigmas, names)
    )


def coarse_theta(
    data: SegmentData, nominal: np.ndarray, sigmas: np.ndarray | None = None
) -> np.ndarray | None:
    """The nominal theta with c_e and t_r scaled by the grid point of :data:`COARSE_C_E` ×
    :data:`COARSE_T_R` whose odometry, each segment moved onto its fixes as one body, fits
    them best — and its measured headings, each segment's turned by one angle, where the
    log has them (``sigmas``: the fixes' and the heading's, ``(σx, σy, σψ)`` [m, m, rad],
    weigh the two); ``None`` when that is the nominal itself (or nothing is measured).

    A solve from a theta far off can creep or stall: a skid-steer robot whose effective
    track is twice the datasheet's turns twice too fast on its odometry, a path a local
    solver does not untangle (100 iterations, χ²/dof 18). The search costs a few integrations
    of the sample (numpy), and the solve then starts where its linearization holds. A grid
    point that fits less than :data:`COARSE_MIN_GAIN` times better than the nominal leaves
    the start at the nominal: the local solve does better than the grid there."""
    fixes = data.position_fixes().astype(float)
    if data.fix_weights is not None:
        fixes = fixes * data.fix_weights
    if fixes.sum() < 3:
        return None
    grid = np.array([[c, t] for c in COARSE_C_E for t in COARSE_T_R])
    thetas = np.repeat(nominal[None], len(grid), axis=0)
    thetas[:, 0] *= grid[:, 0]
    thetas[:, 2] *= grid[:, 1]
    headings = sigmas is not None and data.has_heading()
    steps, fit = StepInputs.of(data.inputs), _AlignedFit.of(data, fixes)  # once for the grid

    def misfit_of(theta: np.ndarray) -> float:
        px, py, psi = integrate_steps(data.poses[:, 0], steps, theta)
        aligned = fit.misfit(px, py)
        if not headings:
            return aligned
        return aligned / float(sigmas[0]) ** 2 + _heading_misfit(data, psi) / float(sigmas[2]) ** 2

    misfit = np.array([misfit_of(theta) for theta in thetas])
    best = int(np.argmin(misfit))
    at_nominal = int(np.argmin(np.abs(np.log(grid)).sum(axis=1)))
    if best == at_nominal or misfit[best] > COARSE_MIN_GAIN * misfit[at_nominal]:
        return None
    return thetas[best]


def _heading_misfit(data: SegmentData, yaw: np.ndarray) -> float:
    """Σ over ``data``'s segments of the squared differences [rad²] of the measured headings
    from the odometry's ``yaw`` ``(S, K+1)``, each segment's turned by their circular mean
    (``n − |Σ e^{iΔ}|² / n`` per segment: wrap-safe, ``Σ (Δ − Δ̄)²`` for small ones)."""
    measured = data.headings_measured()
    turns = np.where(measured, np.exp(1j * (data.poses[..., 2] - yaw)), 0.0)
    count = measured.sum(axis=1)
    held = count > 0
    return float(np.sum(count[held] - np.abs(turns.sum(axis=1)[held]) ** 2 / count[held]))


@dataclasses.dataclass(frozen=True)
class _AlignedFit:
    """The weighted squared distance of fixes from an odometry turned and shifted onto them
    (2-D Procrustes in closed form, positions as complex numbers: ``Σw|a−ā|² + Σw|b−b̄|² −
    2|Σw conj(a−ā)(b−b̄)|``), the fixes' side ``b`` taken once for a grid of odometries."""

    weights: np.ndarray
    total: np.ndarray
    centred: np.ndarray
    spread: np.ndarray

    @classmethod
    def of(cls, data: SegmentData, weights: np.ndarray) -> _AlignedFit:
        """The fit to ``data``'s fixes, each of weight ``weights`` ``(S, K+1)``."""
        b = data.poses[..., 0] + 1j * data.poses[..., 1]
        total = np.maximum(weights.sum(axis=1), np.finfo(float).tiny)
        b = b - (weights * b).sum(axis=1, keepdims=True) / total[:, None]
        return cls(weights, total, b, (weights * np.abs(b) ** 2).sum(axis=1))

    def misfit(self, px: np.ndarray, py: np.ndarray) -> float:
        """Σ over the segments of the misfit of the odometry ``px, py`` ``(S, K+1)``."""
        w, a = self.weights, px + 1j * py
        a = a - (w * a).sum(axis=1, keepdims=True) / self.total[:, None]
        spread_a = (w * np.abs(a) ** 2).sum(axis=1)
        match = np.abs((w * np.conj(a) * self.centred).sum(axis=1))
        return float(np.sum(spread_a + self.spread - 2.0 * match))
