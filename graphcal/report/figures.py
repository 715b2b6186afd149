"""Figures of a calibration run (matplotlib ``Figure`` objects, no global pyplot state).

Every figure says what it shows: numbers carry their meaning and unit, a figure that shows
part of the data says how much, and legends sit outside the plots, never over data.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterable, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure
from matplotlib.ticker import MaxNLocator

from graphcal.evaluation import Evaluation
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.calibration_run import CalibrationRun
from graphcal.pipeline.validation import odometry_paths
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS

_COLOURS = {"nominal": "tab:red", "calibrated": "tab:blue", "true": "tab:green"}
_STEP_LABELS = {
    "step1": "Step 1",
    "step3": "Step 3",
    "step5": "Step 5",
    "joint": "joint",
    "whole": "whole log",
}
_THETA_NAMES = {"nominal": "nominal θ", "calibrated": "recommended θ", "true": "true θ"}
#: The run's theta when a check of :mod:`graphcal.pipeline.trust` failed (exit status 3):
#: an estimate, never called recommended.
NOT_TRUSTED_THETA = "estimated θ (not trusted)"
#: What each step or method of a batch study is, for the captions of the figures showing it
#: (docs/method.md, graphcal/pipeline/staged.py).
STEP_NOTES = {
    "step1": "Step 1 = the paper's first step, the uncompensated baseline: θ of each batch "
    "from the measured wheel rotations and heading, every segment starting from its "
    "measured pose",
    "step3": "Step 3 = Step 1 with the heading corrected per segment (Step 2)",
    "step5": "Step 5 = Step 1 with the compensated wheel rotations (Step 4) and the corrected "
    "heading: the paper's final θ",
    "joint": "joint = wheel-rotation compensation and θ solved together in one graph per "
    "batch (graphcal's default method)",
    "whole": "whole log = one joint solve over all selected segments",
}
#: Up to this many values per box, the values themselves are drawn over the box plot.
_MAX_POINTS = 30
#: Reachable (true θ) lines: wide and pale beneath the thin recommended line, so both show
#: when they (nearly) coincide.
_TRUE_LINE = {"color": _COLOURS["true"], "lw": 5.0, "alpha": 0.35, "zorder": 1}
#: Side padding [in] of equal-aspect maps: room for a tick label centred on the axes' edge,
#: which the layout does not foresee when the aspect widens the limits.
_EDGE_PAD = 0.25
_RECOMMENDED_LINE = {"color": _COLOURS["calibrated"], "lw": 1.2, "zorder": 3}
#: The run's theta when it is not trusted: dashed, so it is not taken for a recommendation.
_NOT_TRUSTED_LINE = {**_RECOMMENDED_LINE, "ls": "--"}
#: Characters per inch of figure width of a caption line in the "small" font.
_CAPTION_CHARS_PER_INCH = 13


def trusted(run: CalibrationRun) -> bool:
    """False if a check of :mod:`graphcal.pipeline.trust` failed: the run's theta is then an
    estimate, shown as not trusted, never as calibrated or recommended."""
    return run.trust is None or run.trust.trusted


def _theta_names(run: CalibrationRun) -> dict[str, str]:
    """Names of nominal, calibrated and true theta; the calibrated one is "recommended θ"
    only if the run is trusted (else :data:`NOT_TRUSTED_THETA`)."""
    return {**_THETA_NAMES, "calibrated": _calibrated_name(run)}


def _calibrated_name(run: CalibrationRun) -> str:
    """What the run's theta is called: "recommended θ" or :data:`NOT_TRUSTED_THETA`."""
    return _THETA_NAMES["calibrated"] if trusted(run) else NOT_TRUSTED_THETA


def _calibrated_line(run: CalibrationRun) -> dict:
    """Line style of the run's theta: solid if trusted, dashed if not."""
    return _RECOMMENDED_LINE if trusted(run) else _NOT_TRUSTED_LINE


