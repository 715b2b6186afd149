"""Chunk-boundary poses moved back onto the odometry after a step (a rollout).

A segment graph is a chain of chunks: chunk ``j`` integrates eq. (1) from the Pose2 at its
start and must reach the Pose2 at its end within the near-hard continuity sigmas
(millimetres, 1e-4 rad). A Levenberg–Marquardt step moves every boundary pose along its
linearization, and a linear step cannot follow a rotation: a step that turns a stretch of
path by ``δψ`` leaves each chunk of length ``s`` a gap of about ``s · δψ² / 2`` at its end,
hundreds of continuity sigmas for ``δψ`` of a few tenths of a radian, so the graph error
grows as the step's fourth power. A robot's wheel time offset turns its path by
``τ · ψ̇`` (metres per second of yaw rate): on a skid-steer robot with 2 Hz fixes, the
undamped step (τ −0.34 s, weakly determined) predicted the error to fall by 3.7 and the
continuity residuals raised it from 258 to 57,500; damped until its continuity held, each
step moved τ by about 1 ms, and the solve crept to its iteration limit.

:func:`rolled_out` re-composes each chain after the step, as a shooting method's forward
pass does: a chunk's odometry from its (new) start is a rigid motion of that start (eq. 1
is the same in any frame), so from the chain's head ``end_j ← start_j ∘ Δ_j ⊖ g_j``, with
``Δ_j`` the chunk's predicted motion at the step's values and ``g_j`` the gap the step's
linearization predicts (:class:`LinearGap`): the gaps the linear model means to leave (the
continuity is near-hard, not hard: on a misfit log the optimum keeps gaps) stay, their
second-order part goes. The same skid-steer step then raises nothing: 258 → 255.3,
gain ratio 0.67.

Where the fixes share an error (a 2-vector at each chunk boundary,
:mod:`graphcal.graph.construction.chunk_processes`), the error at a rolled end moves with it,
by minus the end's move: the step's linearization moved the path and the error the fixes
share together (their sum is what the fixes see), and a rollout that moved the path alone
would leave each fix the second-order part of the turn as a misfit. A robot's 50 Hz fixes
sharing 1.9 m over 60 s, without heading: a segment turns about 5° within that error for
little cost, and every step along it put the fixes hundreds off — the whole-log solve crept
50 iterations to its limit (χ² 8,395 → 270, each accepted step 2–3 %); with the error
following, 21 iterations to its minimum (266.8; campaign seed 54's shape 71). The error at a
chain's head, shared with the segment before when the two are tied, stays: that segment's
head pose is not rolled. The step's other variables (theta, corrections, time offset, the
chain's head) stay as stepped.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

#: The letter of the segment Pose2 keys (:func:`graphcal.graph.construction.keys.segment_pose`).
POSE_LETTER = ord("p")
#: The letter of the fixes' shared error at chunk boundaries
#: (:func:`graphcal.graph.construction.keys.segment_fix_offset`).
FIX_ERROR_LETTER = ord("e")


@dataclass(frozen=True)
class ChunkLink:
    """One chunk factor between two boundary poses: its index in the graph, its start key,
    its end key and the keys of the fixes' shared error at its start and end (``None``
    without one)."""

    factor: int
    start: int
    end: int
    start_fix_error: int | None = None
    end_fix_error: int | None = None


def _is_pose(key: int) -> bool:
    return gtsam.Symbol(key).chr() == POSE_LETTER


def _fix_errors(factor_keys: list[int]) -> tuple[int | None, int | None]:
    """The chunk's fix-error keys at its start and end (its slots' order: start, end)."""
    found = [key for key in factor_keys if gtsam.Symbol(key).chr() == FIX_ERROR_LETTER]
    return (found[0], found[1]) if len(found) == 2 else (None, None)


def chunk_links(graph: gtsam.NonlinearFactorGraph) -> list[ChunkLink]:
    """The chunk factors of ``graph`` whose start and end are both segment poses (keys
    ``start, end, ...`` in that order, their error's last 3 rows the continuity residual),
    chain by chain from each chain's head: every link after its start's own link."""
    following: dict[int, ChunkLink] = {}
    for i in range(graph.size()):
        factor = graph.at(i)
        if factor is None or not isinstance(factor, gtsam.CustomFactor):
            continue
        factor_keys = list(factor.keys())
        if len(factor_keys) >= 2 and _is_pose(factor_keys[0]) and _is_pose(factor_keys[1]):
            following[factor_keys[0]] = ChunkLink(
                i, factor_keys[0], factor_keys[1], *_fix_errors(factor_keys)
            )
    ends = {link.end for link in following.values()}
    ordered = []
    for head in [key for key in following if key not in ends]:
        key = head
        while key in following:
            link = following.pop(key)
            ordered.append(link)
            key = link.end
    return ordered


@dataclass(frozen=True)
class LinearGap:
    """A link's continuity rows of a linearization: the whitened Jacobian ``a (3, n)`` on
    ``keys`` (their dimensions ``dims``), ``b (3,)`` (minus the whitened residual) and the
    rows' ``sigmas (3,)`` [m, m, rad]."""

    keys: tuple[int, ...]
    dims: tuple[int, ...]
    a: np.ndarray
    b: np.ndarray
    sigmas: np.ndarray

    def at(self, step: gtsam.VectorValues) -> np.ndarray:
        """The gap ``predicted − end`` [m, m, rad] the linearization predicts after ``step``
        (keys ``step`` lacks do not move)."""
        parts = [
            step.at(key) if step.exists(key) else np.zeros(dim)
            for key, dim in zip(self.keys, self.dims, strict=True)
        ]
        # elementwise, not BLAS: the same bits whatever the arrays' memory alignment
        return self.sigmas * (np.sum(self.a * np.concatenate(parts), axis=1) - self.b)


def linear_gaps(
    graph: gtsam.NonlinearFactorGraph,
    linear: gtsam.GaussianFactorGraph,
    links: list[ChunkLink],
    dims: dict[int, int],
) -> list[LinearGap]:
    """Each link's :class:`LinearGap` of ``linear``, the linearization of ``graph`` (factor
    for factor, in its order); ``dims``: the dimension of every key."""
    out = []
    for link in links:
        factor = linear.at(link.factor)
        a, b = factor.jacobian()
        factor_keys = tuple(factor.keys())
        sigmas = np.asarray(graph.at(link.factor).noiseModel().sigmas())[-3:]
        key_dims = tuple(dims[key] for key in factor_keys)
        # copies: a view would keep the factor's whole Jacobian (a chunk's ~150 rows) alive
        # from the elimination to the step (80 of 145 MB of a 24 km graph's parts)
        out.append(LinearGap(factor_keys, key_dims, a[-3:].copy(), b[-3:].copy(), sigmas))
    return out


def rolled_out(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    links: list[ChunkLink],
    gaps: list[np.ndarray] | None = None,
) -> gtsam.Values:
    """``values`` with each link's end pose where its chunk's odometry from its start ends,
    less the link's gap in ``gaps`` (``predicted − end`` [m, m, rad]; ``None``: none), with
    ``links`` in chain order (:func:`chunk_links`); ``values`` itself when there are none.

    The chunks' predicted motions ``Δ_j`` are read at ``values`` (one pass over the chunk
    factors: the end plus the continuity residual is the predicted end), then composed along
    each chain from its head. The fixes' shared error at each rolled end moves with it (but at
    a chain's head: see the module's docstring)."""
    if not links:
        return values
    motions = []
    for link in links:
        gap = np.asarray(graph.at(link.factor).unwhitenedError(values))[-3:]
        start, end = values.atPose2(link.start), values.atPose2(link.end)
        predicted = gtsam.Pose2(end.x() + gap[0], end.y() + gap[1], end.theta() + gap[2])
        motions.append(start.between(predicted))
    out = gtsam.Values(values)
    targets = gaps if gaps is not None else [np.zeros(3)] * len(links)
    ends = {link.end for link in links}
    heads = {link.start_fix_error for link in links if link.start not in ends}
    for link, motion, target in zip(links, motions, targets, strict=True):
        end = out.atPose2(link.start).compose(motion)
        x, y, heading = end.x() - target[0], end.y() - target[1], end.theta() - target[2]
        out.update(link.end, gtsam.Pose2(x, y, heading))
        if link.end_fix_error is not None and link.end_fix_error not in heads:
            stepped = values.atPose2(link.end)
            move = np.array([x - stepped.x(), y - stepped.y()])
            out.update(link.end_fix_error, values.atVector(link.end_fix_error) - move)
    return out
