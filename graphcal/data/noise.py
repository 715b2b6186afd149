"""Noise levels read from the log itself, so that the σ graphcal reports matches the error.

A fused heading's white noise varies by an order of magnitude between systems (the paper's
1.5°, a good INS's 0.1–0.3°); weighting it wrongly leaves the heading's slow bias and the
wheels' tick quantization to bias t_r and d (``docs/defects.md``). At 40 Hz the motion
changes the heading smoothly (a yaw acceleration of 0.5 rad/s² moves a second difference by
0.02°), so the second differences of the measured heading are its white noise:
``Δ²ψ_k = ε_k+1 − 2 ε_k + ε_k−1``, variance ``6 σ²``.
"""

from __future__ import annotations

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL

#: White noise has second differences of the same spread over one and over two steps; a
#: heading interpolated or held from a slower stream has much wider ones over two steps. Above
#: this ratio the log's heading noise is not estimated.
MAX_WIDE_RATIO = 1.5
#: Smallest heading noise [rad] reported (a heading smoother than this is weighted as this).
MIN_HEADING_SIGMA = np.deg2rad(0.01)


def heading_noise(
    log: DriveLog,
    nominal: np.ndarray | None = None,
    wheel_noise: float = 0.0,
    quantization: float = 0.0,
) -> float | None:
    """Robust sigma [rad] of the measured heading's white noise, from its second differences
    away from masked samples (``1.4826 · MAD / √6``), or ``None`` for a log too short or
    a heading interpolated or held from a slower stream (its noise is not white per sample;
    the configured heading weight stays). A log whose headings are not at every sample
    (sparse measurements) is measured on its own heading samples only
    (:func:`sparse_heading_noise`; ``nominal``: the vehicle's theta, ``wheel_noise`` [rev]
    per step and the tick ``quantization`` [rev] of the wheels)."""
    if log.sparse:
        if not log.heading_measured.any():
            return None
        nominal = THETA_NOMINAL if nominal is None else nominal
        return sparse_heading_noise(log, nominal, wheel_noise, quantization)
    return _uniform_heading_noise(log.psi, log.masked)


def _uniform_heading_noise(psi: np.ndarray, masked: np.ndarray | None) -> float | None:
    """:func:`heading_noise` of headings at consecutive samples."""
    second = np.diff(psi, 2)
    usable = np.ones(len(second), dtype=bool)
    if masked is not None:
        bad = np.asarray(masked)
        usable &= ~(bad[:-2] | bad[1:-1] | bad[2:])
    second = second[usable]
    if len(second) < 100:
        return None
    wide = psi[4:] - 2.0 * psi[2:-2] + psi[:-4]  # over two steps each side
    if _mad(wide) > MAX_WIDE_RATIO * _mad(second):
        return None  # interpolated or held from a slower stream: not white per sample
    return max(1.4826 * _mad(second) / np.sqrt(6.0), float(MIN_HEADING_SIGMA))


def _mad(values: np.ndarray) -> float:
    """Median absolute deviation."""
    return float(np.median(np.abs(values - np.median(values))))


def sparse_heading_noise(
    log: DriveLog, nominal: np.ndarray, wheel_noise: float = 0.0, quantization: float = 0.0
) -> float | None:
    """Heading noise [rad] of a log with heading samples at their own times, the smaller of
    two estimates (each can only overstate it):

    * on runs of headings at consecutive rows, the uniform estimator (the motion over one
      step is far below the noise);
    * over consecutive heading samples, the second differences of ``measured heading −
      wheel yaw`` (the wheels' yaw, nominal theta, at each sample's own time, removes the
      motion, which headings at 1–10 Hz would confuse with noise), less what the wheels add
      to them: the rounding of tick counts (``quantization`` [rev] on each cumulative
      count, 12 (c/t_r)² q² in a second difference) and white noise per step
      (``wheel_noise`` [rev], (m₁ + m₂) 2 (c/t_r)² σ² over m₁ + m₂ steps).

    ``None`` when neither has 100 usable samples."""
    rows = np.flatnonzero(log.heading_measured)
    estimates = []
    runs_of_three = rows[:-2][rows[2:] - rows[:-2] == 2]
    if len(runs_of_three) >= 100:  # rows r, r+1, r+2 all measure the heading
        psi = log.psi
        second = psi[runs_of_three] - 2.0 * psi[runs_of_three + 1] + psi[runs_of_three + 2]
        if log.masked is not None:
            bad = np.asarray(log.masked)
            second = second[~(bad[runs_of_three] | bad[runs_of_three + 1] | bad[runs_of_three + 2])]
        if len(second) >= 100:
            estimates.append(1.4826 * _mad(second) / np.sqrt(6.0))
    yaw_per_rev = nominal[0] / nominal[2]
    step_yaw = (log.n_rr[:-1] - log.n_rl[:-1]) * yaw_per_rev
    wheel_yaw = np.concatenate([[0.0], np.cumsum(step_yaw)])
    at_fix = wheel_yaw[rows]
    fraction = log.fix_fraction
    if fraction is not None:  # back to the sample's own time within the step before
        before = np.maximum(rows - 1, 0)
        at_fix = at_fix - (1.0 - fraction[rows]) * step_yaw[before]
    second = np.diff(log.psi[rows] - at_fix, 2)
    usable = np.ones(len(second), dtype=bool)
    if log.masked is not None:
        bad = np.asarray(log.masked)[rows]
        usable &= ~(bad[:-2] | bad[1:-1] | bad[2:])
    second = second[usable]
    if len(second) >= 100:
        steps = float(np.median(rows[2:] - rows[:-2]))
        from_wheels = yaw_per_rev**2 * (12.0 * quantization**2 + 2.0 * steps * wheel_noise**2)
        variance = max((1.4826 * _mad(second)) ** 2 - from_wheels, 0.0) / 6.0
        estimates.append(np.sqrt(variance))
    if not estimates:
        return None
    return max(min(estimates), float(MIN_HEADING_SIGMA))
