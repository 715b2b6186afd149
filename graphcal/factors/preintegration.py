"""Preintegrated wheel odometry, modelled on GTSAM's ``PreintegratedImuMeasurements``.

Eq. (1) is rotation- and translation-invariant: integrating the wheel inputs of an interval
from a start state ``s`` ends at ``Pose2(s) * Pose2(delta)``, where ``delta = [dx, dy, dpsi]``
(body frame of the start [m, m], heading change [rad], unwrapped) is the integration from the
zero state. :class:`PreintegratedWheelOdometry` accumulates ``delta`` once, at a linearization
point ``theta_linearization``, together with

* ``d_delta_d_theta`` (3, 4) — first-order correction for a different theta (the role of the
  IMU bias Jacobians);
* ``covariance`` (3, 3) — the wheel-rotation noise propagated to ``delta``
  (``wheel_noise² J_n J_nᵀ``, ``J_n = d delta / d wheel rotations``), and, for encoders that
  count ticks, the rounding of the cumulative counts (``quantization``): step ``k``'s rotation
  error is ``e_(k+1) − e_k`` with ``e`` the rounding error at the sample, so neighbouring steps'
  errors cancel and the increment sees ``quantization² Σ_j D_j D_jᵀ``,
  ``D_j = J_(j−1) − J_j`` (per wheel, ``J_(−1) = J_L = 0``);
* optionally ``d_delta_d_corrections`` (3, 2L) — ``J_n`` itself, columns
  ``[n_rl_0, n_rr_0, n_rl_1, ...]``.

Blocks of steps are appended by SE(2) composition (chain rule for the Jacobians and the
covariance), so appending costs O(block) whatever came before, and appending in pieces equals
integrating all at once to float rounding. The raw inputs are kept for :meth:`reintegrate`.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.model import integrate_with_jacobians
from graphcal.rotation_jacobians import end_wheel_rotation_jacobian

#: Standard deviation [rev] of one measured wheel rotation per sample (the paper's, §3.3).
DEFAULT_WHEEL_NOISE = 0.0005
#: Model-error floor [m, m, rad] added in :meth:`PreintegratedWheelOdometry.tangent_covariance`.
DEFAULT_FLOOR_SIGMAS = (1e-3, 1e-3, 1e-4)


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _compose_jacobians(delta1: np.ndarray, delta2: np.ndarray) -> tuple[np.ndarray, ...]:
    """``delta1 ∘ delta2`` in state coordinates and its Jacobians ``A = d/d delta1``,
    ``B = d/d delta2`` (headings add, unwrapped)."""
    rot = _rotation(delta1[2])
    moved = rot @ delta2[:2]  # delta2's translation in delta1's start frame [m]
    composed = np.array([delta1[0] + moved[0], delta1[1] + moved[1], delta1[2] + delta2[2]])
    a = np.eye(3)
    a[0, 2], a[1, 2] = -moved[1], moved[0]
    b = np.eye(3)
    b[:2, :2] = rot
    return composed, a, b


def _wheel_covariance(d_wheels: np.ndarray, white: float, quantization: float) -> np.ndarray:
    """``(G, 3, 3)`` covariance of the increments whose wheel-rotation Jacobians are
    ``d_wheels (G, 3, 2L)`` (columns ``[n_rl_0, n_rr_0, n_rl_1, ...]``): white rotation noise
    ``white`` [rev] per step plus count rounding ``quantization`` [rev] at every sample."""
    covariance = white**2 * d_wheels @ d_wheels.transpose(0, 2, 1)
    if quantization > 0:
        per_wheel = d_wheels.reshape(*d_wheels.shape[:2], -1, 2)  # (G, 3, L, 2)
        padded = np.pad(per_wheel, ((0, 0), (0, 0), (1, 1), (0, 0)))
        rounding = (padded[:, :, :-1] - padded[:, :, 1:]).reshape(*d_wheels.shape[:2], -1)
        covariance = covariance + quantization**2 * rounding @ rounding.transpose(0, 2, 1)
    return covariance


class PreintegratedWheelOdometry:
    """Wheel steps of eq. (1) integrated into one body-frame increment ``delta``.

    Args:
        theta_linearization: ``(4,)`` ``[c_e, c_d, t_r, d]`` [m, m, m, s²] to integrate at.
        wheel_noise: standard deviation [rev] of one measured wheel rotation per step.
        keep_correction_jacobian: also keep ``d_delta_d_corrections`` (3, 2L).
        quantization: standard deviation [rev] of the rounding error of each wheel's
            cumulative tick count (``1 / (ticks √12)``,
            :func:`graphcal.log.quantization.quantization_sigma`), or 0. Its part of the
            covariance is computed over the whole interval when read, so appending in pieces
            gives the covariance of one block (consecutive keyframe intervals, separate
            preintegrations, treat the count at their common sample as two independent
            errors, which overstates their variance a little).
    """

    def __init__(
        self,
        theta_linearization: np.ndarray,
        wheel_noise: float = DEFAULT_WHEEL_NOISE,
        keep_correction_jacobian: bool = False,
        quantization: float = 0.0,
    ) -> None:
        theta = np.array(theta_linearization, dtype=float)
        if theta.shape != (4,) or not np.all(np.isfinite(theta)):
            raise ValueError(f"theta_linearization must be 4 finite numbers, got {theta}")
        if not (np.isfinite(wheel_noise) and wheel_noise >= 0):
            raise ValueError(f"wheel_noise must be a finite number >= 0 [rev], got {wheel_noise}")
        if not (np.isfinite(quantization) and quantization >= 0):
            raise ValueError(f"quantization must be a finite number >= 0 [rev], got {quantization}")
        self._theta = theta
        self.wheel_noise = float(wheel_noise)
        self.quantization = float(quantization)
        self.keep_correction_jacobian = bool(keep_correction_jacobian)
        self.reset()

    # ----------------------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget all steps (keeps theta_linearization and wheel_noise)."""
        self._delta = np.zeros(3)
        self._d_theta = np.zeros((3, 4))
        self._covariance = np.zeros((3, 3))
        self._n_steps = 0
        self._input_blocks: list[np.ndarray] = []
        # The correction Jacobian is kept in a form that appending does not change: column j
        # is [g_j + J p_end h_j; h_j] (J = 90° rotation, p_end = delta[:2]), where g_j (2,)
        # and h_j = d dpsi / d n_j are in the start frame and independent of later steps.
        self._g_blocks: list[np.ndarray] = []
        self._h_blocks: list[np.ndarray] = []
        self._cache: dict[str, np.ndarray] = {}
        # Single samples wait here and are integrated as one block when a result is read.
        self._pending: list[tuple[float, float, float, float]] = []

    def _flush(self) -> None:
        """Integrate the buffered single samples (one vectorized block)."""
        if self._pending:
            rows = np.array(self._pending, dtype=float)
            self._pending = []
            self._integrate_block(rows)

    def copy(self) -> PreintegratedWheelOdometry:
        """An independent copy (blocks and cached results are never modified in place, so
        they are shared: a factor's copy keeps the tick rounding computed for its interval)."""
        self._flush()
        other = PreintegratedWheelOdometry(
            self._theta, self.wheel_noise, self.keep_correction_jacobian, self.quantization
        )
        other._delta = self._delta.copy()
        other._d_theta = self._d_theta.copy()
        other._covariance = self._covariance.copy()
        other._n_steps = self._n_steps
        other._input_blocks = list(self._input_blocks)
        other._g_blocks = list(self._g_blocks)
        other._h_blocks = list(self._h_blocks)
        other._cache = dict(self._cache)
        return other

    @property
    def theta_linearization(self) -> np.ndarray:
        """``(4,)`` theta [SI] that ``delta`` and its Jacobians are integrated at."""
        return self._theta.copy()

    @property
    def delta(self) -> np.ndarray:
        """``(3,)`` ``[dx, dy, dpsi]`` [m, m, rad]: end pose in the start pose's frame."""
        self._flush()
        return self._delta.copy()

    @property
    def d_delta_d_theta(self) -> np.ndarray:
        """``(3, 4)`` d delta / d theta at theta_linearization."""
        self._flush()
        return self._d_theta.copy()

    @property
    def covariance(self) -> np.ndarray:
        """``(3, 3)`` [m², m², rad²] covariance of delta (state coordinates, no floor)."""
        self._flush()
        return self._covariance + self._rounding_covariance()

    def _rounding_covariance(self) -> np.ndarray:
        """The tick rounding's part of the covariance, over the whole interval (cached)."""
        if self.quantization == 0 or self._n_steps == 0:
            return np.zeros((3, 3))
        if "rounding" not in self._cache:
            inputs = self.inputs
            states = integrate_with_jacobians(np.zeros(3), inputs, self._theta, False)[0]
            d_wheels = end_wheel_rotation_jacobian(states, inputs, self._theta).reshape(3, -1)
            self._cache["rounding"] = _wheel_covariance(d_wheels[None], 0.0, self.quantization)[0]
        return self._cache["rounding"]

    @property
    def n_steps(self) -> int:
        """Number of integrated 40 Hz steps ``L``."""
        self._flush()
        return self._n_steps

    @property
    def inputs(self) -> np.ndarray:
        """``(L, 4)`` the integrated raw inputs ``[n_rl, n_rr, beta, ay]``."""
        self._flush()
        if "inputs" not in self._cache:
            self._cache["inputs"] = (
                np.concatenate(self._input_blocks) if self._input_blocks else np.zeros((0, 4))
            )
        return self._cache["inputs"].copy()

    @property
    def d_delta_d_corrections(self) -> np.ndarray:
        """``(3, 2L)`` d delta / d wheel rotations [m/rev, m/rev, rad/rev], columns
        ``[n_rl_0, n_rr_0, n_rl_1, ...]``; needs ``keep_correction_jacobian``."""
        if not self.keep_correction_jacobian:
            raise AttributeError("constructed without keep_correction_jacobian=True")
        self._flush()
        if "corrections" not in self._cache:
            g = np.concatenate(self._g_blocks, axis=1) if self._g_blocks else np.zeros((2, 0))
            h = np.concatenate(self._h_blocks) if self._h_blocks else np.zeros(0)
            x, y = self._delta[0], self._delta[1]
            self._cache["corrections"] = np.vstack([g[0] - y * h, g[1] + x * h, h])
        return self._cache["corrections"].copy()

    # ------------------------------------------------------------------------ integration
    def integrate_measurements(self, inputs: np.ndarray) -> None:
        """Append a block of steps ``inputs (L, 4)`` ``[n_rl, n_rr, beta, ay]`` [rev, rev, rad,
        m/s²], integrated vectorized at theta_linearization and composed onto ``delta``."""
        inputs = np.array(inputs, dtype=float, ndmin=2)
        if inputs.ndim != 2 or inputs.shape[1] != 4:
            raise ValueError(f"inputs must be (L, 4) [n_rl, n_rr, beta, ay], got {inputs.shape}")
        if not np.all(np.isfinite(inputs)):
            raise ValueError("inputs must be finite")
        self._flush()
        if len(inputs) > 0:
            self._integrate_block(inputs)

    def integrate_measurement(self, n_rl: float, n_rr: float, beta: float, ay: float) -> None:
        """Append one step: wheel rotations [rev], sideslip [rad], lateral acceleration [m/s²].

        The sample is buffered and integrated with the following ones as one block (through
        :meth:`integrate_measurements`) when a result is next read, so a call costs O(1).
        """
        row = (float(n_rl), float(n_rr), float(beta), float(ay))
        if not np.all(np.isfinite(row)):
            raise ValueError(f"inputs must be finite, got {row}")
        self._pending.append(row)

    def _integrate_block(self, inputs: np.ndarray) -> None:
        """Integrate a validated ``(L >= 1, 4)`` block and compose it onto this interval."""
        states, _, d_theta = integrate_with_jacobians(np.zeros(3), inputs, self._theta)
        d_wheels = end_wheel_rotation_jacobian(states, inputs, self._theta).reshape(3, -1)
        delta = states[-1]
        covariance = _wheel_covariance(d_wheels[None], self.wheel_noise, 0.0)[0]
        g = h = None
        if self.keep_correction_jacobian:
            h = d_wheels[2]
            g = np.vstack([d_wheels[0] + delta[1] * h, d_wheels[1] - delta[0] * h])
        inputs.setflags(write=False)
        self._append(delta, d_theta[-1], covariance, len(inputs), [inputs], g, h)

    def _append(
        self,
        delta: np.ndarray,
        d_theta: np.ndarray,
        covariance: np.ndarray,
        n_steps: int,
        input_blocks: list[np.ndarray],
        g: np.ndarray | None,
        h: np.ndarray | None,
    ) -> None:
        """Compose an interval (given in its own start frame) onto the end of this one."""
        composed, a, b = _compose_jacobians(self._delta, delta)
        if self.keep_correction_jacobian:
            # Move the new columns into this start frame: g' = R1 g - J p1 h.
            g = _rotation(self._delta[2]) @ g
            g = np.vstack([g[0] + self._delta[1] * h, g[1] - self._delta[0] * h])
            self._g_blocks.append(g)
            self._h_blocks.append(h)
        self._delta = composed
        self._d_theta = a @ self._d_theta + b @ d_theta
        self._covariance = a @ self._covariance @ a.T + b @ covariance @ b.T
        self._n_steps += n_steps
        self._input_blocks.extend(input_blocks)
        self._cache.clear()

    def reintegrate(self, theta: np.ndarray) -> None:
        """Integrate the kept inputs again at a new linearization point ``theta`` (4,) [SI]."""
        theta = np.array(theta, dtype=float)
        if theta.shape != (4,) or not np.all(np.isfinite(theta)):
            raise ValueError(f"theta must be 4 finite numbers, got {theta}")
        inputs = self.inputs
        self._theta = theta
        self.reset()
        self.integrate_measurements(inputs)

    def merge(self, other: PreintegratedWheelOdometry) -> PreintegratedWheelOdometry:
        """Append the interval ``other`` (which starts where this one ends), in place.

        Both must share theta_linearization, wheel_noise, quantization and
        keep_correction_jacobian
        (else ``ValueError``). Returns ``self``.
        """
        self._flush()
        other._flush()
        if not np.array_equal(self._theta, other._theta):
            raise ValueError(
                f"cannot merge intervals linearized at different theta: {self._theta} and "
                f"{other._theta}; reintegrate one of them first"
            )
        if self.wheel_noise != other.wheel_noise:
            raise ValueError("cannot merge intervals with different wheel_noise")
        if self.quantization != other.quantization:
            raise ValueError("cannot merge intervals with different quantization")
        if self.keep_correction_jacobian != other.keep_correction_jacobian:
            raise ValueError("cannot merge intervals with and without correction Jacobians")
        g = h = None
        if self.keep_correction_jacobian:
            g = np.concatenate(other._g_blocks, axis=1) if other._g_blocks else np.zeros((2, 0))
            h = np.concatenate(other._h_blocks) if other._h_blocks else np.zeros(0)
        self._append(
            other._delta,
            other._d_theta,
            other._covariance,
            other._n_steps,
            list(other._input_blocks),
            g,
            h,
        )
        return self

    @classmethod
    def merged(
        cls, first: PreintegratedWheelOdometry, second: PreintegratedWheelOdometry
    ) -> PreintegratedWheelOdometry:
        """A new preintegration of ``first`` followed by ``second`` (see :meth:`merge`)."""
        return first.copy().merge(second)

    @classmethod
    def from_intervals(
        cls,
        intervals: Sequence[np.ndarray],
        theta_linearization: np.ndarray,
        wheel_noise: float = DEFAULT_WHEEL_NOISE,
        quantization: float = 0.0,
    ) -> list[PreintegratedWheelOdometry]:
        """Preintegrate many intervals ``[(L_i, 4), ...]`` at once: one vectorized integration
        per distinct length (keyframe intervals mostly share one), so the cost is linear in
        the steps whatever a GNSS gap does to one interval. Equals one
        :meth:`integrate_measurements` per interval.
        """
        blocks = [np.asarray(block, dtype=float) for block in intervals]
        for i, block in enumerate(blocks):
            if block.ndim != 2 or block.shape[1] != 4 or len(block) == 0:
                raise ValueError(
                    f"interval {i}: inputs must be (L, 4) [n_rl, n_rr, beta, ay] with L >= 1, "
                    f"got {block.shape}"
                )
            if not np.all(np.isfinite(block)):
                raise ValueError(f"interval {i}: inputs must be finite")
        theta = np.asarray(theta_linearization, dtype=float)
        lengths = np.array([len(block) for block in blocks])
        out: list[PreintegratedWheelOdometry | None] = [None] * len(blocks)
        for length in np.unique(lengths):
            members = np.flatnonzero(lengths == length)
            stacked = np.stack([blocks[i] for i in members])  # (G, L, 4)
            start = np.zeros((len(members), 3))
            states, _, d_theta = integrate_with_jacobians(start, stacked, theta)
            flat = end_wheel_rotation_jacobian(states, stacked, theta).reshape(len(members), 3, -1)
            covariance = _wheel_covariance(flat, wheel_noise, 0.0)
            rounding = _wheel_covariance(flat, 0.0, quantization) if quantization > 0 else None
            for g, i in enumerate(members):
                preintegrated = cls(theta, wheel_noise, quantization=quantization)
                block = stacked[g].copy()
                block.setflags(write=False)
                preintegrated._delta = states[g, -1].copy()
                preintegrated._d_theta = d_theta[g, -1].copy()
                preintegrated._covariance = covariance[g]
                preintegrated._n_steps = int(length)
                preintegrated._input_blocks = [block]
                if rounding is not None:
                    preintegrated._cache["rounding"] = rounding[g]
                out[i] = preintegrated
        return out  # type: ignore[return-value]

    # -------------------------------------------------------------------------- results
    def predict(self, theta: np.ndarray | None = None) -> np.ndarray:
        """``(3,)`` delta [m, m, rad] at ``theta`` to first order:
        ``delta + d_delta_d_theta (theta - theta_linearization)`` (heading unwrapped)."""
        self._flush()
        if theta is None:
            return self._delta.copy()
        return self._delta + self._d_theta @ (np.asarray(theta, dtype=float) - self._theta)

    def delta_pose(self, theta: np.ndarray | None = None) -> gtsam.Pose2:
        """The (predicted) increment as a ``gtsam.Pose2``."""
        d = self.predict(theta)
        return gtsam.Pose2(float(d[0]), float(d[1]), float(d[2]))

    def tangent_covariance(
        self,
        theta: np.ndarray | None = None,
        floor_sigmas: Sequence[float] | None = DEFAULT_FLOOR_SIGMAS,
    ) -> np.ndarray:
        """``(3, 3)`` covariance in the Pose2 tangent at the (predicted) delta pose.

        ``M Σ Mᵀ + diag(floor_sigmas²)``, ``M = diag(R(dpsi)ᵀ, 1)`` (Pose2 retracts in its body
        frame). ``floor_sigmas`` [m, m, rad] is a model-error floor (``None``: none). Σ is the
        covariance at theta_linearization; ``theta`` only sets the rotation ``dpsi``.
        """
        self._flush()
        m = np.eye(3)
        m[:2, :2] = _rotation(self.predict(theta)[2]).T
        out = m @ (self._covariance + self._rounding_covariance()) @ m.T
        if floor_sigmas is not None:
            out += np.diag(np.asarray(floor_sigmas, dtype=float) ** 2)
        return 0.5 * (out + out.T)

    def __repr__(self) -> str:
        self._flush()
        return (
            f"PreintegratedWheelOdometry(n_steps={self._n_steps}, delta={self._delta}, "
            f"theta_linearization={self._theta})"
        )
