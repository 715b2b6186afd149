"""Conversions between graphcal's arrays and ``gtsam.Values``.

graphcal works with states ``[px, py, psi]`` (heading unwrapped) and theta ``[c_e, c_d, t_r,
d]`` as numpy arrays (SI); GTSAM graphs hold ``gtsam.Pose2`` and ``Vector`` values.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.factors.poses import pose2_from_state, state_from_pose2


def insert_theta(values: gtsam.Values, key: int, theta: np.ndarray) -> None:
    """Insert (or update) theta ``(4,)`` (SI) at ``key``."""
    theta = np.asarray(theta, float)
    if values.exists(key):
        values.update(key, theta)
    else:
        values.insert(key, theta)


def theta_from_values(values: gtsam.Values, key: int) -> np.ndarray:
    """Theta ``(4,)`` (SI) stored at ``key``."""
    return np.asarray(values.atVector(key), float)


def insert_states(values: gtsam.Values, keys: Sequence[int], states: np.ndarray) -> None:
    """Insert states ``(N, 3)`` as Pose2 values at ``keys`` ``(N,)``."""
    states = np.asarray(states, float)
    if len(keys) != len(states):
        raise ValueError(f"{len(keys)} keys for {len(states)} states")
    for key, state in zip(keys, states, strict=True):
        values.insert(key, pose2_from_state(state))


def states_from_values(
    values: gtsam.Values, keys: Sequence[int], reference_heading: float = 0.0
) -> np.ndarray:
    """States ``(N, 3)`` of the Pose2 values at ``keys``, heading unwrapped along the sequence
    (the first starts on the branch nearest ``reference_heading``)."""
    out = np.empty((len(keys), 3))
    heading = reference_heading
    for i, key in enumerate(keys):
        out[i] = state_from_pose2(values.atPose2(key), heading)
        heading = out[i, 2]
    return out
