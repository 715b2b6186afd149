"""Display units of the paper (m, mm, m, mm·s²/m) for theta, lengths that fit the vehicle
(:func:`length_unit`: m for a car, mm for a small robot); SI everywhere else.

Only reports and CLI output convert; the code computes in SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Factor from SI to the paper's display unit, per parameter [c_e, c_d, t_r, d].
DISPLAY_SCALE = np.array([1.0, 1e3, 1.0, 1e3])
DISPLAY_UNITS = ("m", "mm", "m", "mm·s²/m")
#: Scale and unit for small differences in a parameter (c_e and t_r deviations read in mm).
DEVIATION_SCALE = np.array([1e3, 1e3, 1e3, 1e3])
DEVIATION_UNITS = ("mm", "mm", "mm", "mm·s²/m")


def to_display(theta: np.ndarray) -> np.ndarray:
    """theta (SI) in the paper's display units (m, mm, m, mm·s²/m)."""
    return np.asarray(theta, dtype=float) * DISPLAY_SCALE


#: A vehicle whose nominal track [m] is below this (a small robot) reads the lengths of its
#: position errors and lever arm in mm: in m they print 0.00.
SMALL_TRACK = 0.5


@dataclass(frozen=True)
class LengthUnit:
    """How reports print a length that fits the vehicle (SI in, ``name`` out).

    Attributes:
        name: ``"m"`` or ``"mm"``.
        scale: factor from m.
        digits: decimals in tables and progress lines; ``figure_digits`` in figures.
    """

    name: str
    scale: float
    digits: int
    figure_digits: int

    def format(self, value: float, *, sign: bool = False, figure: bool = False) -> str:
        """``value`` [m] in this unit, without the unit's name."""
        digits = self.figure_digits if figure else self.digits
        return f"{value * self.scale:{'+' if sign else ''}.{digits}f}"

    def spread(self, sigma: float) -> str:
        """A standard deviation [m] in this unit, never printed as 0 when it is not: more
        digits (two significant) where the unit's decimals would round it away."""
        text = self.format(sigma)
        if sigma > 0 and float(text) == 0.0:
            return f"{sigma * self.scale:.2g}"
        return text


METRES = LengthUnit("m", 1.0, 3, 2)
MILLIMETRES = LengthUnit("mm", 1e3, 1, 1)


def length_unit(track: float) -> LengthUnit:
    """The unit of position errors and lever arms for a vehicle of nominal ``track`` [m]:
    mm for a small robot (below :data:`SMALL_TRACK`), m for a car."""
    return MILLIMETRES if track < SMALL_TRACK else METRES


def time_text(t: float) -> str:
    """A time [s] with every digit it has (the shortest text that reads back as the same
    float), so that two different stamps never print alike: ``1763856111.5369999``."""
    return repr(float(t))
