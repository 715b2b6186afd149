"""How a ``[wheels]`` signal becomes revolutions: its kind's scale, the ECU's circumference,
a tick counter's resolution and wrap (for CSV columns and CAN signals alike)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graphcal.data.manifest import SPEED_UNITS, Manifest


@dataclass(frozen=True)
class WheelScale:
    """How ``[wheels]``'s values become revolutions: multiply by ``scale`` [rev per unit];
    ``resolution`` [rev] of a tick counter, ``wrap`` its wrap count; the keys read (SI)."""

    scale: float
    resolution: float | None = None
    wrap: float | None = None
    circumference: float | None = None
    ticks: float | None = None
    speed_unit: str | None = None


def wheel_scale(manifest: Manifest, kind: str, speed_unit: Callable[[], str]) -> WheelScale:
    """``[wheels]``'s ``circumference``, ``ticks_per_revolution`` and ``ticks_wrap`` for a
    wheel signal of ``kind``, read and checked (one-line errors); ``speed_unit`` gives the
    speed unit of kind "speed" once the circumference is known (a CSV's key, a DBC's unit)."""
    table = manifest.wheels
    circumference = ticks = unit = resolution = None
    if kind == "speed":
        circumference = manifest.number(table, "circumference", None, "wheels", positive=True)
        if circumference is None:
            raise manifest.error(
                "[wheels] kind = 'speed' needs circumference: the wheel circumference [m] the "
                "ECU used to turn rotations into speed (from its documentation; often 2.0)"
            )
        unit = speed_unit()
        scale = SPEED_UNITS[unit] / circumference
    elif kind == "angular_speed" or kind == "angle":
        scale = 1.0 / (2.0 * np.pi)
    elif kind == "rpm":
        scale = 1.0 / 60.0
    else:  # ticks
        ticks = manifest.number(table, "ticks_per_revolution", None, "wheels", positive=True)
        if ticks is None:
            raise manifest.error("[wheels] kind = 'ticks' needs ticks_per_revolution")
        scale = resolution = 1.0 / ticks
    wrap = manifest.number(table, "ticks_wrap", None, "wheels", positive=True)
    if wrap is not None and kind != "ticks":
        raise manifest.error("[wheels] ticks_wrap applies to kind = 'ticks' only")
    return WheelScale(scale, resolution, wrap, circumference, ticks, unit)


def unwrap_counter(counts: np.ndarray, modulus: float) -> np.ndarray:
    """A counter that wraps at ``modulus``, made monotonic across its wrap-arounds."""
    step = np.diff(counts)
    wraps = np.concatenate([[0.0], np.cumsum(np.where(step < -0.5 * modulus, modulus, 0.0))])
    return counts + wraps
