"""Figures of a calibration run (matplotlib ``Figure`` objects, no global pyplot state)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from graphcal.evaluation import Evaluation
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL, integrate
from graphcal.pipeline.run import CalibrationRun
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS

_COLOURS = {"nominal": "tab:red", "calibrated": "tab:blue", "true": "tab:green"}
_STEP_LABELS = {
    "step1": "Step 1",
    "step3": "Step 3",
    "step5": "Step 5",
    "joint": "joint",
    "whole": "whole log",
}


def _theta_true(evaluation: Evaluation | None) -> np.ndarray | None:
    return None if evaluation is None else evaluation.theta_true


def _segment_errors(run: CalibrationRun, evaluation: Evaluation | None) -> dict[str, np.ndarray]:
    """Per validation segment errors [m] of nominal, calibrated and (if known) true theta."""
    errors = dict(run.segment_errors)
    if evaluation is not None:
        errors["true"] = evaluation.validation_errors
    return errors


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
    s = run.settings.segments
    ax.set_title(
        f"{len(run.selected)} of {len(run.segments)} segments selected "
        f"({s.yaw_statistic} |yaw rate| > {s.min_yaw_rate:g} rad/s)"
    )
    ax.legend(loc="best")
    return fig


def box_plots(
    estimates: dict[str, np.ndarray],
    title: str,
    theta_true: np.ndarray | None = None,
    recommended: np.ndarray | None = None,
    not_observable: tuple[str, ...] = (),
) -> Figure:
    """Box plots of each parameter per step or method (paper Fig. 5).

    Args:
        estimates: per step or method (``"step1"``, ``"step5"``, ``"joint"``, ...), thetas
            ``(B, 4)`` in SI; NaN rows are left out.
        title: figure title.
        theta_true, recommended: drawn as horizontal lines when given.
        not_observable: parameters the data did not determine: no recommended line, and the
            panel says so.
    """
    fig = Figure(figsize=(11, 3.6), layout="constrained")
    names = list(estimates)
    for i, name in enumerate(PARAMETER_NAMES):
        ax = fig.add_subplot(1, 4, i + 1)
        data = []
        for step in names:
            t = estimates[step][:, i]
            data.append(t[np.isfinite(t)] * DISPLAY_SCALE[i])
        ax.boxplot(data, tick_labels=[_STEP_LABELS.get(s, s) for s in names])
        if theta_true is not None:
            ax.axhline(theta_true[i] * DISPLAY_SCALE[i], color="tab:green", ls="--", label="true")
        hidden = name in not_observable
        if recommended is not None and not hidden:
            ax.axhline(
                recommended[i] * DISPLAY_SCALE[i], color="tab:blue", lw=0.8, label="recommended"
            )
        ax.set_title(f"{name} [{DISPLAY_UNITS[i]}]" + (": not observable" if hidden else ""))
        ax.grid(axis="y", alpha=0.3)
        if i == 0:
            ax.legend(loc="best", fontsize="small")
    fig.suptitle(title)
    return fig


def parameters_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Box plots of each parameter over the batches of a run (paper Fig. 5)."""
    assert run.batches is not None
    estimates = {name: run.batch_estimates(name) for name in run.batch_theta}
    hidden = tuple(run.observability.not_calibrated) if run.observability is not None else ()
    title = f"Estimates over {len(run.batches)} batches"
    return box_plots(estimates, title, _theta_true(evaluation), run.theta, hidden)


def batch_intervals_figure(
    run: CalibrationRun,
    evaluation: Evaluation | None = None,
    *,
    name: str = "joint",
    limit: int = 60,
) -> Figure:
    """Per-batch estimates of ``name`` with ±2σ bars, next to the recommended theta's band.

    Shows the first ``limit`` batches; excluded batches are drawn hollow in grey.
    """
    thetas, covariances = run.batch_theta[name], run.batch_covariance[name]
    excluded = run.batch_excluded.get(name, np.full(len(thetas), "", dtype=object))
    shown = np.arange(min(limit, len(thetas)))
    fig = Figure(figsize=(11, 6), layout="constrained")
    for i, parameter in enumerate(PARAMETER_NAMES):
        ax = fig.add_subplot(2, 2, i + 1)
        scale = DISPLAY_SCALE[i]
        value = thetas[shown, i] * scale
        bar = 2.0 * np.sqrt(covariances[shown, i, i]) * scale
        for mask, style in ((excluded[shown] == "", "o"), (excluded[shown] != "", "x")):
            if mask.any():
                ax.errorbar(
                    shown[mask],
                    value[mask],
                    yerr=bar[mask],
                    fmt=style,
                    ms=3,
                    lw=0.8,
                    color="tab:blue" if style == "o" else "0.6",
                    label="batch ±2σ" if style == "o" else "excluded batch",
                )
        if run.covariance is not None and run.observability is not None:
            if run.observability.calibrated[i]:
                centre = run.theta[i] * scale
                half = 2.0 * np.sqrt(run.covariance[i, i]) * scale
                ax.axhspan(centre - half, centre + half, color="tab:blue", alpha=0.15)
                ax.axhline(centre, color="tab:blue", lw=0.8, label="recommended ±2σ")
            else:
                ax.set_title(f"{parameter} [{DISPLAY_UNITS[i]}]: not observable")
        if evaluation is not None:
            ax.axhline(evaluation.theta_true[i] * scale, color="tab:green", ls="--", label="true")
        if not ax.get_title():
            ax.set_title(f"{parameter} [{DISPLAY_UNITS[i]}]")
        ax.set_xlabel("batch")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(loc="best", fontsize="small")
    fig.suptitle(f"{_STEP_LABELS.get(name, name)} estimates per batch with ±2σ (95 %) bars")
    return fig