def _shown(label: str, shown: int, total: int) -> str:
    """A step's tick label, with a second line saying how many of its batches it shows when
    not all: ``(7 of 10)``, or ``(none shown)`` instead of ``(0 of 10)``."""
    if shown == total:
        return label
    return f"{label}\n({shown} of {total})" if shown else f"{label}\n(none shown)"


def _left_out(run: CalibrationRun, step: str) -> str:
    """Why batches of ``step`` are not shown (failed solves, batches left out of the
    statistics and the reason), one line; empty if every batch is shown."""
    thetas = run.batch_theta[step]
    total = len(thetas)
    failed = ~np.all(np.isfinite(thetas), axis=1)
    reasons = run.batch_excluded.get(step, np.full(total, "", dtype=object))
    parts = [f"{_count(int(failed.sum()), 'solve', 'solves')} failed"] if failed.any() else []
    kept = ~failed
    for reason in sorted(set(reasons[kept]) - {""}):
        parts.append(f"{int(np.sum(kept & (reasons == reason)))} left out, {reason}")
    if not parts:
        return ""
    shown = total - int(failed.sum()) - int(np.sum(kept & (reasons != "")))
    label = _STEP_LABELS.get(step, step)
    return f"{label}: {shown or 'none'} of {total} batches shown ({'; '.join(parts)})"


def _caption(run: CalibrationRun | None, steps: Iterable[str]) -> list[str]:
    """Caption lines of a figure showing ``steps``: what each step is and, given the run,
    which of its batches are not shown and why."""
    steps = list(steps)
    lines = [STEP_NOTES[s] for s in steps if s in STEP_NOTES]
    if run is not None:
        lines += [line for s in steps if (line := _left_out(run, s))]
    return lines


def _count(n: int, singular: str, plural: str) -> str:
    """``"1 batch"``, ``"2 batches"``."""
    return f"{n} {singular if n == 1 else plural}"


def _legend_below(
    fig: Figure | SubFigure,
    axes: Iterable[Axes],
    ncols: int,
    fontsize: str = "small",
    caption: Sequence[str] = (),
) -> None:
    """One legend of the entries of ``axes`` (first of each label) below the plots, headed
    by the ``caption`` lines (wrapped to the figure's width)."""
    entries: dict[str, object] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    width = int(_CAPTION_CHARS_PER_INCH * fig.figure.get_figwidth())
    title = "\n".join(textwrap.fill(line, width, subsequent_indent="    ") for line in caption)
    if entries or title:
        fig.legend(
            list(entries.values()),
            list(entries),
            loc="outside lower center",
            ncols=max(1, min(ncols, len(entries))),
            fontsize=fontsize,
            title=title or None,
            title_fontsize="small",
            alignment="left",
        )


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
    fig.get_layout_engine().set(w_pad=_EDGE_PAD)
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
    else:  # no segment passed: the method fell back to all of them
        title = (
            f"Route: all {len(run.segments)} calibration segments of {s.length:g} m used\n"
            f"(none has {rule})"
        )
    ax.set_title(title)
    _legend_below(fig, [ax], ncols=3, fontsize="medium")
    return fig


def _boxes(ax: Axes, data: list[np.ndarray], labels: list[str], vertical: bool, label: str) -> None:
    """Box plots of ``data``; with few values per box, the values themselves over the boxes
    (instead of outlier circles: a box of one value is just a line)."""
    few = all(len(d) <= _MAX_POINTS for d in data)
    ax.boxplot(
        data,
        orientation="vertical" if vertical else "horizontal",
        tick_labels=labels,
        showfliers=not few,
    )
    if not few:
        return
    drawn = False
    for position, v in enumerate(data, start=1):
        if len(v):
            at = np.full(len(v), float(position))
            x, y = (at, v) if vertical else (v, at)
            style = {"ms": 3.5, "mfc": "none", "color": "0.25", "zorder": 4}
            ax.plot(x, y, "o", **style, label=None if drawn else label)
            drawn = True


