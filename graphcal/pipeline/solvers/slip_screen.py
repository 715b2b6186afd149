"""Whether a log shows slow wheel slip: a score test on the solved graph.

From the solution without slip (slip scales at zero), one Gauss–Newton step of the graph with
slip scales lowers χ² by ``T = g_sᵀ A_s⁻¹ g_s`` (the scales enter nearly linearly; measured
within 1 % of a Levenberg–Marquardt iteration, at a third of its cost), where ``g_s`` is the
gradient of the slip scales and ``A_s`` their information, both with every other variable of
the graph eliminated. Without slip the gradient is the data's noise, ``g_s ~ N(0, H_s)`` with
``H_s`` the data's part of ``A_s`` (the rest is the scales' prior), so

    E[T] = tr(A_s⁻¹ H_s),    Var[T] = 2 tr((A_s⁻¹ H_s)²)

are known from the same linearization: the statistic's own null distribution on this log,
its rates, noise and driving, not a threshold read off one drive. T is a quadratic form of
Gaussian noise, so its null distribution is taken as the scaled χ² of that mean and variance
(Satterthwaite), read through the Wilson–Hilferty cube root as a normal deviate z (a short
log's few chunks give a skewed T: 7 against 2 ± 1 is z 3.3, not 5). Slip is modelled when z
exceeds the normal quantile of ``1 −`` ``[joint] slip_alpha`` (10⁻³: 3.09); the solve with
slip then continues from there to convergence. The test is taken on at most
:data:`SLIP_SCREEN_SEGMENTS` segments spread over the log: a long log's costs a fraction of
one of its iterations.

Measured (8 km city drive, seed 4, 161 chunks screened): without slip T = 103.4 against
E = 97.9 ± 11.4 (z 0.5); 0.05 % slip, (T − E)/σ 10.4, z 7.8 (per chunk 1.34, where the
former fixed threshold of 1.3 per chunk let drives of 0.89–1.18 pass with c_d 4–5σ off);
0.15 %, (T − E)/σ 82.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from statistics import NormalDist

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed, exception_reason
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.graph.construction.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.construction.moved_values import renumbered
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.optimization.values import taken_from
from graphcal.graph.solution.covariance import with_covariance
from graphcal.graph.solution.estimates import SolvedGraph
from graphcal.graph.solution.segment_solve import ValuesStart, solve_segment_graph
from graphcal.log.segments import SegmentData, spread
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.solvers.slip_score import ScreenSystem
from graphcal.statistics import scaled_chi2_deviate

#: Theta's dimension (c_e, c_d, t_r, d): the first rows of the graph-wide variables.
THETA_SIZE = len(PARAMETER_NAMES)
#: The key letter of the slip scales (:func:`graphcal.graph.construction.keys.segment_slip`).
SLIP_LETTER = chr(gtsam.Symbol(keys.segment_slip(0)).chr())

#: Slip is screened on this many segments spread over the log (all of a shorter log; the
#: warm start's sample, :mod:`graphcal.pipeline.solvers.warm_start`): about 380 chunks in 32
#: segments.
SLIP_SCREEN_SEGMENTS = 32
#: A log whose segments the solve ties into chains is screened whole up to this many
#: segments: a sample breaks its chains, and an untied sample is another estimator (a
#: 8 km log of three drives: c_e's σ 0.37 mm on 32 of its 43 segments, 0.07 mm tied whole),
#: whose response to slip is not the log's.
SLIP_SCREEN_TIED_SEGMENTS = 3 * SLIP_SCREEN_SEGMENTS
#: Cosines per minute of the screened log that the slow test (:class:`SlowSlipTest`)
#: restricts slip to: variations whose half period is a minute or longer.
SLOW_TERMS = 1.0
#: The slow test keeps the directions of its cosines that the screened chunks resolve:
#: singular values of their sampled basis above this share of the largest.
RESOLVED = 1e-6


@dataclass(frozen=True)
class ScoreStatistic:
    """A score test's statistic T (how much one Gauss–Newton step with the tested slip
    scales lowers χ²) and its null distribution's mean ``expected`` and σ ``spread``."""

    statistic: float
    expected: float
    spread: float

    @property
    def z(self) -> float:
        """T's standard normal deviate under its null distribution, a scaled χ² of its mean
        and σ (:func:`~graphcal.statistics.scaled_chi2_deviate`: few chunks give a skewed,
        heavy-tailed T; many, ``(T − E)/σ``)."""
        return scaled_chi2_deviate(self.statistic, self.expected, self.spread)

    def statistics(self) -> dict:
        """T, its null mean and σ and z, for ``calibration.json``."""
        return {
            "chi2_drop": self.statistic,
            "expected_without_slip": self.expected,
            "sigma_without_slip": self.spread,
            "z": self.z,
        }


