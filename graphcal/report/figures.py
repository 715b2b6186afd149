"""Figures of a calibration run (matplotlib ``Figure`` objects, no global pyplot state).

Every figure says what it shows: numbers carry their meaning and unit, a figure that shows
part of the data says how much, and legends sit outside the plots, never over data.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from graphcal.evaluation import Evaluation
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.methods.validation import odometry_paths
from graphcal.report.figure_style import (
    COLOURS,
    EDGE_PAD,
    STEP_LABELS,
    TRUE_LINE,
    calibrated_line,
    draw_boxes,
    errors_by_theta,
    legend_below,
    number_of,
    step_captions,
    theta_names,
    vehicle_length_unit,
)
from graphcal.report.theta_figures import batch_intervals_figure, parameters_figure


def route_figure(run: CalibrationRun) -> Figure:
    """The measured route with the selected calibration segments highlighted."""
    fig = Figure(figsize=(7, 6.6), layout="constrained")
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
    ax.plot(log.px[0], log.py[0], "o", color="k", ms=5, label="start", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    fig.get_layout_engine().set(w_pad=EDGE_PAD)
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    s = run.settings.segments
    rule = f"{s.yaw_statistic} |yaw rate| > {s.min_yaw_rate:g} rad/s"
    passing = int(np.sum(run.yaw_rate > s.min_yaw_rate))
    if len(run.selected) == passing:
        title = (
            f"Route: {len(run.selected)} of {len(run.segments)} calibration segments "
            f"of {s.length:g} m selected\n(those with {rule})"
        )
    else:  # too few passed: the method fell back to all of them
        few = "none has" if passing == 0 else f"only {passing} have"
        title = (
            f"Route: all {len(run.segments)} calibration segments of {s.length:g} m used\n"
            f"({few} {rule})"
        )
    ax.set_title(title)
    legend_below(fig, [ax], ncols=3, fontsize="medium")
    return fig


def validation_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Validation errors E_p of the batches' theta per step (paper Fig. 6)."""
    unit = vehicle_length_unit(run)
    segment_errors = {k: e * unit.scale for k, e in errors_by_theta(run, evaluation).items()}
    mean_error = {name: float(np.mean(e)) for name, e in segment_errors.items()}
    fig = Figure(figsize=(7.5, 4.6), layout="constrained")
    ax = fig.add_subplot()
    called = theta_names(run)
    caption: list[str] = []
    if any(np.isfinite(e).any() for e in run.batch_errors.values()):  # E_p per batch, step
        data, labels = [], []
        for name, e in run.batch_errors.items():
            data.append(e[np.isfinite(e)] * unit.scale)
            if len(data[-1]) == len(e):
                counted = number_of(len(e), "batch", "batches")
            elif len(data[-1]):
                counted = f"{len(data[-1])} of {len(e)} batches"
            else:
                counted = f"none of {len(e)} shown"
            labels.append(f"{STEP_LABELS.get(name, name)}\n({counted})")
        caption = step_captions(run, run.batch_errors)
        ax.set_ylabel("θ of each batch, by step")
        ax.set_xlabel(f"validation error E_p [{unit.name}] (mean position error, eq. 16 / K)")
        points = "E_p of a batch's θ"
    else:  # no batches: the spread over the validation segments of each theta
        labels = [called[n] for n in segment_errors]
        data = list(segment_errors.values())
        ax.set_ylabel("θ of the odometry")
        ax.set_xlabel(
            f"mean position error of a validation segment [{unit.name}] (lines: E_p, their mean)"
        )
        points = "a segment's error"
    draw_boxes(ax, data, labels, vertical=False, label=points)
    values = np.concatenate([np.ravel(d) for d in data])
    shown = [float(v) for v in values[np.isfinite(values)]]
    top = max(shown, default=np.nan)
    names = {**called, "true": "reachable (true θ)"}
    # enough digits to tell the recommended from the reachable error apart
    close = abs(mean_error["calibrated"] - mean_error.get("true", np.inf)) < 0.01 * unit.scale
    digits = unit.figure_digits + (1 if close else 0)
    for name, style in (
        ("nominal", {"color": COLOURS["nominal"], "ls": ":", "lw": 1.5, "zorder": 2}),
        ("true", TRUE_LINE),
        ("calibrated", calibrated_line(run)),
    ):
        if name not in mean_error:
            continue
        label = f"{names[name]}: E_p {mean_error[name]:.{digits}f} {unit.name}"
        if name == "nominal" and mean_error[name] > 1.5 * top:
            ax.plot([], [], **style, label=label + " (off scale)")
            continue
        ax.axvline(mean_error[name], **style, label=label)
        if np.isfinite(mean_error[name]):
            shown.append(mean_error[name])
    if shown:  # everything drawn, with a margin (a box of one value is not at the edge)
        low, high = min(shown), max(shown)
        pad = 0.05 * (high - low) if high > low else 0.05 * max(abs(high), 1.0)
        ax.set_xlim(low - pad, high + pad)
    ax.set_title(
        f"Validation on {number_of(len(run.validation), 'segment', 'segments')} of "
        f"{run.settings.segments.validation_length:g} m"
    )
    ax.grid(axis="x", alpha=0.3)
    legend_below(fig, [ax], ncols=2, caption=caption)
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
    fig = Figure(figsize=(11, 5.0), layout="constrained")
    left_fig, right_fig = fig.subfigures(1, 2)
    left, right = left_fig.add_subplot(), right_fig.add_subplot()
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
    estimated = number_of(len(estimates), "Step 4 estimate", "Step 4 estimates")
    left.plot([], [], color="0.4", lw=0.5, label=f"thin, same colours: {estimated}")
    right.plot(t, measured[:, 1] - measured[:, 0], ".", ms=1.5, color="0.5", label="measured")
    right.plot(t, compensated[:, 1] - compensated[:, 0], color="k", lw=1.2, label="compensated")
    right.plot([], [], color="tab:blue", lw=0.5, label=estimated)
    left.set_title("Correction of each rear wheel")
    left.set_ylabel("wheel-rotation correction [10⁻³ rev per sample]")
    right.set_title("Right minus left wheel rotation (turning)")
    right.set_ylabel("n_rr − n_rl [rev per sample]")
    for sub, ax in ((left_fig, left), (right_fig, right)):
        ax.set_xlabel("time in segment [s]")
        ax.grid(alpha=0.3)
        legend_below(sub, [ax], ncols=1)  # two columns overflow a half-width panel
    start = run.log.t[run.selected.start[s]] - run.log.t[0]
    fig.suptitle(
        f"Wheel rotations of selected calibration segment {s} "
        f"(from {start:.0f} s into the log, {t[-1]:.1f} s long)"
    )
    return fig


