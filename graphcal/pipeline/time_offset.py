"""The time offset between the wheel and pose streams, from a χ² profile of the joint solve.

Wheels that are late against the pose bias c_e, t_r and d by many σ (docs/method.md: 0.05 s
put c_e 18σ off on a 24 km drive). The offset applied to the wheels
(:func:`graphcal.data.timing.shift_wheel_rotations`) is profiled
(:mod:`graphcal.pipeline.profile`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import Segments
from graphcal.pipeline.joint import JointSettings
from graphcal.pipeline.profile import ProfileEstimate, profile_estimate


def estimate_time_offset(
    log: DriveLog,
    selected: Segments,
    settings: JointSettings,
    search: float = 0.2,
    step: float = 0.05,
    workers: int = 1,
    progress: Callable[[str], None] | None = None,
) -> ProfileEstimate:
    """The offset [s] by which the wheels are late against the pose, tried from ``-search``
    to ``+search`` in steps of ``step`` [s] and refined by the profile's parabola."""
    grid = np.round(np.arange(-search, search + 0.5 * step, step), 9)
    return profile_estimate("time_offset", log, selected, settings, grid, workers, progress)
