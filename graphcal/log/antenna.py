"""The GNSS antenna's lever arm: positions measured away from the centre of gravity.

An antenna ``arm = (longitudinal, lateral)`` metres ahead of and left of the centre of
gravity measures ``p_cg + R(ψ) · arm``. In a bend its path is longer or shorter than the
centre of gravity's, which reads as circumference (docs/method.md: 1.2 m ahead put c_e 16σ
off). :func:`move_to_centre` moves the measured positions back, with the measured heading
smoothed over :data:`HEADING_WINDOW_S`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.log.drive_log import DriveLog
from graphcal.model import lever_offset

#: Window [s] of the centred mean of the heading used to rotate the arm: the heading's white
#: noise (1.5° per 40 Hz sample in the paper) would otherwise move the positions by arm × noise.
HEADING_WINDOW_S = 1.0


def smoothed_heading(log: DriveLog, window_s: float = HEADING_WINDOW_S) -> np.ndarray:
    """The heading [rad] as a centred moving mean over ``window_s`` (shorter at the ends)."""
    half = max(1, round(0.5 * window_s / log.dt))
    n = len(log.psi)
    total = np.concatenate([[0.0], np.cumsum(log.psi)])
    lo = np.maximum(np.arange(n) - half, 0)
    hi = np.minimum(np.arange(n) + half + 1, n)
    return (total[hi] - total[lo]) / (hi - lo)


def move_to_centre(log: DriveLog, arm: tuple[float, float]) -> DriveLog:
    """``log`` with its positions moved from an antenna at ``arm`` [m] (ahead, left of the
    centre of gravity, body frame) to the centre of gravity."""
    ahead, left = float(arm[0]), float(arm[1])
    if ahead == 0.0 and left == 0.0:
        return log
    offset = lever_offset(smoothed_heading(log), np.array([ahead, left]))
    return dataclasses.replace(log, px=log.px - offset[:, 0], py=log.py - offset[:, 1])
