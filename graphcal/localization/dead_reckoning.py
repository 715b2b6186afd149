"""Dead reckoning through GNSS outages: what calibration is for.

Before an outage the localization fuses GNSS and wheel odometry; during it only the wheels
remain. :func:`outage_errors` reproduces that on a drive with known truth, for several
thetas: at many places it (1) estimates the pose at the outage's start with a short
fixed-lag smoothing window of GNSS positions and wheel odometry under that theta, then (2)
integrates eq. (1) with the measured wheel signals through the outage, and reports the final
and mean position error against the truth.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
import pandas as pd

from graphcal.errors import GraphcalError
from graphcal.factors.measured_pose import MeasuredPoseFactor
from graphcal.graph.construction.keyframes import fix_offsets, gnss_keyframes
from graphcal.graph.construction.keys import keyframe
from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.localization.keyframe_odometry import keyframe_odometry_factors
from graphcal.localization.values import insert_states, states_from_values
from graphcal.log.drive_log import DriveLog
from graphcal.model import integrate
from graphcal.progress import Progress, reports_progress, say


@dataclass(frozen=True)
class OutageSettings:
    """Settings of :func:`outage_errors` (SI).

    Attributes:
        durations_s: outage lengths [s].
        spacing_s: time between outage starts [s].
        window_s: GNSS + odometry smoothing window before each outage [s].
        gnss_rate_hz, gnss_sigma: GNSS rate [Hz] and position sigma [m] in that window.
    """

    durations_s: Sequence[float] = (30.0, 60.0, 120.0)
    spacing_s: float = 45.0
    window_s: float = 20.0
    gnss_rate_hz: float = 5.0
    gnss_sigma: float = 0.2


def pose_before_outage(
    log: DriveLog, start: int, theta: np.ndarray, settings: OutageSettings
) -> np.ndarray:
    """State ``[px, py, psi]`` at sample ``start`` from the smoothing window that ends there
    (GNSS positions and wheel odometry with ``theta`` fixed)."""
    first = max(0, start - round(settings.window_s / log.dt))
    if log.measured is None:
        stride = gnss_keyframes(log, settings.gnss_rate_hz)[1]
        keyframes = np.arange(start, first - 1, -stride)[::-1]
    else:  # the fixes in the window, and the outage's start
        fixes = gnss_keyframes(log, settings.gnss_rate_hz)
        keyframes = np.unique(np.append(fixes[(fixes >= first) & (fixes <= start)], start))
    if len(keyframes) < 2:
        raise GraphcalError(f"outage at sample {start}: no GNSS window before it")
    keys = [keyframe(i) for i in range(len(keyframes))]
    graph = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Isotropic.Sigma(2, settings.gnss_sigma)
    offsets = fix_offsets(log, keyframes, float(theta[0]))
    for key, k, offset in zip(keys, keyframes, offsets, strict=True):
        if not log.position_measured[k]:
            continue
        if offset == 0.0:
            graph.add(gtsam.PoseTranslationPrior2D(key, gtsam.Point2(log.px[k], log.py[k]), noise))
        else:  # a fix taken before the row's time
            sigmas = np.full(3, settings.gnss_sigma)
            graph.add(
                MeasuredPoseFactor(
                    key, log.pose(k), sigmas, with_heading=False, offset=np.array([offset, 0.0])
                ).factor()
            )
    for factor in keyframe_odometry_factors(log, keyframes, keys, None, theta=theta):
        graph.add(factor)
    values = gtsam.Values()
    insert_states(values, keys, log.poses[keyframes])
    options = SolveOptions(20, 1e-8, "outage start pose")
    result, _ = solve_lm(graph, values, options, driver="python")
    return states_from_values(result, keys, float(log.psi[keyframes[0]]))[-1]


@reports_progress
def outage_errors(
    log: DriveLog,
    truth: DriveLog,
    thetas: dict[str, np.ndarray],
    settings: OutageSettings | None = None,
    progress: Progress | None = None,
) -> pd.DataFrame:
    """Position errors of dead reckoning through simulated GNSS outages.

    Args:
        log: the measured drive (GNSS/IMU pose and wheel signals).
        truth: its noise-free poses (a synthetic drive's truth).
        thetas: named parameter sets to compare, e.g. nominal, calibrated and true (SI).
        settings: outage lengths and placement.
        progress: called with one line per theta.

    Returns:
        One row per theta, outage length and start: ``theta``, ``duration_s``,
        ``start_t_s``, ``final_error_m``, ``mean_error_m``.
    """
    settings = settings or OutageSettings()
    if len(truth) != len(log):
        raise GraphcalError(f"truth has {len(truth)} samples, the log {len(log)}")
    longest = round(max(settings.durations_s) / log.dt)
    window = round(settings.window_s / log.dt)
    starts = np.arange(window, len(log) - longest - 1, round(settings.spacing_s / log.dt))
    if len(starts) == 0:
        raise GraphcalError(
            f"the log ({log.t[-1] - log.t[0]:.0f} s) is too short for a {settings.window_s:g} s "
            f"window and a {max(settings.durations_s):g} s outage"
        )
    steps = starts[:, None] + np.arange(longest)[None, :]  # (S, K) sample indices
    inputs = log.inputs[steps]
    true_positions = truth.poses[np.concatenate([steps, steps[:, -1:] + 1], axis=1), :2]
    rows = []
    for name, theta in thetas.items():
        theta = np.asarray(theta, float)
        start_states = np.array([pose_before_outage(log, int(s), theta, settings) for s in starts])
        path = integrate(start_states, inputs, theta)[..., :2]  # (S, K+1, 2)
        error = np.linalg.norm(path - true_positions, axis=-1)
        for duration in settings.durations_s:
            k = round(duration / log.dt)
            for i, s in enumerate(starts):
                rows.append(
                    {
                        "theta": name,
                        "duration_s": float(duration),
                        "start_t_s": float(log.t[s]),
                        "final_error_m": float(error[i, k]),
                        "mean_error_m": float(error[i, : k + 1].mean()),
                    }
                )
        say(f"outages: {name} theta done ({len(starts)} starts)")
    return pd.DataFrame(rows)


def outage_table(errors: pd.DataFrame) -> pd.DataFrame:
    """Median final and mean position error [m] per outage length and theta."""
    return (
        errors.groupby(["duration_s", "theta"], sort=False)[["final_error_m", "mean_error_m"]]
        .median()
        .unstack("theta")
    )
