"""Figures of the batches' theta: box plots of each parameter per step (paper Fig. 5) and
every batch's estimate with its ±2σ interval next to the run's theta.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from graphcal.evaluation import Evaluation
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.report.figure_style import (
    NOT_TRUSTED_THETA,
    PRIOR_KEPT,
    PRIOR_LINE,
    RECOMMENDED_LINE,
    STEP_LABELS,
    THETA_NAMES,
    TRUE_LINE,
    calibrated_line,
    calibrated_name,
    draw_boxes,
    left_out,
    legend_below,
    number_of,
    step_captions,
    trusted,
)
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS


def _shown(label: str, shown: int, total: int) -> str:
    """A step's tick label, with a second line saying how many of its batches it shows when
    not all: ``(7 of 10)``, or ``(none shown)`` instead of ``(0 of 10)``."""
    if shown == total:
        return label
    return f"{label}\n({shown} of {total})" if shown else f"{label}\n(none shown)"


def _theta_true(evaluation: Evaluation | None) -> np.ndarray | None:
    return None if evaluation is None else evaluation.theta_true


@dataclass(frozen=True)
class Recommended:
    """The theta a figure recommends: its value ``(4,)`` (SI), legend entry and line style
    (default :data:`RECOMMENDED_LINE`; :data:`NOT_TRUSTED_THETA`, dashed, for a run that is
    not trusted)."""

    theta: np.ndarray
    label: str = THETA_NAMES["calibrated"]
    style: dict | None = None


def box_plots(
    estimates: dict[str, np.ndarray],
    title: str,
    theta_true: np.ndarray | None = None,
    recommended: Recommended | None = None,
    not_observable: tuple[str, ...] = (),
    *,
    notes: Sequence[str] = (),
    held: tuple[str, ...] = (),
) -> Figure:
    """Box plots of each parameter per step or method (paper Fig. 5).

    Args:
        estimates: per step or method (``"step1"``, ``"step5"``, ``"joint"``, ...), thetas
            ``(B, 4)`` in SI; NaN rows are left out (a tick label says how many are left).
        title: figure title.
        theta_true, recommended: drawn as horizontal lines when given (``recommended``:
            :class:`Recommended`, its value, legend entry and style).
        not_observable: parameters the data did not determine: ``recommended``'s value is
            drawn as the prior value kept (:data:`PRIOR_KEPT`), not as an estimate, and the
            panel's title says so.
        held: parameters the vehicle profile holds at their nominal (``fix_d``): the panel
            says so.
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
            labels.append(_shown(STEP_LABELS.get(step, step), len(data[-1]), len(t)))
        draw_boxes(ax, data, labels, vertical=True, label="one batch's estimate")
        if theta_true is not None:
            ax.axhline(theta_true[i] * DISPLAY_SCALE[i], **TRUE_LINE, label="true θ")
        hidden = name in not_observable
        if recommended is not None and hidden:  # the prior value the run keeps, not an estimate
            value = recommended.theta[i] * DISPLAY_SCALE[i]
            ax.axhline(value, **PRIOR_LINE, label=PRIOR_KEPT)
        elif recommended is not None:
            style = recommended.style or RECOMMENDED_LINE
            value = recommended.theta[i] * DISPLAY_SCALE[i]
            ax.axhline(value, **style, label=recommended.label)
        # What the panel lacks, in its title (over no line or box): beside the name it
        # overflows the panel
        if hidden:
            status = "\nnot observable"
        elif name in held:
            status = "\nheld at nominal"
        elif not any(len(d) for d in data):
            status = "\nno batch estimate (see below)"
        else:
            status = ""
        ax.set_title(f"{name} [{DISPLAY_UNITS[i]}]" + status)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title)
    legend_below(fig, axes, ncols=4, caption=[*step_captions(None, names), *notes])
    return fig


