"""Shared styling and wording of the figures of a calibration run: colours and line
styles, what theta and the steps are called, captions saying what is not shown and why, and
the legend below the plots.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterable, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure

from graphcal.evaluation import Evaluation
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.units import LengthUnit, length_unit

COLOURS = {"nominal": "tab:red", "calibrated": "tab:blue", "true": "tab:green"}
STEP_LABELS = {
    "step1": "Step 1",
    "step3": "Step 3",
    "step5": "Step 5",
    "joint": "joint",
    "whole": "whole log",
}
THETA_NAMES = {"nominal": "nominal θ", "calibrated": "recommended θ", "true": "true θ"}
#: The run's theta when a check of :mod:`graphcal.pipeline.end_to_end.trust` failed (exit status 3):
#: an estimate, never called recommended.
NOT_TRUSTED_THETA = "estimated θ (not trusted)"
#: What each step or method of a batch study is, for the captions of the figures showing it
#: (docs/method.md, graphcal/pipeline/methods/staged.py).
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
TRUE_LINE = {"color": COLOURS["true"], "lw": 5.0, "alpha": 0.35, "zorder": 1}
#: Side padding [in] of equal-aspect maps: room for a tick label centred on the axes' edge,
#: which the layout does not foresee when the aspect widens the limits.
EDGE_PAD = 0.25
RECOMMENDED_LINE = {"color": COLOURS["calibrated"], "lw": 1.2, "zorder": 3}
#: A parameter the data did not determine: the prior (nominal) value the run keeps.
PRIOR_LINE = {"color": COLOURS["nominal"], "ls": ":", "lw": 1.5, "zorder": 2}
PRIOR_KEPT = "prior value kept (not observable)"
#: The run's theta when it is not trusted: dashed, so it is not taken for a recommendation.
_NOT_TRUSTED_LINE = {**RECOMMENDED_LINE, "ls": "--"}
#: Characters per inch of figure width of a caption line in the "small" font.
_CAPTION_CHARS_PER_INCH = 13


def vehicle_length_unit(run: CalibrationRun) -> LengthUnit:
    """The unit of the run's position errors and lever arm: mm for a small robot, m for a
    car (:func:`~graphcal.units.length_unit` of the vehicle's nominal track)."""
    return length_unit(float(run.settings.vehicle.theta_nominal[2]))


def trusted(run: CalibrationRun) -> bool:
    """False if a check of :mod:`graphcal.pipeline.end_to_end.trust` failed: the run's theta
    is then an estimate, shown as not trusted, never as calibrated or recommended."""
    return run.trust is None or run.trust.trusted


def theta_names(run: CalibrationRun) -> dict[str, str]:
    """Names of nominal, calibrated and true theta; the calibrated one is "recommended θ"
    only if the run is trusted (else :data:`NOT_TRUSTED_THETA`)."""
    return {**THETA_NAMES, "calibrated": calibrated_name(run)}


def calibrated_name(run: CalibrationRun) -> str:
    """What the run's theta is called: "recommended θ" or :data:`NOT_TRUSTED_THETA`."""
    return THETA_NAMES["calibrated"] if trusted(run) else NOT_TRUSTED_THETA


def calibrated_line(run: CalibrationRun) -> dict:
    """Line style of the run's theta: solid if trusted, dashed if not."""
    return RECOMMENDED_LINE if trusted(run) else _NOT_TRUSTED_LINE


def left_out(run: CalibrationRun, step: str) -> str:
    """Why batches of ``step`` are not shown (failed solves, batches left out of the
    statistics and the reason), one line; empty if every batch is shown."""
    thetas = run.batch_theta[step]
    total = len(thetas)
    failed = ~np.all(np.isfinite(thetas), axis=1)
    reasons = run.batch_excluded.get(step, np.full(total, "", dtype=object))
    parts = [f"{number_of(int(failed.sum()), 'solve', 'solves')} failed"] if failed.any() else []
    kept = ~failed
    for reason in sorted(set(reasons[kept]) - {""}):
        parts.append(f"{int(np.sum(kept & (reasons == reason)))} left out, {reason}")
    if not parts:
        return ""
    shown = total - int(failed.sum()) - int(np.sum(kept & (reasons != "")))
    label = STEP_LABELS.get(step, step)
    return f"{label}: {shown or 'none'} of {total} batches shown ({'; '.join(parts)})"


def step_captions(run: CalibrationRun | None, steps: Iterable[str]) -> list[str]:
    """Caption lines of a figure showing ``steps``: what each step is and, given the run,
    which of its batches are not shown and why."""
    steps = list(steps)
    lines = [STEP_NOTES[s] for s in steps if s in STEP_NOTES]
    if run is not None:
        lines += [line for s in steps if (line := left_out(run, s))]
    return lines


def number_of(n: int, singular: str, plural: str) -> str:
    """``"1 batch"``, ``"2 batches"``."""
    return f"{n} {singular if n == 1 else plural}"


def legend_below(
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


def errors_by_theta(run: CalibrationRun, evaluation: Evaluation | None) -> dict[str, np.ndarray]:
    """Per validation segment errors [m] of nominal, calibrated and (if known) true theta."""
    errors = dict(run.segment_errors)
    if evaluation is not None:
        errors["true"] = evaluation.validation_errors
    return errors


def draw_boxes(
    ax: Axes, data: list[np.ndarray], labels: list[str], vertical: bool, label: str
) -> None:
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