def validation_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Validation errors E_p of the batches' theta per step (paper Fig. 6)."""
    segment_errors = _segment_errors(run, evaluation)
    mean_error = {name: float(np.mean(e)) for name, e in segment_errors.items()}
    fig = Figure(figsize=(7, 3.8), layout="constrained")
    ax = fig.add_subplot()
    if any(np.isfinite(e).any() for e in run.batch_errors.values()):  # E_p per batch, step
        labels = [_STEP_LABELS.get(n, n) for n in run.batch_errors]
        data = [e[np.isfinite(e)] for e in run.batch_errors.values()]
    else:  # no batches: the spread over the validation segments of each theta
        labels = [f"{n} θ, per segment" for n in segment_errors]
        data = list(segment_errors.values())
    ax.boxplot(data, orientation="horizontal", tick_labels=labels)
    top = max(float(np.max(d)) for d in data if len(d))
    for name, style in (("nominal", ":"), ("true", "--"), ("calibrated", "-")):
        if name == "nominal" and mean_error[name] > 1.5 * top:
            ax.plot(
                [],
                [],
                color=_COLOURS[name],
                ls=style,
                label=f"nominal: {mean_error[name]:.2f} m (off scale)",
            )
            continue
        if name in mean_error:
            label = {"true": "reachable (true θ)", "calibrated": "recommended θ"}.get(name, name)
            ax.axvline(
                mean_error[name],
                color=_COLOURS[name],
                ls=style,
                label=f"{label}: {mean_error[name]:.2f} m",
            )
    ax.set_xlabel("validation error E_p [m] (mean position error, eq. 16 / K)")
    ax.set_title(
        f"Validation on {len(run.validation)} segments of "
        f"{run.settings.segments.validation_length:g} m"
    )
    ax.grid(axis="x", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig


def wheel_rotations_figure(run: CalibrationRun) -> Figure:
    """Measured vs estimated wheel rotations of one segment and their difference (Fig. 4)."""
    assert run.staged is not None
    s = run.staged.example_segment
    measured = run.data.segment(s)[1][:, :2]
    k = len(measured)
    t = np.arange(k) * run.log.dt
    compensated = run.staged.compensated_rotations[s, :k]
    estimates = run.staged.step4_estimates
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for e in estimates:
        left.plot(t, (e - measured)[:, 0] * 1e3, color="tab:blue", lw=0.5, alpha=0.4)
        left.plot(t, (e - measured)[:, 1] * 1e3, color="tab:orange", lw=0.5, alpha=0.4)
        right.plot(t, e[:, 1] - e[:, 0], color="tab:blue", lw=0.5, alpha=0.4)
    left.plot(
        t,
        (compensated - measured)[:, 0] * 1e3,
        color="tab:blue",
        lw=1.4,
        label="compensated − measured, rear left",
    )
    left.plot(
        t,
        (compensated - measured)[:, 1] * 1e3,
        color="tab:orange",
        lw=1.4,
        label="compensated − measured, rear right",
    )
    left.plot([], [], color="0.4", lw=0.5, label=f"thin: the {len(estimates)} Step 4 estimates")
    right.plot(t, measured[:, 1] - measured[:, 0], ".", ms=1.5, color="0.5", label="measured")
    right.plot(t, compensated[:, 1] - compensated[:, 0], color="k", lw=1.2, label="compensated")
    right.plot([], [], color="tab:blue", lw=0.5, label="Step 4 estimates")
    left.set_ylabel("wheel-rotation correction [10⁻³ rev per sample]")
    right.set_ylabel("n_rr − n_rl [rev]")
    for ax in (left, right):
        ax.set_xlabel("time in segment [s]")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    fig.suptitle(f"Wheel rotations of selected segment {s}")
    return fig


def trajectory_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """The validation segment with the median nominal error: measured vs odometry paths."""
    segment_errors = _segment_errors(run, evaluation)
    errors = segment_errors["nominal"]
    i = int(np.argsort(errors)[len(errors) // 2])
    poses, inputs = run.validation.segment(i)
    thetas = {"nominal": THETA_NOMINAL, "calibrated": run.theta}
    if evaluation is not None:
        thetas["true"] = evaluation.theta_true
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
            label=f"odometry, {name} θ ({segment_errors[name][i]:.2f} m)",
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    ax.set_title(f"Validation segment {i}: odometry from the measured start pose")
    ax.legend(loc="best")
    return fig


def figures(run: CalibrationRun, evaluation: Evaluation | None = None) -> dict[str, Figure]:
    """All figures of a run, by file name (with the truth drawn in, given an evaluation)."""
    out = {
        "route.png": route_figure(run),
        "validation.png": validation_figure(run, evaluation),
        "trajectory.png": trajectory_figure(run, evaluation),
    }
    if run.batches is not None:
        out["parameters.png"] = parameters_figure(run, evaluation)
    if "joint" in run.batch_covariance:
        out["batch_intervals.png"] = batch_intervals_figure(run, evaluation)
    if run.staged is not None:
        out["wheel_rotations.png"] = wheel_rotations_figure(run)
    return out