@dataclass(frozen=True)
class SlowSlipTest(ScoreStatistic):
    """The same score test against slip that varies slowly over the log: the chunks' scales
    restricted to :data:`SLOW_TERMS` ``per minute`` cosines of the log's time, each wheel's
    mean and their difference (the constant of each is c_e's and c_d's, eliminated);
    ``terms``: the directions tested."""

    terms: int

    def describe(self) -> str:
        """``slowly over the log: 59 against 8 ± 4 (z 6.1)``."""
        return (
            f"slowly over the log: {self.statistic:.0f} against {self.expected:.0f} ± "
            f"{self.spread:.0f} (z {self.z:.1f})"
        )

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {**self.statistics(), "terms": self.terms}


@dataclass(frozen=True)
class SlipTest(ScoreStatistic):
    """The slip screen's statistic over every chunk's scales and its null distribution
    (module docstring); ``chunks``: the chunks screened (two slip scales each); ``slow``: the
    slow test on the same reduced system."""

    chunks: int
    slow: SlowSlipTest | None = None
    #: ``(4, 4)`` theta's covariance from slow slip of the wheels' effective circumference
    #: that no test can show (:func:`unseen_slip_covariance`) on the screened segments, in
    #: units of their own statistical σ (a correlation-like matrix, scaled to the whole
    #: log's σ where it is used); ``None`` where none is assumed.
    unseen_slip: np.ndarray | None = None

    def shown(self, alpha: float) -> bool:
        """The log shows slip at false-alarm rate ``alpha``: the chunks' test or the slow
        one (:class:`SlowSlipTest`) beyond its quantile of ``1 − alpha/2`` each."""
        tests = 1 if self.slow is None else 2
        limit = NormalDist().inv_cdf(1.0 - alpha / tests)
        return self.z > limit or (self.slow is not None and self.slow.z > limit)

    def describe(self) -> str:
        """``χ² lower by 216 with slip scales, 98 ± 11 without slip (z 10.4)``, and the
        slow test's."""
        line = (
            f"χ² lower by {self.statistic:.0f} with slip scales on {self.chunks} chunks, "
            f"{self.expected:.0f} ± {self.spread:.0f} without slip (z {self.z:.1f})"
        )
        return line if self.slow is None else f"{line}; {self.slow.describe()}"

    def unseen_slip_scale(self) -> np.ndarray | None:
        """``(4,)`` how many times the data's σ of each parameter its σ with the unseen slip
        is (:attr:`unseen_slip`; ``None`` without one)."""
        if self.unseen_slip is None:
            return None
        return np.sqrt(1.0 + np.clip(np.diag(self.unseen_slip), 0.0, None))

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        out = {**self.statistics(), "chunks": self.chunks}
        if self.slow is not None:
            out["slow"] = self.slow.to_dict()
        scale = self.unseen_slip_scale()
        if scale is not None:
            pairs = zip(PARAMETER_NAMES, scale, strict=True)
            out["sigma_scale_for_unseen_slip"] = {name: float(v) for name, v in pairs}
        return out


