"""Display units of the paper (m, mm, m, mm·s²/m) for theta; SI everywhere else.

Only reports and CLI output convert; the code computes in SI.
"""

from __future__ import annotations

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
