"""The chunk factors of one graph evaluated together, vectorized over chunks.

GTSAM calls a graph's Python factors one by one: a 24 km whole-log graph has 570 chunk
factors, and each call's numpy work on 50 steps is mostly per-call overhead (0.8 ms a call,
``docs/performance.md``). A :class:`ChunkBatch` makes the first call of a linearization or
error pass compute every member chunk at once with :func:`~graphcal.factors.chunk.chunk_errors`
(chunks of equal shape stacked, in blocks of :data:`BLOCK_CHUNKS`), and answers the other
members' calls from that pass:

* a member's answer is used only if the variables it reads from the ``Values`` it was called
  with equal those the pass computed it at (compared exactly), so any caller — GTSAM's
  optimizer, ``Marginals``, a single ``factor.error`` in a test — gets what the member alone
  would compute;
* Jacobians are kept until their member has handed them to GTSAM (an error-only pass keeps
  only errors), so the batch holds at most one linearization's blocks besides GTSAM's own.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Protocol

import gtsam
import numpy as np

from graphcal.factors.chunk import ChunkError, OdometryChunk, chunk_errors
from graphcal.factors.chunk_inputs import DefectValues, StackedChunks

#: Chunks per vectorized evaluation: bounds the ``(C, L+1, 3, L, 2)`` rotation Jacobian
#: (64 chunks of 50 steps: 8 MB).
BLOCK_CHUNKS = 64


class _Answer:
    """One member's result of a pass: the arguments it was computed at, its error and (until
    handed over) its GTSAM Jacobian blocks."""

    __slots__ = ("arguments", "blocks", "error")

    def __init__(self, arguments: np.ndarray, error: np.ndarray, blocks: list | None):
        self.arguments = arguments
        self.error = error
        self.blocks = blocks


@dataclass(frozen=True)
class ChunkArguments:
    """What a chunk factor reads from a ``Values`` (states, not Pose2; ``None``: no slot)."""

    start: np.ndarray
    theta: np.ndarray
    corrections: np.ndarray | None
    end: np.ndarray | None
    slip: np.ndarray | None
    time_offset: np.ndarray | None
    lever_arm: np.ndarray | None
    heading_bias: np.ndarray | None
    fix_offset: np.ndarray | None = None
    rear_slip_gain: np.ndarray | None = None


class BatchMember(Protocol):
    """What a batch needs of a member (:class:`~graphcal.factors.chunk_factor.ChunkOdometryFactor`
    is one): its chunk, the rows of its error it keeps, its variables read cheaply and as
    arguments, the shape it stacks with, and GTSAM's Jacobian blocks from a stacked result."""

    chunk: OdometryChunk
    rows: np.ndarray | None

    def raw(self, values: gtsam.Values) -> np.ndarray: ...

    def arguments(self, raw: np.ndarray) -> ChunkArguments: ...

    def shape_signature(self) -> tuple: ...

    def jacobian_blocks(
        self, result: ChunkError, start: np.ndarray, end: np.ndarray | None
    ) -> list[np.ndarray]: ...


class ChunkBatch:
    """Chunk factors of one graph whose errors and Jacobians are computed together.

    Members join with :meth:`add` (``ChunkOdometryFactor(..., batch=...)`` does it) and call
    :meth:`evaluate` from their GTSAM callback.
    """

    def __init__(self) -> None:
        self.members: list[BatchMember] = []
        self._answers: dict[int, _Answer] = {}
        self._stacked: dict[tuple[int, ...], tuple] = {}  # measurements of a block, stacked

    def add(self, member: BatchMember) -> int:
        """Register ``member``; returns its index in the batch."""
        self.members.append(member)
        return len(self.members) - 1

    def evaluate(
        self, index: int, values: gtsam.Values, jacobians: bool
    ) -> tuple[np.ndarray, list | None]:
        """Member ``index``'s unwhitened error at ``values`` and, with ``jacobians``, its
        Jacobian blocks in key order (as :meth:`ChunkOdometryFactor.__call__` returns them)."""
        raw = self.members[index].raw(values)
        answer = self._answers.get(index)
        if not _answers_for(answer, raw, jacobians):
            self._compute_all(values, jacobians, index, raw)
            answer = self._answers[index]
        blocks = None
        if jacobians:
            blocks, answer.blocks = answer.blocks, None  # handed over: GTSAM keeps its copy
        return answer.error, blocks

    def _compute_all(
        self, values: gtsam.Values, jacobians: bool, index: int, raw: np.ndarray
    ) -> None:
        """Compute every member at ``values`` (members whose variables ``values`` lacks are
        left out; member ``index`` from its ``raw`` read)."""
        self._answers.clear()
        groups: dict[tuple, list[tuple[int, np.ndarray]]] = defaultdict(list)
        for i, member in enumerate(self.members):
            if i == index:
                read = raw
            else:
                try:
                    read = member.raw(values)
                except (RuntimeError, IndexError, KeyError):  # a Values lacking its variables
                    continue
            groups[member.shape_signature()].append((i, read))
        for group in groups.values():
            for first in range(0, len(group), BLOCK_CHUNKS):
                self._compute_block(group[first : first + BLOCK_CHUNKS], jacobians)

    def _compute_block(self, block: list[tuple[int, np.ndarray]], jacobians: bool) -> None:
        members = [self.members[i] for i, _ in block]
        args = [member.arguments(raw) for member, (_, raw) in zip(members, block, strict=True)]
        inputs, measured, rates, fractions = self._measurements(tuple(i for i, _ in block))

        def stacked(name: str) -> np.ndarray | None:
            items = [getattr(a, name) for a in args]
            return None if items[0] is None else np.stack(items)

        result = chunk_errors(
            StackedChunks(
                inputs, measured, None if args[0].time_offset is None else rates, fractions
            ),
            stacked("start"),
            stacked("theta"),
            stacked("corrections"),
            stacked("end"),
            jacobians,
            DefectValues(
                stacked("slip"),
                stacked("time_offset"),
                stacked("lever_arm"),
                stacked("heading_bias"),
                stacked("fix_offset"),
                stacked("rear_slip_gain"),
            ),
        )
        blocks = None
        if jacobians:
            blocks = members[0].jacobian_blocks(result, stacked("start"), stacked("end"))
        for n, (i, raw) in enumerate(block):
            rows = members[n].rows  # the measured components' rows, or all
            if rows is None:
                error = result.error[n]
                mine = None if blocks is None else [np.ascontiguousarray(b[n]) for b in blocks]
            else:
                error = result.error[n][rows]
                mine = (
                    None if blocks is None else [np.ascontiguousarray(b[n][rows]) for b in blocks]
                )
            self._answers[i] = _Answer(raw, error, mine)

    def _measurements(self, block: tuple[int, ...]) -> tuple:
        """The block's inputs, measured poses, rotation rates and fix fractions stacked (made
        once)."""
        if block not in self._stacked:
            chunks = [self.members[i].chunk for i in block]

            def stack(name: str) -> np.ndarray | None:
                items = [getattr(c, name) for c in chunks]
                return None if items[0] is None else np.stack(items)

            self._stacked[block] = (
                stack("inputs"),
                stack("measured_poses"),
                stack("rotation_rates"),
                stack("fractions"),
            )
        return self._stacked[block]


def _answers_for(answer: _Answer | None, raw: np.ndarray, jacobians: bool) -> bool:
    """``answer`` was computed at the variables ``raw`` and holds what is asked."""
    if answer is None or (jacobians and answer.blocks is None):
        return False
    return np.array_equal(answer.arguments, raw)
