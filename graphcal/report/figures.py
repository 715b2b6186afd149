"""Figures of a calibration run (matplotlib ``Figure`` objects, no global pyplot state)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from graphcal.model import THETA_NOMINAL, integrate
from graphcal.pipeline.run import CalibrationRun

_COLOURS = {"nominal": "tab:red", "calibrated": "tab:blue", "true": "tab:green"}


def route_figure(run: CalibrationRun) -> Figure:
    """The measured route with the selected calibration segments highlighted."""
    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot()
    log = run.log
    ax.plot(log.px, log.py, color="0.75", lw=0.8, label="measured route")
    for i, (a, b) in enumerate(zip(run.selected.start, run.selected.stop, strict=True)):
        ax.plot(
            log.px[a : b + 1],
            log.py[a : b + 1],
            color="tab:orange",
            lw=1.6,
            label="selected calibration segments" if i == 0 else None,
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    ax.set_title(
        f"{len(run.selected)} of {len(run.segments)} segments selected "
        f"({run.settings.yaw_statistic} |yaw rate| > {run.settings.min_yaw_rate:g} rad/s)"
    )
    ax.legend(loc="best")
    return fig


def validation_figure(run: CalibrationRun) -> Figure:
    """Box plots of the validation errors (eq. 16 / K) per theta, the paper's Fig. 6 layout."""
    fig = Figure(figsize=(7, 3.8), layout="constrained")
    ax = fig.add_subplot()
    names = list(run.validation_errors)
    ax.boxplot(
        [run.validation_errors[n] for n in names], orientation="horizontal", tick_labels=names
    )
    ax.set_xlabel("mean position error on a validation segment [m]")
    ax.set_title(
        f"Validation on {len(run.validation)} segments of {run.settings.validation_length:g} m"
    )
    ax.grid(axis="x", alpha=0.3)
    return fig


def trajectory_figure(run: CalibrationRun) -> Figure:
    """The validation segment with the median nominal error: measured vs odometry paths."""
    errors = run.validation_errors["nominal"]
    i = int(np.argsort(errors)[len(errors) // 2])
    k = int(run.validation.n_steps[i])
    poses, inputs = run.validation.poses[i, : k + 1], run.validation.inputs[i, :k]
    thetas = {"nominal": THETA_NOMINAL, "calibrated": run.theta}
    if run.theta_true is not None:
        thetas["true"] = run.theta_true
    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(poses[:, 0], poses[:, 1], ".", ms=1.5, color="0.5", label="measured")
    for name, theta in thetas.items():
        path = integrate(poses[0], inputs, theta)
        ax.plot(
            path[:, 0],
            path[:, 1],
            color=_COLOURS[name],
            ls="--" if name == "true" else "-",
            label=f"odometry, {name} θ ({run.validation_errors[name][i]:.2f} m)",
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    ax.set_title(f"Validation segment {i}: odometry from the measured start pose")
    ax.legend(loc="best")
    return fig