def parameters_figure(run: CalibrationRun, evaluation: Evaluation | None = None) -> Figure:
    """Box plots of each parameter over the batches of a run (paper Fig. 5).

    Where the run held parameters it found not observable at their prior, its joint batches
    (solved holding them too) show their estimates of the calibrated ones, though they are
    left out of the batch statistics; the caption says so."""
    assert run.batches is not None
    hidden = tuple(run.observability.not_calibrated) if run.observability is not None else ()
    estimates, notes = {}, []
    for name in run.batch_theta:
        estimates[name], note = _shown_estimates(run, name, hidden)
        if note:
            notes.append(note)
    title = (
        f"Estimates of θ over {number_of(len(run.batches), 'batch', 'batches')}, by step "
        "(box: quartiles, whiskers: data within 1.5 IQR)"
    )
    return box_plots(
        estimates,
        title,
        _theta_true(evaluation),
        Recommended(run.theta, calibrated_name(run), calibrated_line(run)),
        hidden,
        notes=notes,
        held=tuple(
            name
            for name, fixed in zip(PARAMETER_NAMES, run.observability.held, strict=True)
            if fixed
        )
        if run.observability is not None
        else (),
    )


#: Up to this many batches the ±2σ bars are drawn at full width; beyond, thinner and paler
#: in proportion, so that 100 or 1000 of them still show each batch's interval.
FULL_BARS = 60


def _shown_estimates(
    run: CalibrationRun, step: str, hidden: tuple[str, ...]
) -> tuple[np.ndarray, str]:
    """The thetas ``(B, 4)`` of ``step`` that :func:`parameters_figure` shows (NaN: not
    shown) and the caption line saying what is not shown and why.

    A batch left out only because the parameters ``hidden`` (the run's not observable ones)
    were not observable keeps its estimates of the others, when its solve held ``hidden`` at
    the prior as the run's did (a step with covariances: the joint batches); every other
    batch left out or failed is not shown (:func:`left_out`)."""
    thetas = run.batch_estimates(step)
    reasons = run.batch_excluded.get(step)
    if not hidden or reasons is None or step not in run.batch_covariance:
        return thetas, left_out(run, step)
    partial = np.array(
        [_only_not_observable(str(r), hidden) for r in reasons], dtype=bool
    ) & np.all(np.isfinite(run.batch_theta[step]), axis=1)
    if not partial.any():
        return thetas, left_out(run, step)
    shown = np.array(thetas)
    kept = [i for i, p in enumerate(PARAMETER_NAMES) if p not in hidden]
    shown[np.ix_(partial, kept)] = run.batch_theta[step][np.ix_(partial, kept)]
    label = STEP_LABELS.get(step, step)
    names = ", ".join(PARAMETER_NAMES[i] for i in kept)
    line = (
        f"{label}: {names} of {number_of(int(partial.sum()), 'batch', 'batches')} solved with "
        f"{', '.join(hidden)} held at the prior (not observable), shown though left out of the "
        "batch statistics"
    )
    rest = len(partial) - int(partial.sum())
    if rest:
        line += f"; {rest} other {'batch' if rest == 1 else 'batches'} failed or left out"
    return shown, line


def _only_not_observable(reason: str, hidden: tuple[str, ...]) -> bool:
    """A batch's exclusion ``reason`` names only parameters in ``hidden`` as not observable."""
    prefix = "not observable: "
    if not reason.startswith(prefix):
        return False
    return set(reason[len(prefix) :].split(", ")) <= set(hidden)


def batch_intervals_figure(
    run: CalibrationRun,
    evaluation: Evaluation | None = None,
    *,
    name: str = "joint",
) -> Figure:
    """Every batch's estimate of ``name`` with its ±2σ bar, next to the run's theta and its
    ±2σ band (no band for a theta that is not trusted: the report gives it no interval).

    Beyond :data:`FULL_BARS` batches the bars are thinner, and the title says so. Excluded
    batches are grey crosses; failed solves (no estimate) are counted in the title.
    """
    thetas, covariances = run.batch_theta[name], run.batch_covariance[name]
    count = len(thetas)
    excluded = run.batch_excluded.get(name, np.full(count, "", dtype=object))
    finite = np.all(np.isfinite(thetas), axis=1)
    kinds = (
        (finite & (excluded == ""), "o", "tab:blue", "batch estimate ±2σ"),
        (finite & (excluded != ""), "x", "0.55", "excluded batch ±2σ"),
    )
    fig = Figure(figsize=(11, 6.6), layout="constrained")
    axes = []
    for i in range(len(PARAMETER_NAMES)):
        ax = fig.add_subplot(2, 2, i + 1)
        axes.append(ax)
        _batch_estimates(ax, thetas[:, i], covariances[:, i, i], i, kinds)
        title = f"{PARAMETER_NAMES[i]} [{DISPLAY_UNITS[i]}]" + _run_interval(ax, run, i)
        if evaluation is not None:
            ax.axhline(evaluation.theta_true[i] * DISPLAY_SCALE[i], **TRUE_LINE, label="true θ")
        ax.set_title(title)
        _batch_axis(ax, count)
    fig.suptitle(_batch_intervals_title(name, count, int(np.sum(~finite))))
    caption = []
    if not trusted(run) and run.covariance is not None:
        caption.append(
            f"{NOT_TRUSTED_THETA}: a trust check failed, so it has no ±2σ band (the summary "
            "gives it no interval either)"
        )
    legend_below(fig, axes, ncols=5, caption=caption)
    return fig


