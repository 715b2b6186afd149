"""Estimates from a χ² profile of the joint solve: a quantity the model does not carry as a
variable (a time offset, a lever arm) is applied to the log at a grid of values, the joint
solve over the selected segments is repeated at each, and the parabola through the smallest
χ² and its neighbours gives the estimate (its vertex) and σ (from its curvature:
χ²(x) ≈ χ²_min + (x − x̂)²/σ², scaled by χ²/dof when the residuals exceed the noise model).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from graphcal.data.antenna import move_to_centre
from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import Segments, gather_segments
from graphcal.data.timing import shift_wheel_rotations
from graphcal.errors import CalibrationFailed
from graphcal.pipeline.joint import JointSettings, calibrate_joint
from graphcal.pipeline.parallel import map_tasks

#: A profile whose σ exceeds this share of the searched span shows nothing.
MAX_SIGMA_SHARE = 0.1
#: How each profiled quantity is applied to a log (module level, so workers can pickle it).
APPLY: dict[str, Callable[[DriveLog, float], DriveLog]] = {
    "time_offset": shift_wheel_rotations,
    "lever_arm_longitudinal": lambda log, x: move_to_centre(log, (x, 0.0)),
    "lever_arm_lateral": lambda log, y: move_to_centre(log, (0.0, y)),
}


@dataclass(frozen=True)
class ProfileEstimate:
    """A quantity estimated from a χ² profile.

    Attributes:
        name: what was profiled (a key of :data:`APPLY`).
        value: the estimate (SI); sigma: its standard deviation (NaN if the profile has no
            minimum inside the grid or no curvature: not observable).
        grid, chi2: the values tried and the joint solve's χ² at each.
        at_edge: the smallest χ² lies at the end of the grid.
    """

    name: str
    value: float
    sigma: float
    grid: np.ndarray
    chi2: np.ndarray
    at_edge: bool

    @property
    def observable(self) -> bool:
        """The profile has a minimum inside its grid whose σ is small next to the grid's
        span (a flat profile — a quantity the drive does not show — has neither)."""
        span = float(self.grid[-1] - self.grid[0])
        return (
            not self.at_edge
            and bool(np.isfinite(self.sigma))
            and self.sigma < MAX_SIGMA_SHARE * span
        )

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {
            "value": self.value,
            "sigma": self.sigma if np.isfinite(self.sigma) else None,
            "observable": self.observable,
            "profile": {"values": self.grid.tolist(), "chi2": self.chi2.tolist()},
        }


def _chi2_task(
    log: DriveLog, selected: Segments, name: str, value: float, settings: JointSettings
) -> tuple[float, int]:
    data = gather_segments(APPLY[name](log, value), selected)
    try:
        solved = calibrate_joint(data, settings)
    except CalibrationFailed:
        return np.inf, 0
    return 2.0 * solved.final_error, solved.degrees_of_freedom


def _parabola(grid: np.ndarray, chi2: np.ndarray, dof: int) -> tuple[float, float, bool]:
    """Vertex and σ of the parabola through the smallest χ² and its neighbours, and whether
    the smallest lies at an end of the grid (then the vertex is that grid value, σ NaN)."""
    best = int(np.argmin(np.where(np.isfinite(chi2), chi2, np.inf)))
    at_edge = best in (0, len(grid) - 1)
    value, sigma = float(grid[best]), float("nan")
    if not at_edge and np.all(np.isfinite(chi2[best - 1 : best + 2])):
        left, middle, right = chi2[best - 1 : best + 2]
        step = float(grid[best + 1] - grid[best])
        second = left - 2.0 * middle + right
        if second > 0:
            value += 0.5 * step * (left - right) / second
            scale = max(1.0, middle / dof) if dof > 0 else 1.0
            sigma = float(np.sqrt(2.0 * scale * step**2 / second))
    return value, sigma, at_edge


def _profile(name, log, selected, settings, grid, workers, progress) -> tuple[np.ndarray, int]:
    tasks = [(log, selected, name, float(v), settings) for v in grid]
    results = map_tasks(_chi2_task, tasks, workers, progress, f"{name} profile")
    return np.array([r[0] for r in results]), max(r[1] for r in results)


def profile_estimate(
    name: str,
    log: DriveLog,
    selected: Segments,
    settings: JointSettings,
    grid: np.ndarray,
    workers: int = 1,
    progress: Callable[[str], None] | None = None,
) -> ProfileEstimate:
    """Estimate ``name`` (a key of :data:`APPLY`) from the χ² profile over ``grid``, refined
    by a second parabola through three points a quarter of the grid step apart around the
    first vertex (χ² is a parabola only near its minimum)."""
    grid = np.asarray(grid, float)
    chi2, dof = _profile(name, log, selected, settings, grid, workers, progress)
    if not np.isfinite(chi2).any():
        raise CalibrationFailed(f"{name} profile: every joint solve failed")
    value, sigma, at_edge = _parabola(grid, chi2, dof)
    if np.isfinite(sigma):
        quarter = 0.25 * float(grid[1] - grid[0])
        fine = value + quarter * np.array([-1.0, 0.0, 1.0])
        fine_chi2, fine_dof = _profile(name, log, selected, settings, fine, workers, None)
        refined, refined_sigma, fine_edge = _parabola(fine, fine_chi2, fine_dof)
        if not fine_edge and np.isfinite(refined_sigma):
            value, sigma = refined, refined_sigma
        grid, chi2 = np.concatenate([grid, fine]), np.concatenate([chi2, fine_chi2])
        order = np.argsort(grid, kind="stable")
        grid, chi2 = grid[order], chi2[order]
    return ProfileEstimate(name, value, sigma, grid, chi2, at_edge)
