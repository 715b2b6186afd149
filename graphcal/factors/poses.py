"""Pose variables and pose-measurement factors (the paper's W = [1, 1, 50] as noise models).

States ``[px, py, psi]`` become ``gtsam.Pose2`` variables. Pose2 wraps its angle, so states are
read back with the heading on the branch nearest a reference (the measured heading).
"""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.model import wrap_angle

#: The paper's pose weights W = [w_px, w_py, w_psi] (§4.4).
PAPER_POSE_WEIGHTS = (1.0, 1.0, 50.0)


def pose_sigmas(
    weights: tuple[float, float, float] = PAPER_POSE_WEIGHTS, position_sigma: float = 0.2
) -> np.ndarray:
    """Standard deviations ``[m, m, rad]`` equivalent to least-squares weights ``W``.

    A weight is an inverse variance, so ``sigma_i = position_sigma * sqrt(w_px / w_i)``; with
    the paper's W and a 0.2 m position noise the heading sigma is 0.028 rad (1.6°), close to
    the paper's 1.5° heading noise.
    """
    w = np.asarray(weights, dtype=float)
    if w.shape != (3,) or not np.all(w > 0):
        raise ValueError(f"pose weights must be three positive numbers, got {weights}")
    return position_sigma * np.sqrt(w[0] / w)


def pose2_from_state(state: np.ndarray) -> gtsam.Pose2:
    """A ``gtsam.Pose2`` from a state ``[px, py, psi]``."""
    return gtsam.Pose2(float(state[0]), float(state[1]), float(state[2]))


def state_from_pose2(pose: gtsam.Pose2, reference_heading: float) -> np.ndarray:
    """State ``[px, py, psi]`` of a Pose2, heading unwrapped to the branch nearest ``reference``."""
    psi = reference_heading + float(wrap_angle(pose.theta() - reference_heading))
    return np.array([pose.x(), pose.y(), psi])


def body_to_world(heading: float) -> np.ndarray:
    """d state / d Pose2 tangent at a pose with ``heading``: Pose2 retracts in its body frame."""
    c, s = np.cos(heading), np.sin(heading)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pose_measurement_factor(
    key: int, measured_state: np.ndarray, sigmas: np.ndarray | None = None
) -> gtsam.PriorFactorPose2:
    """A measured pose (GNSS/IMU) on a Pose2 variable, weighted like the paper's W.

    With equal x and y sigmas the factor's body-frame error weighs like the world-frame one.
    """
    sigmas = pose_sigmas() if sigmas is None else np.asarray(sigmas, dtype=float)
    return gtsam.PriorFactorPose2(
        key, pose2_from_state(measured_state), gtsam.noiseModel.Diagonal.Sigmas(sigmas)
    )