def with_slip_if_shown(
    solved: SolvedGraph,
    data: SegmentData,
    weights: np.ndarray | None,
    spec: SegmentGraphSpec,
    alpha: float,
    options: SolveOptions,
    unseen: UnseenSlip | None = None,
) -> tuple[SolvedGraph, SlipTest]:
    """The solve with slip scales if the log shows slip, else ``solved``; both with their
    covariance, and the statistic that decided (see the module docstring). Without slip
    shown, theta's covariance gains what ``unseen`` slow slip would move it by
    (:func:`unseen_slip_covariance`).

    Args:
        solved: the solve without slip scales of ``data`` with the fix ``weights`` (``None``:
            the data's own); its covariance is computed here, and its graph freed before
            the graph with slip scales is built (the two are never held at once: on a
            200 km log each is most of the memory).
        spec: the graph with slip scales.
        alpha: the test's false-alarm rate.
        options: of the solve with slip scales (its ``workers`` also screen and compute
            the covariance).

    Raises:
        CalibrationFailed: if the screening step fails.
    """
    label, workers = options.label, options.workers
    solved = _released(with_covariance(solved, label, workers))
    weighted = data if weights is None else dataclasses.replace(data, fix_weights=weights)
    screened = _screened(data, spec)
    screen = build_segment_graph(weighted.take(screened), spec)
    at_solution = _moved(solved.result, screened, screen.values)
    test = _slip_test(screen, at_solution, spec, workers, weighted.take(screened), unseen)
    if not test.shown(alpha):
        return _with_unseen_slip(solved, test), test
    test = dataclasses.replace(test, unseen_slip=None)  # modelled: the solve's σ holds it
    with_slip, initial = screen, at_solution
    if len(screened) < len(data):
        with_slip = build_segment_graph(weighted, spec)
        initial = _moved(solved.result, np.arange(len(data)), with_slip.values)
    final = solve_segment_graph(weighted, spec, options, start=ValuesStart(initial, with_slip))
    return dataclasses.replace(final, outcome=solved.outcome.then(final.outcome)), test


def _screened(data: SegmentData, spec: SegmentGraphSpec) -> np.ndarray:
    """The segments of ``data`` the screen solves: all of a log tied into chains up to
    :data:`SLIP_SCREEN_TIED_SEGMENTS`, else :data:`SLIP_SCREEN_SEGMENTS` spread over it."""
    if len(data) <= SLIP_SCREEN_TIED_SEGMENTS and spec.tied(data).any():
        return np.arange(len(data))
    return spread(len(data), SLIP_SCREEN_SEGMENTS)


def _slip_test(
    screen: BuiltGraph,
    at_solution: gtsam.Values,
    spec: SegmentGraphSpec,
    workers: int,
    segments: SegmentData,
    unseen: UnseenSlip | None = None,
) -> SlipTest:
    """The score test of the module docstring on ``screen`` (a graph with slip scales of
    ``segments``) at ``at_solution``: every other variable eliminated down to the
    graph-wide ones and the slip scales, then the graph-wide ones eliminated too; the
    slow test (:class:`SlowSlipTest`) on the same reduced system, and with ``unseen`` what
    that slip would move theta by (:func:`unseen_slip_covariance`)."""
    base = shared_keys(spec)
    slip = [int(k) for k in screen.values.keys() if chr(gtsam.Symbol(k).chr()) == SLIP_LETTER]
    screening = PartitionedGraph(screen.graph, at_solution, base + slip)
    try:
        with screening.parallel(workers):
            parts, priors = screening.part_systems()
    except RuntimeError as exc:
        reason = exception_reason(exc)
        raise CalibrationFailed(f"joint solve failed: {reason}") from exc
    data = np.zeros_like(priors)
    for part in parts:  # each touches its own segment's scales
        part.add_to(data)
    total = data + priors
    k = sum(screening.dims[key] for key in base)  # the graph-wide variables come first
    # The graph-wide variables eliminated: the slip scales' score, information and the
    # score's covariance without slip, on their block structure (slip_score)
    system = ScreenSystem(total, data, k)
    chunks = sum(len(bounds) - 1 for bounds in screen.bounds)
    spans = _chunk_spans(slip, screen.bounds)
    basis = _slow_basis(spans, segments)
    slow = None
    if basis is not None:  # the same test on B's directions: Bᵀ g, Bᵀ A B, Bᵀ H B
        slow = SlowSlipTest(*_score_test(*system.restricted(basis)), basis.shape[1])
    widened = None
    if unseen is not None and unseen.sigma > 0:
        # θ̂'s response to the slip scales, every other variable at its optimum: −I_θθ⁻¹ I_θs
        # (the gain: no prior ties theta to the slip scales)
        response = -system.gain.T[:THETA_SIZE]
        times, travel = _chunk_times_and_travel(spans, segments)
        sigma = np.sqrt(np.diag(np.linalg.inv(total[:k, :k]))[:THETA_SIZE])
        unit = np.where(sigma > 0, 1.0 / np.where(sigma > 0, sigma, 1.0), 0.0)
        widened = unseen_slip_covariance(response, times, travel, unseen) * np.outer(unit, unit)
    test = SlipTest(*system.test(), chunks=chunks, slow=slow)
    return dataclasses.replace(test, unseen_slip=widened)


