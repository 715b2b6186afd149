"""The vehicle a drive log comes from: its nominal theta and its sensors' noise (SI).

A :class:`VehicleProfile` holds what a datasheet and the sensors' specifications say before
any calibration: the nominal ``theta = [c_e, c_d, t_r, d]``, how far it may be off, the noise
of the measured poses and of the wheel rotations, and the wheel encoder's resolution. The
defaults are the paper's car (§3.3, §4.4): c_e = 2 m, t_r = 1.55 m, 0.2 m position noise, the
pose weights W = [1, 1, 50], 0.0005 rev wheel noise.

The profile is the ``[vehicle]`` section of a settings file (``graphcal calibrate --config``)
or a file of its own (:func:`graphcal.pipeline.configuration.settings_file.load_vehicle`); it
supplies the defaults of the settings that depend on the vehicle
(:func:`graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`) and the nominal theta
the data layer checks logs against. A delivery robot with 0.5 m wheel circumference and
0.2 m track, for example (``data/vehicles/delivery_robot.toml`` has every key with its unit)::

    name = "delivery robot"
    theta_nominal = [0.5, 0.0, 0.2, 0.0]                 # c_e m, c_d m, t_r m, d s²
    theta_prior_sigmas = [0.025, 0.0025, 0.025, 0.0025]  # same units
    position_sigma = 0.05       # m
    heading_sigma = 0.0175      # rad (1°)
    wheel_noise = 0.0005        # rev per sample interval
    ticks_per_revolution = 64   # encoder counts per wheel revolution

This module depends on numpy and the model only, so every layer may use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from graphcal.errors import check_settings
from graphcal.model import C_E, PARAMETER_NAMES, T_R, THETA_NOMINAL, THETA_PRIOR_SIGMAS

#: The paper's position noise [m] (§3.3) and heading sigma [rad] that, with it, gives the
#: paper's pose weights W = [1, 1, 50]: 0.2 / sqrt(50) = 0.028 rad (1.6°).
PAPER_POSITION_SIGMA = 0.2
PAPER_HEADING_SIGMA = PAPER_POSITION_SIGMA / math.sqrt(50.0)
#: A held parameter's prior sigma as a share of its datasheet sigma: 10⁻⁴ holds d to within
#: 10⁻⁷ s² of its nominal (0.1 µrad of yaw per m/s² of lateral acceleration and m of travel)
#: while the solve's normal equations stay well conditioned.
HELD_SIGMA_SCALE = 1e-4


def held_prior_sigmas(
    sigmas: np.ndarray | tuple[float, ...] | list[float], held: tuple[str, ...] | list[str]
) -> np.ndarray:
    """``(4,)`` theta prior ``sigmas`` with those of the parameters named in ``held``
    (:data:`~graphcal.model.PARAMETER_NAMES`) :data:`HELD_SIGMA_SCALE` times as large: held
    at the prior's mean."""
    out = np.array(sigmas, dtype=float)
    for name in held:
        out[PARAMETER_NAMES.index(name)] *= HELD_SIGMA_SCALE
    return out


