"""Numerical derivatives through GTSAM's retract, shared by the Jacobian and covariance tests."""

from __future__ import annotations

from collections.abc import Callable, Iterable

import gtsam
import numpy as np


def retract_jacobian(
    residual: Callable[[gtsam.Values], np.ndarray],
    values: gtsam.Values,
    keys: Iterable[int],
    h: float = 1e-6,
) -> tuple[np.ndarray, dict[int, list[int]]]:
    """d residual / d tangent of each key's variable, by central differences of retractions.

    Pose2 variables are perturbed with ``retract`` (GTSAM's tangent), vectors additively.
    Returns the Jacobian and, per key, the indices of its columns.
    """
    columns: list[np.ndarray] = []
    by_key: dict[int, list[int]] = {}
    for key in keys:
        try:
            pose, dim = values.atPose2(key), 3
        except RuntimeError:
            pose, dim = None, len(values.atVector(key))
        for i in range(dim):
            delta = np.zeros(dim)
            delta[i] = h
            pair = []
            for sign in (1.0, -1.0):
                v = gtsam.Values(values)
                if pose is not None:
                    v.update(key, pose.retract(sign * delta))
                else:
                    v.update(key, values.atVector(key) + sign * delta)
                pair.append(residual(v))
            by_key.setdefault(key, []).append(len(columns))
            columns.append((pair[0] - pair[1]) / (2 * h))
    return np.column_stack(columns), by_key