@dataclass(frozen=True)
class UnseenSlip:
    """Slow variation of the wheels' effective circumference that a drive cannot show:
    relative σ (``[joint] unseen_slip_sigma``; default 0.002 = 0.2 %) and correlation time [s]
    (``[joint] unseen_slip_time``)."""

    sigma: float
    time: float


def unseen_slip_covariance(
    response: np.ndarray, times: np.ndarray, travel: np.ndarray, unseen: UnseenSlip
) -> np.ndarray:
    """``(4, 4)`` covariance [SI] of what slow slip moves the solved theta by, relative to
    the theta that holds on average over the distance driven (docs/defects.md, "Slip no test
    can see").

    Both wheels' rotations of chunk ``j`` scaled by ``1 + m_j``, ``m`` a Gauss–Markov
    process of ``unseen``'s σ and correlation time over the chunks' ``times`` [s], less its
    mean over their ``travel`` (a constant scale is c_e's, c_d's and d's own); ``response``
    ``(4, 2J)``: theta's change per slip scale of each chunk's two wheels (``−I_θθ⁻¹ I_θs``
    of the screen's reduced system). A least-squares fit weighs a drive's middle more than
    its ends (a slope fitted to positions); the truth weighs every metre alike, so slip that
    varies over minutes moves c_e by up to a third of its amplitude while the data show
    nothing a constant c_e would not explain."""
    common = response[:, 0::2] + response[:, 1::2]  # both wheels of a chunk alike
    weights = travel / max(float(travel.sum()), 1e-12)
    # m less its travel-weighted mean: the response to m − (wᵀm)·1 is (R − (R·1) wᵀ) m
    centred = common - np.outer(common.sum(axis=1), weights)
    lag = np.abs(times[:, None] - times[None, :])
    process = unseen.sigma**2 * np.exp(-lag / unseen.time)
    return centred @ process @ centred.T


def _chunk_times_and_travel(
    spans: tuple[np.ndarray, np.ndarray, np.ndarray], data: SegmentData
) -> tuple[np.ndarray, np.ndarray]:
    """Each slip key's chunk (its ``spans``, :func:`_chunk_spans`): the time [s] of its
    middle sample and the rotations [rev] its wheels turn on average (travel in wheel
    turns). Segments without their log's sample rows are taken as hours apart
    (independent)."""
    segments, starts, ends = spans
    middles = (starts + ends) // 2
    if data.sample_index is not None:
        times = data.sample_index[segments, middles] * float(data.dt)
    else:
        times = middles * float(data.dt) + 3600.0 * segments
    turns = np.abs(data.inputs[..., :2]).mean(axis=-1)  # (S, K) each step's wheel turns
    travelled = np.concatenate([np.zeros((len(turns), 1)), np.cumsum(turns, axis=1)], axis=1)
    travel = travelled[segments, ends] - travelled[segments, starts]
    return times.astype(float), travel


