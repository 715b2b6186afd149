"""Chunks of a segment: one Python factor integrates a chunk of steps (``docs/performance.md``)."""

from __future__ import annotations

import numpy as np


def chunk_bounds(n_steps: int, chunk_steps: int | None) -> np.ndarray:
    """Chunk boundaries ``[0, ..., n_steps]`` of a segment of ``n_steps`` steps.

    ``chunk_steps=None`` gives one chunk. Otherwise chunks have ``chunk_steps`` steps and the
    last absorbs a remainder shorter than half a chunk.
    """
    if chunk_steps is None or chunk_steps >= n_steps:
        return np.array([0, n_steps])
    bounds = [*range(0, n_steps, chunk_steps), n_steps]
    if len(bounds) > 2 and bounds[-1] - bounds[-2] < chunk_steps // 2:
        bounds.pop(-2)
    return np.asarray(bounds)