def _bar_style(count: int) -> dict:
    """Width and size of ``count`` batches' markers and ±2σ bars: full up to
    :data:`FULL_BARS`, thinner and paler beyond (each bar still drawn)."""
    if count <= FULL_BARS:
        return {"ms": 3.0, "lw": 0.8, "alpha": 1.0}
    share = float(np.sqrt(FULL_BARS / count))
    return {"ms": max(1.2, 3.0 * share), "lw": max(0.2, 0.8 * share), "alpha": 0.6}


def _batch_estimates(
    ax: Axes,
    theta: np.ndarray,
    variance: np.ndarray,
    i: int,
    kinds: tuple[tuple[np.ndarray, str, str, str], ...],
) -> None:
    """Parameter ``i`` of each batch ``(B,)`` (SI; its variances ``(B,)``) in display
    units with its ±2σ bar, per kind (mask, marker, colour, label)."""
    scale = DISPLAY_SCALE[i]
    batch = np.arange(len(theta))
    value = theta * scale
    style = _bar_style(len(theta))
    for mask, marker, colour, label in kinds:
        if not mask.any():
            continue
        bar = 2.0 * np.sqrt(np.maximum(variance[mask], 0.0)) * scale
        ax.errorbar(
            batch[mask],
            value[mask],
            yerr=np.where(np.isfinite(bar), bar, 0.0),
            fmt=marker,
            color=colour,
            label=label,
            **style,
        )


def _run_interval(ax: Axes, run: CalibrationRun, i: int) -> str:
    """The run's parameter ``i`` and its ±2σ band, if the run has a covariance; returns what
    the panel's title gains (``": not observable"`` for a parameter the data did not
    determine)."""
    if run.covariance is None or run.observability is None:
        return ""
    if not run.observability.calibrated[i]:
        return ": not observable"
    theta_name = calibrated_name(run)
    scale = DISPLAY_SCALE[i]
    centre = run.theta[i] * scale
    ax.axhline(centre, **calibrated_line(run), label=theta_name)
    if not trusted(run):  # the summary gives it no interval: neither does the figure
        return ": not trusted"
    half = 2.0 * np.sqrt(run.covariance[i, i]) * scale
    ax.axhspan(
        centre - half,
        centre + half,
        color="tab:blue",
        alpha=0.15,
        lw=0,
        label=f"{theta_name} ±2σ",
    )
    return ""


def _batch_axis(ax: Axes, count: int) -> None:
    """The batch numbers along x, whole numbers only; grid, no offset on y."""
    ax.set_xlabel("batch number")
    ax.set_xlim(-0.5, max(count, 1) - 0.5)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.grid(alpha=0.3)


def _batch_intervals_title(name: str, count: int, failed: int) -> str:
    """The figure's title: which step, how many batches shown (failed ones counted), their
    ±2σ bars (thinner beyond :data:`FULL_BARS` batches)."""
    if failed:
        shown = f"{count - failed} of {count} batches ({failed} failed, no estimate)"
    else:
        shown = f"all {count} batches" if count > 1 else "the only batch"
    thin = " (thin lines: many batches)" if count > FULL_BARS else ""
    step = STEP_LABELS.get(name, name).capitalize()
    return f"{step} estimates of {shown} with ±2σ (95 %) bars{thin}"
