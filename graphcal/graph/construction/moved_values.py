"""A solution's values moved to another graph of the same log: a subset of its segments
renumbered, the wheel corrections moved with wheels shifted by whole samples."""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.graph.construction import keys


def renumbered(values: gtsam.Values, segments: Sequence[int] | np.ndarray) -> gtsam.Values:
    """The variables of a segment graph's ``values`` that belong to its ``segments``, segment
    ``segments[i]``'s as segment ``i``'s, with its graph-wide variables as they are: the
    values of a graph over those segments (of a solution, a start for it)."""
    where = {int(s): i for i, s in enumerate(segments)}
    every = np.asarray(values.keys(), dtype=np.uint64)
    letters = (every >> np.uint64(keys.INDEX_BITS)).astype(int)
    index = (every & np.uint64((1 << keys.INDEX_BITS) - 1)).astype(np.int64)
    per_segment = np.isin(letters, [ord(c) for c in keys.SEGMENT_LETTERS])
    segment = index // keys.SEGMENT_STRIDE
    taken = ~per_segment | np.isin(segment, list(where))  # a long log's others not looped
    pose = np.isin(letters, [ord(c) for c in keys.POSE_LETTERS])
    out = gtsam.Values()
    rows = zip(every[taken], per_segment[taken], segment[taken], pose[taken], strict=True)
    for key, own, s, is_pose in rows:  # by letter: a failed atPose2 costs 60 µs a key
        key = int(key)
        value = values.atPose2(key) if is_pose else values.atVector(key)
        out.insert(keys.in_segment(key, where[int(s)]) if own else key, value)
    return out


def with_corrections_shifted(values: gtsam.Values, segments: int, lags: np.ndarray) -> gtsam.Values:
    """``values`` of a graph of ``segments`` segments whose wheel corrections are moved to
    wheels shifted by ``lags`` ``(segments,)`` whole samples each (``n'_k = n_{k+lag}``,
    :func:`~graphcal.log.timing.shift_wheel_rotations`): each segment's corrections, its
    chunks' end to end, taken ``lag`` steps later, zero past its end (or before its start)."""
    out = gtsam.Values(values)
    for s, lag in enumerate(np.asarray(lags, int)):
        if lag == 0:
            continue
        chunks = []
        while out.exists(keys.segment_corrections(s, len(chunks))):
            chunks.append(np.asarray(out.atVector(keys.segment_corrections(s, len(chunks)))))
        if not chunks:
            continue
        steps = np.concatenate(chunks).reshape(-1, 2)
        moved = np.zeros_like(steps)
        n = len(steps)
        if abs(lag) < n:
            if lag > 0:
                moved[: n - lag] = steps[lag:]
            else:
                moved[-lag:] = steps[: n + lag]
        ends = np.cumsum([len(c) // 2 for c in chunks])[:-1]
        for k, part in enumerate(np.split(moved, ends)):
            out.update(keys.segment_corrections(s, k), part.reshape(-1))
    return out