def _chunk_spans(
    slip: list[int], bounds: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each slip key's segment and its chunk's first and end step (``(J,)`` each)."""
    segments = np.array([keys.segment_of(key) for key in slip], dtype=int)
    chunks = np.array([gtsam.Symbol(key).index() % keys.SEGMENT_STRIDE for key in slip], int)
    starts = np.array([bounds[s][c] for s, c in zip(segments, chunks, strict=True)], int)
    ends = np.array([bounds[s][c + 1] for s, c in zip(segments, chunks, strict=True)], int)
    return segments, starts, ends


def _with_unseen_slip(solved: SolvedGraph, test: SlipTest) -> SolvedGraph:
    """``solved`` with theta's covariance widened by ``test``'s unseen slip, scaled per
    parameter from the screened segments' statistical σ to the whole log's (the same where
    every segment is screened; on a long log's sample both shrink alike with its length)."""
    if test.unseen_slip is None or solved.covariance is None:
        return solved
    sigma = np.sqrt(np.clip(np.diag(solved.covariance), 0.0, None))
    added = test.unseen_slip * np.outer(sigma, sigma)
    return dataclasses.replace(solved, covariance=solved.covariance + added)


def _score_test(
    score: np.ndarray, information: np.ndarray, noise: np.ndarray
) -> tuple[float, float, float]:
    """T = gᵀ A⁻¹ g of a ``score`` g with ``information`` A, and its null mean tr(A⁻¹H) and
    σ √(2 tr((A⁻¹H)²)) for the score's covariance ``noise`` H (module docstring)."""
    ratio = np.linalg.solve(information, noise)
    statistic = float(score @ np.linalg.solve(information, score))
    # tr((A⁻¹H)²) ≥ 0 for A positive definite and H semidefinite; a degenerate system's
    # rounding (a garbled log of the loader's fuzz test) can dip below: no spread, not NaN
    spread = float(np.sqrt(max(2.0 * float(np.trace(ratio @ ratio)), 0.0)))
    return statistic, float(np.trace(ratio)), spread


def _slow_basis(
    spans: tuple[np.ndarray, np.ndarray, np.ndarray], data: SegmentData
) -> np.ndarray | None:
    """``(2 J, q)``: slip that varies slowly over the log, as the slip scales of the ``J``
    chunks of ``spans`` (:func:`_chunk_spans`; keys in order, two scales each) — cosines
    ``cos(π j τ)`` of the chunk's time ``τ`` in [0, 1] over the screened samples,
    ``j = 1 …`` :data:`SLOW_TERMS` per minute of it (at least 2), on the wheels' mean and
    on their difference, as an orthonormal basis of the directions the chunks resolve
    (:data:`RESOLVED`); ``None`` without sample rows or slip scales."""
    segments, starts, ends = spans
    if data.sample_index is None or len(segments) == 0:
        return None
    middle = data.sample_index[segments, (starts + ends) // 2].astype(float)
    span = float(np.ptp(middle))
    if span <= 0:
        return None
    minutes = span * float(data.dt) / 60.0
    terms = max(2, int(np.ceil(SLOW_TERMS * minutes)))
    tau = (middle - middle.min()) / span
    cosines = np.cos(np.pi * np.outer(tau, np.arange(1, terms + 1)))  # (chunks, terms)
    mean = np.kron(cosines, np.array([[1.0], [1.0]]))  # rows: s_rl, s_rr of each chunk
    difference = np.kron(cosines, np.array([[1.0], [-1.0]]))
    # The test depends on the span alone: an orthonormal basis of what the chunks resolve
    # (a long log's screened segments, spread over hours, sample 594 cosines at 902 scales:
    # ill-conditioned, its null mean read 59,995 ± 0)
    left, singular, _ = np.linalg.svd(np.hstack([mean, difference]), full_matrices=False)
    return left[:, singular > RESOLVED * singular[0]]


def _released(solution: SolvedGraph) -> SolvedGraph:
    """``solution`` without its factors and its split graph (the values, estimates, spec
    and chunking stay): what is left once nothing more is solved on that graph."""
    built = dataclasses.replace(
        solution.built, graph=gtsam.NonlinearFactorGraph(), chunk_factors=()
    )
    return dataclasses.replace(solution, built=built, partitioned=None)


def _moved(result: gtsam.Values, segments: np.ndarray, values: gtsam.Values) -> gtsam.Values:
    """``values`` of a graph over ``segments`` of ``result``'s graph, with ``result``'s value
    of every variable the two share (segment ``segments[i]``'s as segment ``i``'s)."""
    return taken_from(values, renumbered(result, segments))