def box_plots(
    estimates: dict[str, np.ndarray],
    title: str,
    theta_true: np.ndarray | None = None,
    recommended: np.ndarray | None = None,
    not_observable: tuple[str, ...] = (),
    *,
    recommended_label: str = _THETA_NAMES["calibrated"],
    recommended_style: dict | None = None,
    notes: Sequence[str] = (),
    held: tuple[str, ...] = (),
) -> Figure:
    """Box plots of each parameter per step or method (paper Fig. 5).

    Args:
        estimates: per step or method (``"step1"``, ``"step5"``, ``"joint"``, ...), thetas
            ``(B, 4)`` in SI; NaN rows are left out (a tick label says how many are left).
        title: figure title.
        theta_true, recommended: drawn as horizontal lines when given.
        not_observable: parameters the data did not determine: no recommended line, and the
            panel says so.
        held: parameters the vehicle profile holds at their nominal (``fix_d``): the panel
            says so.
        recommended_label, recommended_style: legend entry and line style of
            ``recommended`` (e.g. :data:`NOT_TRUSTED_THETA`, dashed, for a run that is not
            trusted).
        notes: caption lines below the legend, after the explanation of each step shown
            (:data:`STEP_NOTES`), e.g. why batches are not shown.
    """
    fig = Figure(figsize=(11, 4.4), layout="constrained")
    names = list(estimates)
    axes = []
    for i, name in enumerate(PARAMETER_NAMES):
        ax = fig.add_subplot(1, 4, i + 1)
        axes.append(ax)
        data, labels = [], []
        for step in names:
            t = estimates[step][:, i]
            data.append(t[np.isfinite(t)] * DISPLAY_SCALE[i])
            labels.append(_shown(_STEP_LABELS.get(step, step), len(data[-1]), len(t)))
        _boxes(ax, data, labels, vertical=True, label="one batch's estimate")
        if not any(len(d) for d in data):
            # low in the panel: the lines of theta run through its middle
            ax.text(0.5, 0.12, "no batch estimate\nto show (see below)", transform=ax.transAxes,
                    ha="center", va="center", color="0.4")  # fmt: skip
        if theta_true is not None:
            ax.axhline(theta_true[i] * DISPLAY_SCALE[i], **_TRUE_LINE, label="true θ")
        hidden = name in not_observable
        if recommended is not None and not hidden:
            style = recommended_style or _RECOMMENDED_LINE
            ax.axhline(recommended[i] * DISPLAY_SCALE[i], **style, label=recommended_label)
        # "not observable" on a line of its own: beside the name it overflows the panel
        status = "\nnot observable" if hidden else "\nheld at nominal" if name in held else ""
        ax.set_title(f"{name} [{DISPLAY_UNITS[i]}]" + status)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title)
    _legend_below(fig, axes, ncols=4, caption=[*_caption(None, names), *notes])
    return fig


