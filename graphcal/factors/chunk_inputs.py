"""What a chunk's error is evaluated with besides its states, theta and corrections: the
values of the defect variables (:class:`DefectValues`), and the measurements of many chunks
stacked for one vectorized evaluation (:class:`StackedChunks`,
:func:`~graphcal.factors.chunk.chunk_errors`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DefectValues:
    """Values of the defect variables a chunk's error may depend on (each ``None``: zero, and
    no Jacobian). For one chunk: ``slip (2,)`` relative scales of the two wheels (the
    rotation of wheel w becomes ``n_w · (1 + slip_w)``), ``time_offset`` [s] of the wheels
    (positive: late against the pose), ``lever_arm (2,)`` [m] of the antenna (ahead, left of
    the centre of gravity), ``heading_bias`` [rad] of the measured heading, ``fix_offset
    (2, 2)`` [m] the fixes' world-frame error ``[east, north]`` at the chunk's start and at its
    end (a slowly varying GNSS error, linear between:
    :mod:`graphcal.graph.construction.gauss_markov`), ``rear_slip_gain`` [rad per m/s²] of a
    log without a sideslip (the model's point, the rear axle, moves at the sideslip
    ``−gain · a_y`` to the heading: its tyres' slip angle); for :func:`chunk_errors` each with
    a leading chunk axis."""

    slip: np.ndarray | None = None
    time_offset: np.ndarray | float | None = None
    lever_arm: np.ndarray | None = None
    heading_bias: np.ndarray | float | None = None
    fix_offset: np.ndarray | None = None
    rear_slip_gain: np.ndarray | float | None = None


#: No defect variables: the paper's chunk.
NO_DEFECTS = DefectValues()


@dataclass(frozen=True)
class StackedChunks:
    """The measurements of ``C`` chunks of ``L`` steps, stacked for :func:`chunk_errors`:
    ``inputs (C, L, 4)``, ``measured_poses (C, L+1, 3)`` or ``None``, ``rotation_rates
    (C, L, 2)`` (needed with a time offset) and ``fractions (C, L)`` (each tracked pose's
    measurement part-way through its step, :func:`graphcal.model.partial_steps`; ``None``:
    at the samples)."""

    inputs: np.ndarray
    measured_poses: np.ndarray | None
    rotation_rates: np.ndarray | None = None
    fractions: np.ndarray | None = None
