"""A measured pose (GNSS position and fused heading) seen through the antenna's lever arm and
a heading bias: the start-pose factor of the calibration graphs and the GNSS factor of the
localization graphs when those are estimated.

A GNSS antenna ``arm = [ahead, left]`` [m] from the centre of gravity measures the position
``p + R(ψ) · arm``; a fused heading with a slow bias ``b`` measures ``ψ + b``. The error of
the Pose2 ``x = [p, ψ]`` against the measured state ``m`` is

    e = [p + R(ψ) · arm − m_p,  wrap(ψ + b − m_ψ)]

in world coordinates, as the tracking residuals of
:class:`~graphcal.factors.ChunkOdometryFactor` (only its position rows for a GNSS position
alone). With neither arm nor bias estimated the graphs use GTSAM's own
``PoseTranslationPrior2D`` and ``PoseRotationPrior2D`` instead.
"""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.factors.poses import body_to_world, state_from_pose2
from graphcal.model import wrap_angle


class MeasuredPoseFactor:
    """A measured pose on a Pose2, with optional lever-arm and heading-bias keys (the
    ``gtsam.CustomFactor`` callable).

    Args:
        pose: the Pose2 key.
        measured: measured state ``[px, py, psi]`` (SI).
        sigmas: ``[m, m, rad]`` of the error.
        lever_arm: key of the 2-vector lever arm [m], or ``None`` (zero arm).
        heading_bias: key of the 1-vector heading bias [rad], or ``None`` (no bias).
        with_heading: the heading is measured too (else the error is the position's alone,
            and ``heading_bias`` must be ``None``).
        robust: Huber threshold [in σ] of a robust noise model, or 0 for a Gaussian one.
        offset: a known body-frame offset ``[ahead, left]`` [m] added to the lever arm
            (a fix taken a moment before the pose's time: minus the distance driven since,
            ahead), or ``None``.

    Keys, in order: pose, lever_arm, heading_bias (those given).
    """

    def __init__(
        self,
        pose: int,
        measured: np.ndarray,
        sigmas: np.ndarray,
        lever_arm: int | None = None,
        heading_bias: int | None = None,
        with_heading: bool = True,
        robust: float = 0.0,
        offset: np.ndarray | None = None,
    ):
        self.pose_key = int(pose)
        # Copies: a row of a caller's (N, 3) array would keep all of it alive with each
        # factor (5,295 fixes of a 12 km log held 5.4 GB).
        self.measured = np.array(measured, dtype=float)
        self.sigmas = np.array(sigmas, dtype=float)
        if self.measured.shape != (3,) or self.sigmas.shape != (3,):
            raise ValueError("a measured pose needs a measured state (3,) and sigmas (3,)")
        if heading_bias is not None and not with_heading:
            raise ValueError("a heading bias needs a measured heading")
        self.lever_arm_key = lever_arm
        self.heading_bias_key = heading_bias
        self.rows = 3 if with_heading else 2
        self.robust = float(robust)
        self.offset = np.zeros(2) if offset is None else np.array(offset, dtype=float)

    @property
    def keys(self) -> list[int]:
        """The factor's keys: pose, lever_arm, heading_bias (those given)."""
        slots = (self.pose_key, self.lever_arm_key, self.heading_bias_key)
        return [k for k in slots if k is not None]

    def factor(self) -> gtsam.CustomFactor:
        """The ``gtsam.CustomFactor`` of this measurement."""
        noise = gtsam.noiseModel.Diagonal.Sigmas(self.sigmas[: self.rows])
        if self.robust > 0:
            huber = gtsam.noiseModel.mEstimator.Huber.Create(self.robust)
            noise = gtsam.noiseModel.Robust.Create(huber, noise)
        return gtsam.CustomFactor(noise, self.keys, self)

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        state = state_from_pose2(values.atPose2(self.pose_key), float(self.measured[2]))
        arm = self.offset
        if self.lever_arm_key is not None:
            arm = arm + values.atVector(self.lever_arm_key)
        bias = 0.0
        if self.heading_bias_key is not None:
            bias = float(values.atVector(self.heading_bias_key)[0])
        cos, sin = np.cos(state[2]), np.sin(state[2])
        rotation = np.array([[cos, -sin], [sin, cos]])
        error = np.empty(3)
        error[:2] = state[:2] + rotation @ arm - self.measured[:2]
        error[2] = wrap_angle(state[2] + bias - self.measured[2])
        if H is not None:
            d_state = np.eye(3)
            d_state[:2, 2] = np.array([[-sin, -cos], [cos, -sin]]) @ arm
            blocks = [d_state @ body_to_world(state[2])]
            if self.lever_arm_key is not None:
                blocks.append(np.vstack([rotation, np.zeros((1, 2))]))
            if self.heading_bias_key is not None:
                blocks.append(np.array([[0.0], [0.0], [1.0]]))
            for i, block in enumerate(blocks):
                H[i] = np.ascontiguousarray(block[: self.rows])
        return error[: self.rows]