def trajectory_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """The validation segment with the median nominal error: measured vs odometry paths."""
    segment_errors = errors_by_theta(run, evaluation)
    unit = vehicle_length_unit(run)
    errors = segment_errors["nominal"]
    i = int(np.argsort(errors)[len(errors) // 2])
    poses, _ = run.validation.segment(i)
    one = run.validation.take(np.array([i]))
    fixes = one.position_fixes()[0]
    thetas = {"nominal": run.settings.vehicle.theta_nominal, "calibrated": run.theta}
    if evaluation is not None:
        thetas["true"] = evaluation.theta_true
    fig = Figure(figsize=(7, 7), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(*poses[fixes, :2].T, ".", ms=1.5 if fixes.mean() > 0.5 else 4, color="0.5",
            label="measured positions")  # fmt: skip
    for name, theta in thetas.items():
        path = odometry_paths(one, theta)[0]
        error = segment_errors[name][i]
        ax.plot(
            path[:, 0],
            path[:, 1],
            color=COLOURS[name],
            ls="--" if name == "true" else "-",
            label=f"odometry, {theta_names(run)[name]}: mean position error "
            f"{unit.format(error, figure=True)} {unit.name}",
        )
    start = odometry_paths(one, run.theta)[0, 0]
    ax.plot(start[0], start[1], "o", color="k", ms=5, label="start", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    fig.get_layout_engine().set(w_pad=EDGE_PAD)
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    ax.set_title(
        f"Validation segment {i} ({run.settings.segments.validation_length:g} m): "
        f"the median of {len(errors)} by nominal-θ error\n"
        + (
            "odometry integrated from the measured start pose"
            if one.start_measured().all()
            else "odometry placed where it fits the fixes best (no fix at the start sample)"
        )
    )
    legend_below(fig, [ax], ncols=1)
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
