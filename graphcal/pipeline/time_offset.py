"""The time offset between the wheel and pose streams, as a profile over the graph's error.

Wheels that are late against the pose bias c_e, t_r and d by many σ (docs/method.md: 0.05 s
put c_e 18σ off on a 24 km drive). The joint solve's χ² over the selected segments, as a
function of the offset applied to the wheels (:func:`graphcal.data.timing.shift_wheel_rotations`),
is smallest at the true offset and close to a parabola around it: the minimum of the parabola
through the best grid point and its neighbours is the estimate, its curvature the σ
(χ²(τ) ≈ χ²_min + (τ − τ̂)² / σ², scaled by χ²/dof when the residuals are larger than the
noise model).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import Segments, gather_segments
from graphcal.data.timing import shift_wheel_rotations
from graphcal.errors import CalibrationFailed
from graphcal.pipeline.joint import JointSettings, calibrate_joint
from graphcal.pipeline.parallel import map_tasks


@dataclass(frozen=True)
class TimeOffset:
    """An estimated wheel-vs-pose time offset.

    Attributes:
        offset: [s] by which the wheel signals are late (the log is corrected by it).
        sigma: its standard deviation [s].
        offsets, chi2: the profile: offsets tried [s] and the joint solve's χ² at each.
        at_edge: the minimum lies at the end of the searched range (widen it).
    """

    offset: float
    sigma: float
    offsets: np.ndarray
    chi2: np.ndarray
    at_edge: bool

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {
            "offset_s": self.offset,
            "sigma_s": self.sigma,
            "profile": {"offset_s": self.offsets.tolist(), "chi2": self.chi2.tolist()},
            "at_edge_of_search": self.at_edge,
        }


def _chi2_task(log: DriveLog, selected: Segments, offset: float, settings: JointSettings):
    data = gather_segments(shift_wheel_rotations(log, offset), selected)
    try:
        solved = calibrate_joint(data, settings)
    except CalibrationFailed:
        return np.inf, 0
    return 2.0 * solved.final_error, solved.degrees_of_freedom


def estimate_time_offset(
    log: DriveLog,
    selected: Segments,
    settings: JointSettings,
    search: float = 0.2,
    step: float = 0.025,
    workers: int = 1,
    progress=None,
) -> TimeOffset:
    """The wheel-vs-pose offset [s] minimizing the joint solve's χ² over ``selected``.

    Args:
        log: the drive log; selected: the calibration segments to solve.
        settings: the joint solve's settings.
        search: the offsets tried run from ``-search`` to ``+search`` [s] ...
        step: ... in steps of ``step`` [s] (about the log's sample interval or a fraction).
        workers: processes for the profile's solves.
    """
    offsets = np.round(np.arange(-search, search + 0.5 * step, step), 9)
    tasks = [(log, selected, float(o), settings) for o in offsets]
    results = map_tasks(_chi2_task, tasks, workers, progress, "time-offset profile")
    chi2 = np.array([r[0] for r in results])
    dof = max(r[1] for r in results)
    if not np.isfinite(chi2).any():
        raise CalibrationFailed("time-offset profile: every joint solve failed")
    best = int(np.nanargmin(np.where(np.isfinite(chi2), chi2, np.nan)))
    at_edge = best in (0, len(offsets) - 1)
    offset, sigma = float(offsets[best]), float("nan")
    if not at_edge and np.all(np.isfinite(chi2[best - 1 : best + 2])):
        left, middle, right = chi2[best - 1 : best + 2]
        curvature = (left - 2.0 * middle + right) / step**2  # d²χ²/dτ²
        if curvature > 0:
            offset += 0.5 * step * (left - right) / (left - 2.0 * middle + right)
            scale = max(1.0, middle / dof) if dof > 0 else 1.0
            sigma = float(np.sqrt(2.0 * scale / curvature))
    return TimeOffset(offset, sigma, offsets, chi2, at_edge)