@dataclass(frozen=True)
class VehicleProfile:
    """A vehicle's nominal theta and sensor noise; the defaults are the paper's car (SI).

    Attributes:
        name: what the profile describes (shown in ``calibration.json``).
        theta_nominal: ``[c_e, c_d, t_r, d]`` from the datasheet [m, m, m, s²]: the starting
            point of calibration, the "nominal" row of the report and what the log's
            plausibility checks convert wheel rotations with.
        theta_prior_sigmas: how far the datasheet may be off, same units: the weak prior on
            theta. The default is the car's (c_e ±10 cm, c_d ±1 cm, t_r ±20 cm, d ±0.01 s²);
            give a small vehicle its own (e.g. the same fractions of its nominal values).
        position_sigma: standard deviation [m] of the measured position.
        heading_sigma: standard deviation [rad] of the measured heading; with
            ``position_sigma`` it gives the pose weights (:meth:`pose_weights`).
        wheel_noise: standard deviation [rev] of a measured wheel rotation per sample interval,
            beyond the encoder's quantization.
        ticks_per_revolution: encoder counts per wheel revolution, or ``None`` when the
            rotations are not quantized noticeably (:meth:`tick_quantization`).
        reverses: wheels turning backwards are motion — a differential-drive robot spinning
            on the spot or reversing — integrated by eq. (1) like any other step. False (a
            car): the sideslip model covers forward driving only, so backwards wheels are
            masked as reversing.
        fix_d: hold d at its nominal value (a light vehicle without load transfer); it is
            then reported as fixed, not estimated.
    """

    name: str = "paper car"
    theta_nominal: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    position_sigma: float = PAPER_POSITION_SIGMA
    heading_sigma: float = PAPER_HEADING_SIGMA
    wheel_noise: float = 0.0005
    ticks_per_revolution: int | None = None
    reverses: bool = False
    fix_d: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"vehicle.name must be non-empty text, got {self.name!r}")
        for key in ("theta_nominal", "theta_prior_sigmas"):
            value = np.array(getattr(self, key), dtype=float)
            if value.shape != (4,):
                raise ValueError(
                    f"vehicle.{key} must be 4 numbers [c_e, c_d, t_r, d], got shape {value.shape}"
                )
            object.__setattr__(self, key, value)
        check_settings(
            "vehicle",
            positive_vectors={"theta_prior_sigmas": self.theta_prior_sigmas},
            finite_vectors={"theta_nominal": self.theta_nominal},
            positive={"position_sigma": self.position_sigma, "heading_sigma": self.heading_sigma},
            non_negative={"wheel_noise": self.wheel_noise},
        )
        for index, what in ((C_E, "c_e (wheel circumference)"), (T_R, "t_r (rear track)")):
            if not self.theta_nominal[index] > 0:
                raise ValueError(
                    f"vehicle.theta_nominal: {what} must be positive, got "
                    f"{self.theta_nominal[index]:g} m"
                )
        ticks = self.ticks_per_revolution
        if ticks is not None and not (
            isinstance(ticks, int) and not isinstance(ticks, bool) and ticks >= 1
        ):
            raise ValueError(
                f"vehicle.ticks_per_revolution must be a whole number >= 1, got {ticks!r}"
            )
        for key in ("reverses", "fix_d"):
            if not isinstance(getattr(self, key), bool):
                raise ValueError(f"vehicle.{key} must be true or false, got {getattr(self, key)!r}")
        if self.white_wheel_noise() <= 0:
            raise ValueError(
                "vehicle.wheel_noise must be positive unless ticks_per_revolution is given, "
                f"got {self.wheel_noise!r}"
            )

    def tick_quantization(self) -> float:
        """Rounding error sigma [rev] of a cumulative encoder count, ``1 / (tpr √12)`` (0
        without ``ticks_per_revolution``): ``[joint] tick_quantization``. A rotation during
        an interval is the difference of two counts, so errors of successive intervals
        cancel in a sum; the joint solve models exactly that
        (:func:`graphcal.factors.chunk_correction_prior`)."""
        if self.ticks_per_revolution is None:
            return 0.0
        return 1.0 / (self.ticks_per_revolution * math.sqrt(12.0))

    def white_wheel_noise(self) -> float:
        """``wheel_noise`` [rev], or a tenth of the tick quantization when it is 0 (counts with
        no noise of their own): ``[joint] wheel_noise``."""
        return float(self.wheel_noise) if self.wheel_noise > 0 else 0.1 * self.tick_quantization()

    def solve_prior_sigmas(self) -> np.ndarray:
        """The theta prior's sigmas a solve uses: ``theta_prior_sigmas``, with d's
        :data:`HELD_SIGMA_SCALE` times as large when ``fix_d`` (held at its nominal)."""
        return held_prior_sigmas(self.theta_prior_sigmas, ("d",) if self.fix_d else ())

    def size_scale(self) -> float:
        """The vehicle's size relative to the paper's car: nominal track / 1.55 m (1 for the
        car). Segment lengths scale with it
        (:func:`graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`)."""
        return float(self.theta_nominal[T_R] / THETA_NOMINAL[T_R])

    def pose_weights(self) -> tuple[float, float, float]:
        """The pose weights ``W = (1, 1, (position_sigma / heading_sigma)²)`` (§4.4).

        Rounded to 12 significant digits, so the paper's sigmas give exactly W = (1, 1, 50).
        """
        heading = (self.position_sigma / self.heading_sigma) ** 2
        return (1.0, 1.0, float(f"{heading:.12g}"))
