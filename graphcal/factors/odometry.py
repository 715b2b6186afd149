"""A GTSAM factor for one whole segment: eq. (1) integrated from the segment's start pose.

This is the batch Gauss–Newton residual of the paper (eqs. 6–11) as a factor: the odometry
model, driven by the segment's measured inputs and the shared parameters theta, predicts the
poses ``1..K``; the error is the prediction minus the measured poses, weighted per pose
component. One Python factor per segment, evaluated vectorized over its steps, keeps the
number of Python calls per linearization at the number of segments (see ``NOTES.md``: Python
factors cost ~50 µs each plus a copy of the optimizer's values per call).

Variables: the segment's start pose as ``gtsam.Pose2`` (optional: hold it at its measurement,
as the paper's state initialization does) and theta as a 4-vector.
"""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.model import integrate_with_jacobians, wrap_angle

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


class SegmentOdometryError:
    """Residual and Jacobians of one segment (the callable inside the CustomFactor).

    Args:
        measured_poses: measured states of the segment, ``(K+1, 3)``; row 0 is the start.
        inputs: measured inputs ``[n_rl, n_rr, beta, ay]`` of its ``K`` steps, ``(K, 4)``.
        estimate_start: if true the first key is the start pose (Pose2) and the second theta;
            otherwise the only key is theta and the start is held at ``measured_poses[0]``.
    """

    def __init__(self, measured_poses: np.ndarray, inputs: np.ndarray, estimate_start: bool):
        self.measured_poses = np.asarray(measured_poses, dtype=float)
        self.inputs = np.asarray(inputs, dtype=float)
        if self.measured_poses.shape != (len(self.inputs) + 1, 3) or self.inputs.shape[1:] != (4,):
            raise ValueError(
                f"segment needs poses (K+1, 3) and inputs (K, 4), got {self.measured_poses.shape} "
                f"and {self.inputs.shape}"
            )
        self.estimate_start = estimate_start

    def start_state(self, values: gtsam.Values, start_key: int) -> np.ndarray:
        """The start state from a Pose2 value, heading on the measured branch."""
        return state_from_pose2(values.atPose2(start_key), self.measured_poses[0, 2])

    def evaluate(
        self, start: np.ndarray, theta: np.ndarray, jacobians: bool
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Error ``(3K,)``, d error / d start ``(3K, 3)`` and d error / d theta ``(3K, 4)``."""
        states, d_start, d_theta = integrate_with_jacobians(start, self.inputs, theta, jacobians)
        error = (states[1:] - self.measured_poses[1:]).reshape(-1)
        if not jacobians:
            return error, None, None
        return error, d_start[1:].reshape(-1, 3), d_theta[1:].reshape(-1, 4)

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        keys = factor.keys()
        if self.estimate_start:
            start = self.start_state(values, keys[0])
            theta = values.atVector(keys[1])
        else:
            start = self.measured_poses[0]
            theta = values.atVector(keys[0])
        error, d_start, d_theta = self.evaluate(start, theta, H is not None)
        if H is not None:
            if self.estimate_start:
                # Pose2 retracts in its body frame: d(px, py)/d(xi_x, xi_y) = R(psi).
                c, s = np.cos(start[2]), np.sin(start[2])
                to_body = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                H[0] = d_start @ to_body
                H[1] = d_theta
            else:
                H[0] = d_theta
        return error


def segment_odometry_factor(
    theta_key: int,
    measured_poses: np.ndarray,
    inputs: np.ndarray,
    sigmas: np.ndarray | None = None,
    start_key: int | None = None,
) -> gtsam.CustomFactor:
    """A factor tying theta (and optionally the segment's start pose) to a measured segment.

    Args:
        theta_key: key of the 4-vector theta ``[c_e, c_d, t_r, d]`` (SI).
        measured_poses: measured states ``(K+1, 3)`` ``[px, py, psi]``, heading unwrapped.
        inputs: measured inputs ``(K, 4)`` ``[n_rl, n_rr, beta, ay]``.
        sigmas: per-component pose sigmas ``[m, m, rad]``; default :func:`pose_sigmas`.
        start_key: key of the start ``Pose2``; ``None`` holds the start at its measurement
            (the paper's state initialization, Step 1).
    """
    sigmas = pose_sigmas() if sigmas is None else np.asarray(sigmas, dtype=float)
    error = SegmentOdometryError(measured_poses, inputs, estimate_start=start_key is not None)
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.tile(sigmas, len(error.inputs)))
    keys = [theta_key] if start_key is None else [start_key, theta_key]
    return gtsam.CustomFactor(noise, keys, error)