def parameters_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Box plots of each parameter over the batches of a run (paper Fig. 5)."""
    assert run.batches is not None
    estimates = {name: run.batch_estimates(name) for name in run.batch_theta}
    hidden = tuple(run.observability.not_calibrated) if run.observability is not None else ()
    title = (
        f"Estimates of θ over {_count(len(run.batches), 'batch', 'batches')}, by step "
        "(box: quartiles, whiskers: data within 1.5 IQR)"
    )
    return box_plots(
        estimates,
        title,
        _theta_true(evaluation),
        run.theta,
        hidden,
        recommended_label=_calibrated_name(run),
        recommended_style=_calibrated_line(run),
        notes=[line for step in estimates if (line := _left_out(run, step))],
        held=tuple(
            name
            for name, fixed in zip(PARAMETER_NAMES, run.observability.held, strict=True)
            if fixed
        )
        if run.observability is not None
        else (),
    )


def batch_intervals_figure(
    run: CalibrationRun,
    evaluation: Evaluation | None = None,
    *,
    name: str = "joint",
    limit: int = 60,
) -> Figure:
    """Every batch's estimate of ``name`` next to the run's theta and its ±2σ band (labelled
    not trusted when a trust check failed).

    Up to ``limit`` batches get ±2σ bars; more are drawn as points, and the title says so.
    Excluded batches are grey crosses; failed solves (no estimate) are counted in the title.
    """
    thetas, covariances = run.batch_theta[name], run.batch_covariance[name]
    count = len(thetas)
    excluded = run.batch_excluded.get(name, np.full(count, "", dtype=object))
    batch = np.arange(count)
    finite = np.all(np.isfinite(thetas), axis=1)
    bars = count <= limit
    kinds = (
        (finite & (excluded == ""), "o", "tab:blue", "batch ±2σ" if bars else "batch estimate"),
        (finite & (excluded != ""), "x", "0.55", "excluded batch"),
    )
    theta_name = _calibrated_name(run)
    fig = Figure(figsize=(11, 6.6), layout="constrained")
    axes = []
    for i, parameter in enumerate(PARAMETER_NAMES):
        ax = fig.add_subplot(2, 2, i + 1)
        axes.append(ax)
        scale = DISPLAY_SCALE[i]
        value = thetas[:, i] * scale
        for mask, marker, colour, label in kinds:
            if not mask.any():
                continue
            if bars:
                bar = 2.0 * np.sqrt(covariances[mask, i, i]) * scale
                ax.errorbar(
                    batch[mask],
                    value[mask],
                    yerr=bar,
                    fmt=marker,
                    ms=3,
                    lw=0.8,
                    color=colour,
                    label=label,
                )
            else:
                size = 2.0 if marker == "o" else 4.0
                ax.plot(
                    batch[mask], value[mask], marker, ms=size, alpha=0.7, color=colour, label=label
                )
        title = f"{parameter} [{DISPLAY_UNITS[i]}]"
        if run.covariance is not None and run.observability is not None:
            if run.observability.calibrated[i]:
                centre = run.theta[i] * scale
                half = 2.0 * np.sqrt(run.covariance[i, i]) * scale
                ax.axhspan(
                    centre - half,
                    centre + half,
                    color="tab:blue",
                    alpha=0.15,
                    lw=0,
                    label=f"{theta_name} ±2σ",
                )
                ax.axhline(centre, **_calibrated_line(run), label=theta_name)
            else:
                title += ": not observable"
        sigmas = np.sqrt(covariances[kinds[0][0], i, i]) * scale
        if not bars and np.isfinite(sigmas).any():  # the bars' size, in words
            title += f"; median batch 2σ: ±{2.0 * np.nanmedian(sigmas):#.2g}"
        if evaluation is not None:
            ax.axhline(evaluation.theta_true[i] * scale, **_TRUE_LINE, label="true θ")
        ax.set_title(title)
        ax.set_xlabel("batch number")
        ax.set_xlim(-0.5, max(count, 1) - 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(alpha=0.3)
    failed = int(np.sum(~finite))
    if failed:
        shown = f"{count - failed} of {count} batches ({failed} failed, no estimate)"
    else:
        shown = f"all {count} batches" if count > 1 else "the only batch"
    detail = " with ±2σ (95 %) bars" if bars else f"; ±2σ bars drawn only up to {limit} batches"
    fig.suptitle(f"{_STEP_LABELS.get(name, name).capitalize()} estimates of {shown}{detail}")
    _legend_below(fig, axes, ncols=5)
    return fig


def validation_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Validation errors E_p of the batches' theta per step (paper Fig. 6)."""
    segment_errors = _segment_errors(run, evaluation)
    mean_error = {name: float(np.mean(e)) for name, e in segment_errors.items()}
    fig = Figure(figsize=(7.5, 4.6), layout="constrained")
    ax = fig.add_subplot()
    theta_names = _theta_names(run)
    caption: list[str] = []
    if any(np.isfinite(e).any() for e in run.batch_errors.values()):  # E_p per batch, step
        data, labels = [], []
        for name, e in run.batch_errors.items():
            data.append(e[np.isfinite(e)])
            if len(data[-1]) == len(e):
                counted = _count(len(e), "batch", "batches")
            elif len(data[-1]):
                counted = f"{len(data[-1])} of {len(e)} batches"
            else:
                counted = f"none of {len(e)} shown"
            labels.append(f"{_STEP_LABELS.get(name, name)}\n({counted})")
        caption = _caption(run, run.batch_errors)
        ax.set_ylabel("θ of each batch, by step")
        ax.set_xlabel("validation error E_p [m] (mean position error, eq. 16 / K)")
        points = "E_p of a batch's θ"
    else:  # no batches: the spread over the validation segments of each theta
        labels = [theta_names[n] for n in segment_errors]
        data = list(segment_errors.values())
        ax.set_ylabel("θ of the odometry")
        ax.set_xlabel("mean position error of a validation segment [m] (lines: E_p, their mean)")
        points = "a segment's error"
    _boxes(ax, data, labels, vertical=False, label=points)
    values = np.concatenate([np.ravel(d) for d in data])
    shown = [float(v) for v in values[np.isfinite(values)]]
    top = max(shown, default=np.nan)
    names = {**theta_names, "true": "reachable (true θ)"}
    # enough digits to tell the recommended from the reachable error apart
    close = abs(mean_error["calibrated"] - mean_error.get("true", np.inf)) < 0.01
    digits = 3 if close else 2
    for name, style in (
        ("nominal", {"color": _COLOURS["nominal"], "ls": ":", "lw": 1.5, "zorder": 2}),
        ("true", _TRUE_LINE),
        ("calibrated", _calibrated_line(run)),
    ):
        if name not in mean_error:
            continue
        label = f"{names[name]}: E_p {mean_error[name]:.{digits}f} m"
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
        f"Validation on {_count(len(run.validation), 'segment', 'segments')} of "
        f"{run.settings.segments.validation_length:g} m"
    )
    ax.grid(axis="x", alpha=0.3)
    _legend_below(fig, [ax], ncols=2, caption=caption)
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
    estimated = _count(len(estimates), "Step 4 estimate", "Step 4 estimates")
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
        _legend_below(sub, [ax], ncols=1)  # two columns overflow a half-width panel
    start = run.log.t[run.selected.start[s]] - run.log.t[0]
    fig.suptitle(
        f"Wheel rotations of selected calibration segment {s} "
        f"(from {start:.0f} s into the log, {t[-1]:.1f} s long)"
    )
    return fig


def trajectory_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """The validation segment with the median nominal error: measured vs odometry paths."""
    segment_errors = _segment_errors(run, evaluation)
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
            color=_COLOURS[name],
            ls="--" if name == "true" else "-",
            label=f"odometry, {_theta_names(run)[name]}: mean position error {error:.2f} m",
        )
    start = odometry_paths(one, run.theta)[0, 0]
    ax.plot(start[0], start[1], "o", color="k", ms=5, label="start", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    fig.get_layout_engine().set(w_pad=_EDGE_PAD)
    ax.set_xlabel("px [m]")
    ax.set_ylabel("py [m]")
    ax.set_title(
        f"Validation segment {i} ({run.settings.segments.validation_length:g} m): "
        f"the median of {len(errors)} by nominal-θ error\n"
        + (
            "odometry integrated from the measured start pose"
            if one.start_measured().all()
            else "odometry placed where it fits the fixes best (no pose measured at the start)"
        )
    )
    _legend_below(fig, [ax], ncols=1)
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
