"""A preintegrated wheel-odometry factor between two Pose2 keyframes, like GTSAM's ImuFactor.

:class:`WheelOdometryFactor` joins the Pose2 variables ``X_i``, ``X_j`` of two keyframes and the
shared 4-vector ``theta = [c_e, c_d, t_r, d]`` (SI) through a
:class:`~graphcal.factors.preintegration.PreintegratedWheelOdometry` of the wheel steps between
them. Its error has the layout of ``gtsam.BetweenFactorPose2``::

    D = Pose2(preintegrated.predict(theta)),   e = Logmap(D⁻¹ · (X_i⁻¹ · X_j))

so nothing is re-integrated while theta stays near the linearization point (the first-order
correction is used), and the inputs are re-integrated when theta moves beyond
``reintegration_thresholds`` — as GTSAM users repropagate an IMU preintegration when the bias
estimate moves. With theta fixed the factor is a plain C++ ``BetweenFactorPose2``
(:func:`wheel_odometry_between_factor`).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.factors.preintegration import (
    DEFAULT_FLOOR_SIGMAS,
    DEFAULT_WHEEL_NOISE,
    PreintegratedWheelOdometry,
)

#: Theta changes [m, m, m, s²] beyond which the inputs are re-integrated instead of using the
#: first-order correction (c_e 5 mm, c_d 1 mm, t_r 2 cm, d 1e-3 s²).
DEFAULT_REINTEGRATION_THRESHOLDS = np.array([5e-3, 1e-3, 2e-2, 1e-3])


def preintegrate(
    inputs: np.ndarray,
    theta: np.ndarray,
    wheel_noise: float = DEFAULT_WHEEL_NOISE,
    keep_correction_jacobian: bool = False,
    quantization: float = 0.0,
) -> PreintegratedWheelOdometry:
    """Preintegrate ``inputs (L, 4)`` ``[n_rl, n_rr, beta, ay]`` at ``theta (4,)`` [SI] in one call.

    ``wheel_noise`` [rev] is the standard deviation of one measured wheel rotation per step,
    ``quantization`` [rev] that of a cumulative tick count's rounding (0: not counted).
    """
    preintegrated = PreintegratedWheelOdometry(
        theta, wheel_noise, keep_correction_jacobian, quantization
    )
    preintegrated.integrate_measurements(inputs)
    return preintegrated


def _beyond(theta: np.ndarray, reference: np.ndarray, thresholds: np.ndarray) -> bool:
    return bool(np.any(np.abs(theta - reference) > thresholds))


def wheel_odometry_between_factor(
    pose_i_key: int,
    pose_j_key: int,
    preintegrated: PreintegratedWheelOdometry,
    theta: np.ndarray,
    floor_sigmas: Sequence[float] | None = DEFAULT_FLOOR_SIGMAS,
    reintegration_thresholds: np.ndarray = DEFAULT_REINTEGRATION_THRESHOLDS,
) -> gtsam.BetweenFactorPose2:
    """The wheel odometry with theta fixed: a C++ ``BetweenFactorPose2`` (no Python callback).

    Measurement ``Pose2(preintegrated.predict(theta))``, noise
    ``Gaussian.Covariance(preintegrated.tangent_covariance(theta, floor_sigmas))``. If theta is
    beyond ``reintegration_thresholds`` [SI] of the linearization point, a copy of
    ``preintegrated`` is re-integrated at theta first (``preintegrated`` is not modified).
    """
    theta = np.asarray(theta, dtype=float)
    thresholds = np.asarray(reintegration_thresholds, dtype=float)
    if _beyond(theta, preintegrated.theta_linearization, thresholds):
        preintegrated = preintegrated.copy()
        preintegrated.reintegrate(theta)
    noise = gtsam.noiseModel.Gaussian.Covariance(
        preintegrated.tangent_covariance(theta, floor_sigmas)
    )
    return gtsam.BetweenFactorPose2(pose_i_key, pose_j_key, preintegrated.delta_pose(theta), noise)


class WheelOdometryFactor:
    """Preintegrated wheel odometry between Pose2 keys ``i``, ``j`` with theta as a variable.

    Error (3,) [m, m, rad] in the Pose2 tangent, as ``BetweenFactorPose2``::

        B = X_i⁻¹ X_j,  D = Pose2(delta + d_delta_d_theta (theta − theta_lin)),
        E = D⁻¹ B,      e = Logmap(E)

    Jacobians (right perturbations ``X ← X Exp(ξ)``, ``J_r⁻¹(e)`` = ``Pose2.LogmapDerivative``):

    * ``d e/d ξ_i = J_r⁻¹(e) H1``, ``d e/d ξ_j = J_r⁻¹(e) H2`` with ``H1 = −Ad(B⁻¹)``,
      ``H2 = I`` from ``X_i.between(X_j, H1, H2)`` (E = D⁻¹B moves with B's right tangent);
    * ``D ← D Exp(η)`` gives ``E ← Exp(−η) E = E Exp(−Ad(E⁻¹) η)``, so
      ``d e/d η = −J_r⁻¹(e) Ad(E⁻¹)``; a state change ``dδ`` of D is the tangent
      ``η = M dδ``, ``M = diag(R(ψ_D)ᵀ, 1)``, and ``dδ = d_delta_d_theta dθ``, hence
      ``d e/d theta = −J_r⁻¹(e) Ad(E⁻¹) M d_delta_d_theta``.

    Args:
        pose_i_key, pose_j_key: the Pose2 keyframes at the interval's start and end.
        theta_key: the shared 4-vector theta ``[c_e, c_d, t_r, d]`` (SI).
        preintegrated: the interval's preintegration; the factor keeps (and re-integrates)
            its own copy, as ``gtsam.ImuFactor`` copies its PIM.
        floor_sigmas: model-error floor [m, m, rad] of the noise model (``None``: none).
        reintegration_thresholds: ``(4,)`` [SI]; when ``|theta − theta_lin|`` exceeds one of
            them the inputs are re-integrated at theta before the error is evaluated.
        slip_key: optional 2-vector ``[s_rl, s_rr]`` of relative wheel-slip scales over the
            interval (slow slip: the rotation of wheel w is ``n_w (1 + s_w)``). A scale acts as
            a change of that wheel's circumference (eqs. 3a, 3b), so the factor evaluates at
            ``theta + S s`` with ``S = d[c_e, c_d, t_r, d]/d s`` built from the circumferences
            at the construction's linearization point (constant, so the Jacobian
            ``d e/d s = d e/d theta · S`` is exact; the relative error of that reference,
            ``d·a_y/c_e``, is about 1e-3 of the slip).
        slip_noise: ``(2, 2)`` covariance of slip scales that are not estimated (no
            ``slip_key``), added to the noise model through the same Jacobian, or ``None``.

    The noise model ``Gaussian.Covariance(tangent_covariance())`` is fixed at construction.
    """

    def __init__(
        self,
        pose_i_key: int,
        pose_j_key: int,
        theta_key: int,
        preintegrated: PreintegratedWheelOdometry,
        floor_sigmas: Sequence[float] | None = DEFAULT_FLOOR_SIGMAS,
        reintegration_thresholds: np.ndarray = DEFAULT_REINTEGRATION_THRESHOLDS,
        slip_key: int | None = None,
        slip_noise: np.ndarray | None = None,
    ) -> None:
        if preintegrated.n_steps == 0 and floor_sigmas is None:
            raise ValueError("an empty preintegration needs floor_sigmas for its noise model")
        if slip_key is not None and slip_noise is not None:
            raise ValueError(
                "give slip_key (slip estimated) or slip_noise (slip as noise), not both"
            )
        thresholds = np.array(reintegration_thresholds, dtype=float)
        if thresholds.shape != (4,) or not np.all(thresholds > 0):
            raise ValueError(f"reintegration_thresholds must be 4 values > 0, got {thresholds}")
        self.pose_i_key = pose_i_key
        self.pose_j_key = pose_j_key
        self.theta_key = theta_key
        self.slip_key = slip_key
        self.slip_to_theta = slip_to_theta(preintegrated.theta_linearization)
        self.preintegrated = preintegrated.copy()
        self.floor_sigmas = None if floor_sigmas is None else tuple(map(float, floor_sigmas))
        self.reintegration_thresholds = thresholds
        self._set_window()
        self.n_reintegrations = 0
        covariance = self.preintegrated.tangent_covariance(floor_sigmas=self.floor_sigmas)
        if slip_noise is not None:
            pim = self.preintegrated
            c, s = np.cos(pim.delta[2]), np.sin(pim.delta[2])
            tangent = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
            d_slip = tangent @ pim.d_delta_d_theta @ self.slip_to_theta
            covariance = covariance + d_slip @ np.asarray(slip_noise, float) @ d_slip.T
        self.noise_model = gtsam.noiseModel.Gaussian.Covariance(0.5 * (covariance + covariance.T))

    def factor(self) -> gtsam.CustomFactor:
        """A ``gtsam.CustomFactor`` (keys ``[pose_i, pose_j, theta]``, then ``slip`` if
        given) to add to a graph.

        Every call makes a new CustomFactor around this object (they share its state).
        """
        keys = [self.pose_i_key, self.pose_j_key, self.theta_key]
        if self.slip_key is not None:
            keys.append(self.slip_key)
        return gtsam.CustomFactor(self.noise_model, keys, self)

    def between_factor(self, theta: np.ndarray) -> gtsam.BetweenFactorPose2:
        """This factor with theta fixed, as a C++ ``BetweenFactorPose2``
        (see :func:`wheel_odometry_between_factor`)."""
        return wheel_odometry_between_factor(
            self.pose_i_key,
            self.pose_j_key,
            self.preintegrated,
            theta,
            self.floor_sigmas,
            self.reintegration_thresholds,
        )

    def relinearize_if_needed(self, theta: np.ndarray) -> bool:
        """Re-integrate at ``theta`` if it is beyond the thresholds; ``True`` if it did."""
        window = self._window
        # Plain floats: called for every factor at every error evaluation, where numpy's
        # per-call overhead on 4-vectors was an eighth of a smoothing solve.
        inside = zip(window[0], theta.tolist(), window[1], strict=True)
        if all(lo <= x <= hi for lo, x, hi in inside) or not np.all(np.isfinite(theta)):
            return False  # a non-finite theta gives a non-finite error, which LM rejects
        self.preintegrated.reintegrate(theta)
        self._set_window()
        self.n_reintegrations += 1
        return True

    def _set_window(self) -> None:
        """Theta range ``(low, high)`` in which the preintegration is used to first order."""
        reference = self.preintegrated.theta_linearization
        thresholds = self.reintegration_thresholds
        self._window = ((reference - thresholds).tolist(), (reference + thresholds).tolist())

    def evaluate(
        self,
        pose_i: gtsam.Pose2,
        pose_j: gtsam.Pose2,
        theta: np.ndarray,
        jacobians: bool = False,
        slip: np.ndarray | None = None,
    ) -> tuple[np.ndarray, list[np.ndarray] | None]:
        """Error (3,) and, with ``jacobians``, ``[d e/d ξ_i, d e/d ξ_j, d e/d theta]``
        (and ``d e/d slip`` when ``slip`` is given).

        The inputs are re-integrated when theta moves beyond the thresholds; slip scales
        always enter through the first-order correction (they are small and change from
        interval to interval: re-integrating on them would make the error jump wherever a
        scale crosses a threshold)."""
        theta = np.asarray(theta, dtype=float)
        self.relinearize_if_needed(theta)
        if slip is not None:
            theta = theta + self.slip_to_theta @ np.asarray(slip, dtype=float)
        pim = self.preintegrated
        predicted = pim.predict(theta)
        measured = gtsam.Pose2(predicted[0], predicted[1], predicted[2])
        if not jacobians:
            return gtsam.Pose2.Logmap(measured.between(pose_i.between(pose_j))), None
        h1 = np.empty((3, 3), order="F")
        h2 = np.empty((3, 3), order="F")
        relative = pose_i.between(pose_j, h1, h2)
        residual_pose = measured.between(relative)
        error = gtsam.Pose2.Logmap(residual_pose)
        log_derivative = gtsam.Pose2.LogmapDerivative(error)
        c, s = np.cos(measured.theta()), np.sin(measured.theta())
        d_theta = pim.d_delta_d_theta
        tangent_d_theta = np.vstack(
            [c * d_theta[0] + s * d_theta[1], c * d_theta[1] - s * d_theta[0], d_theta[2]]
        )
        d_measured = -log_derivative @ residual_pose.inverse().AdjointMap()
        d_theta_error = d_measured @ tangent_d_theta
        out = [log_derivative @ h1, log_derivative @ h2, d_theta_error]
        if slip is not None:
            out.append(d_theta_error @ self.slip_to_theta)
        return error, out

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        error, jac = self.evaluate(
            values.atPose2(self.pose_i_key),
            values.atPose2(self.pose_j_key),
            values.atVector(self.theta_key),
            H is not None,
            None if self.slip_key is None else values.atVector(self.slip_key),
        )
        if H is not None:
            for i, block in enumerate(jac):
                H[i] = block
        return error


def slip_to_theta(theta: np.ndarray) -> np.ndarray:
    """``(4, 2)`` change of ``[c_e, c_d, t_r, d]`` per relative slip scale ``[s_rl, s_rr]``
    at ``theta``: a scale ``s_w`` stretches wheel w's circumference (eqs. 3a, 3b,
    ``c_rl = c_e + c_d/2``, ``c_rr = c_e − c_d/2`` at zero lateral acceleration) by
    ``c_w s_w``, i.e. ``c_e`` by the mean and ``c_d`` by the difference of the two."""
    c_e, c_d = float(theta[0]), float(theta[1])
    c_rl, c_rr = c_e + 0.5 * c_d, c_e - 0.5 * c_d
    out = np.zeros((4, 2))
    out[0] = 0.5 * c_rl, 0.5 * c_rr
    out[1] = c_rl, -c_rr
    return out
