"""The settings that follow the vehicle: a vehicle profile's nominal theta, noise and size
give the defaults of ``theta_initial``, ``theta_prior_sigmas``, ``pose_weights`` and
``position_sigma`` of ``[calibration]`` and ``[joint]``, the joint solve's wheel noise, tick
rounding and ``fix_d``, and the segment lengths (the car's scaled by the vehicle's track)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection
from typing import Any

import numpy as np

from graphcal.pipeline.configuration.settings import Settings
from graphcal.vehicle import VehicleProfile


def apply_vehicle(
    settings: Settings, vehicle: VehicleProfile, *, keep: Collection[str] = ()
) -> Settings:
    """``settings`` for ``vehicle``: the settings that depend on the vehicle follow it.

    ``theta_initial`` and ``theta_prior_sigmas`` (from the vehicle's nominal theta and its
    sigmas), ``pose_weights`` and ``position_sigma`` of ``calibration`` and ``joint``, and
    ``joint.wheel_noise`` (the vehicle's effective wheel noise) take the vehicle's values,
    unless set otherwise: named in ``keep`` (``"joint.wheel_noise"``) or holding another value
    than the one ``settings.vehicle`` implies. A settings file's ``[vehicle]`` section is
    applied so, keeping the keys the file gives in ``[calibration]`` and ``[joint]``.
    """
    known = {f"{s}.{k}" for s, d in DERIVED_SECTIONS for k in d}
    unknown = sorted(set(keep) - known)
    if unknown:
        raise ValueError(
            f"keep names {unknown}, not settings that follow the vehicle: {sorted(known)}"
        )
    return follow_vehicle(settings, settings.vehicle, vehicle, set(keep))


#: The settings of a section that follow the vehicle, and how each derives from it.
_FROM_VEHICLE: dict[str, Callable[[VehicleProfile], Any]] = {
    "theta_initial": lambda v: v.theta_nominal.copy(),
    "theta_prior_sigmas": lambda v: v.solve_prior_sigmas(),
    "pose_weights": lambda v: v.pose_weights(),
    "position_sigma": lambda v: v.position_sigma,
}
_FROM_VEHICLE_JOINT = {
    **_FROM_VEHICLE,
    "wheel_noise": lambda v: v.white_wheel_noise(),
    "tick_quantization": lambda v: v.tick_quantization(),
    "fix_d": lambda v: v.fix_d,
}
#: The paper's car's segment lengths [m] (§5.1); a vehicle's scale with its size
#: (:meth:`~graphcal.vehicle.VehicleProfile.size_scale`: its track over the car's).
CAR_SEGMENT_LENGTH = 150.0
CAR_VALIDATION_LENGTH = 300.0
_FROM_VEHICLE_SEGMENTS: dict[str, Callable[[VehicleProfile], Any]] = {
    "length": lambda v: _scaled_length(CAR_SEGMENT_LENGTH, v),
    "validation_length": lambda v: _scaled_length(CAR_VALIDATION_LENGTH, v),
}
#: Per section, the settings that follow the vehicle and how each derives from it.
DERIVED_SECTIONS = (
    ("calibration", _FROM_VEHICLE),
    ("joint", _FROM_VEHICLE_JOINT),
    ("segments", _FROM_VEHICLE_SEGMENTS),
)


def segment_lengths(vehicle: VehicleProfile) -> tuple[float, float]:
    """The calibration and validation segment lengths [m] for ``vehicle``'s size."""
    return (
        _scaled_length(CAR_SEGMENT_LENGTH, vehicle),
        _scaled_length(CAR_VALIDATION_LENGTH, vehicle),
    )


def _scaled_length(car_length: float, vehicle: VehicleProfile) -> float:
    """``car_length`` [m] scaled to ``vehicle``'s size, to 0.1 m (exact for the car)."""
    scale = vehicle.size_scale()
    return car_length if scale == 1.0 else round(car_length * scale, 1)


def follow_vehicle(
    settings: Settings, previous: VehicleProfile, vehicle: VehicleProfile, keep: set[str]
) -> Settings:
    """``settings`` with ``vehicle``; each vehicle-dependent setting not in ``keep`` that
    still holds what ``previous`` implies takes what ``vehicle`` implies."""
    changes: dict[str, Any] = {"vehicle": vehicle}
    for section, derived in DERIVED_SECTIONS:
        current = getattr(settings, section)
        follow = {
            key: derive(vehicle)
            for key, derive in derived.items()
            if f"{section}.{key}" not in keep
            and np.array_equal(
                np.asarray(getattr(current, key), float), np.asarray(derive(previous), float)
            )
        }
        changes[section] = dataclasses.replace(current, **follow)
    return dataclasses.replace(settings, **changes)
