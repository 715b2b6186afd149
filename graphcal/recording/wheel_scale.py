"""How a ``[wheels]`` signal becomes revolutions: its kind's scale, the ECU's circumference,
a tick counter's resolution and wrap (for CSV columns and CAN signals alike)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graphcal.recording.section import Section
from graphcal.recording.vocabulary import SPEED_UNITS, WHEEL_KINDS


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


def wheel_scale(wheels: Section, kind: str, speed_unit: Callable[[], str]) -> WheelScale:
    """The ``wheels`` section's ``circumference``, ``ticks_per_revolution`` and ``ticks_wrap``
    for a wheel signal of ``kind`` (:data:`~graphcal.recording.vocabulary.WHEEL_KINDS`), read
    and checked (one-line errors); ``speed_unit`` gives the speed unit of kind "speed" once
    the circumference is known (a CSV's key, a DBC's unit)."""
    circumference = ticks = unit = resolution = None
    if kind == "speed":
        circumference = wheels.number("circumference", None, positive=True)
        if circumference is None:
            raise wheels.error(
                "[wheels] kind = 'speed' needs circumference: the wheel circumference [m] the "
                "ECU used to turn rotations into speed (from its documentation; often 2.0)"
            )
        unit = speed_unit()
        scale = SPEED_UNITS[unit] / circumference
    elif kind == "ticks":
        ticks = wheels.number("ticks_per_revolution", None, positive=True)
        if ticks is None:
            raise wheels.error("[wheels] kind = 'ticks' needs ticks_per_revolution")
        scale = resolution = 1.0 / ticks
    else:
        scale = WHEEL_KINDS[kind].revolutions_per_unit
    wrap = wheels.number("ticks_wrap", None, positive=True)
    if wrap is not None and kind != "ticks":
        raise wheels.error("[wheels] ticks_wrap applies to kind = 'ticks' only")
    return WheelScale(scale, resolution, wrap, circumference, ticks, unit)


def unwrap_counter(counts: np.ndarray, modulus: float) -> np.ndarray:
    """A counter that wraps at ``modulus``, made monotonic across its wrap-arounds."""
    step = np.diff(counts)
    wraps = np.concatenate([[0.0], np.cumsum(np.where(step < -0.5 * modulus, modulus, 0.0))])
    return counts + wraps
