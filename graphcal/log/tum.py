"""Trajectories in the TUM text format, for comparison with tools such as evo.

One pose per line: ``timestamp tx ty tz qx qy qz qw`` (seconds, metres, unit quaternion),
space separated, ``#`` comments allowed. graphcal's planar states ``[px, py, psi]`` map to
``tz = 0`` and the rotation ``psi`` about z: ``q = (0, 0, sin(psi/2), cos(psi/2))``.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.files import atomic_write_text


def tum_text(t: np.ndarray, states: np.ndarray, comment: str = "") -> str:
    """The TUM text of planar ``states`` ``(N, 3)`` [m, m, rad] at times ``t`` ``(N,)`` [s]."""
    t = np.asarray(t, float)
    states = np.asarray(states, float)
    if states.ndim != 2 or states.shape[1] != 3 or len(t) != len(states):
        raise GraphcalError(
            f"TUM export needs times (N,) and states (N, 3), got {t.shape} and {states.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(states))):
        raise GraphcalError("TUM export: the trajectory contains NaN or infinite values")
    half = 0.5 * states[:, 2]
    zeros = np.zeros(len(t))
    table = np.column_stack(
        [t, states[:, 0], states[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)]
    )
    buffer = io.StringIO()
    header = "timestamp tx ty tz qx qy qz qw" + (f"\n{comment}" if comment else "")
    np.savetxt(buffer, table, fmt="%.9f", header=header)
    return buffer.getvalue()


def write_tum(
    path: str | os.PathLike[str], t: np.ndarray, states: np.ndarray, comment: str = ""
) -> Path:
    """Write a planar trajectory as a TUM file atomically (see :func:`tum_text`)."""
    return atomic_write_text(path, tum_text(t, states, comment))


def read_tum(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Times ``(N,)`` [s] and planar states ``(N, 3)`` [m, m, rad] of a TUM file.

    The heading is the rotation about z of each quaternion, unwrapped along the file (as
    graphcal's states are); tz and any tilt are dropped.
    """
    try:
        table = np.loadtxt(path, comments="#", ndmin=2)
    except (OSError, ValueError) as exc:
        raise GraphcalError(f"{path}: not a readable TUM trajectory: {exc}") from exc
    if table.shape[1] != 8:
        raise GraphcalError(f"{path}: TUM lines need 8 numbers, found {table.shape[1]}")
    qx, qy, qz, qw = table[:, 4:].T
    heading = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy**2 + qz**2))
    return table[:, 0], np.column_stack([table[:, 1], table[:, 2], np.unwrap(heading)])
