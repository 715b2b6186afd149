"""Statistics and plain-text tables of a run, theta in the paper's display units."""

from __future__ import annotations

import numpy as np

from graphcal.graph.solution.observability import HELD_VERDICT
from graphcal.model import PARAMETER_NAMES
from graphcal.units import (
    DEVIATION_SCALE,
    DISPLAY_SCALE,
    DISPLAY_UNITS,
    METRES,
    LengthUnit,
    to_display,
)

_FORMATS = ("{:.4f}", "{:.3f}", "{:.4f}", "{:.3f}")

#: The paper's reductions of the middle-50 % range from Step 1 to Step 5 (§5.5), in percent.
PAPER_IQR_REDUCTION = {"c_e": 78.0, "c_d": 87.0, "t_r": 80.0, "d": 84.0}


def step_statistics(thetas: np.ndarray, truth: np.ndarray | None = None) -> dict[str, dict]:
    """Per parameter: median, IQR and, given the truth, bias (median − truth) and RMSE (SI).

    ``thetas`` is ``(B, 4)``; rows with NaN (failed batches) are left out.
    """
    good = thetas[np.all(np.isfinite(thetas), axis=1)]
    if len(good) == 0:  # every batch of this step failed: nothing to summarize
        empty = {"median": None, "iqr": None} | (
            {"bias": None, "rmse": None} if truth is not None else {}
        )
        return {name: dict(empty) for name in PARAMETER_NAMES}
    q25, median, q75 = np.percentile(good, [25, 50, 75], axis=0)
    stats: dict[str, dict] = {}
    for i, name in enumerate(PARAMETER_NAMES):
        entry = {"median": float(median[i]), "iqr": float(q75[i] - q25[i])}
        if truth is not None:
            entry["bias"] = float(median[i] - truth[i])
            entry["rmse"] = float(np.sqrt(np.mean((good[:, i] - truth[i]) ** 2)))
        stats[name] = entry
    return stats


def iqr_reduction(first: dict[str, dict], last: dict[str, dict]) -> dict[str, float | None]:
    """Reduction of the IQR from ``first`` to ``last`` step, percent, per parameter.

    ``None`` where it is undefined (a step without results, or a zero first IQR, e.g. with
    a single batch).
    """
    out: dict[str, float | None] = {}
    for name in PARAMETER_NAMES:
        a, b = first[name]["iqr"], last[name]["iqr"]
        out[name] = 100.0 * (1.0 - b / a) if a and b is not None else None
    return out


NOT_OBSERVABLE = "n/o"


def theta_table(
    rows: dict[str, np.ndarray], not_observable: dict[str, set[str]] | None = None
) -> str:
    """A table with one row per named theta (SI in, display units out, units in the header).

    ``not_observable`` maps a row name to parameters shown as ``n/o`` instead of a number.
    """
    hidden = not_observable or {}
    header = ["", *(f"{n} [{u}]" for n, u in zip(PARAMETER_NAMES, DISPLAY_UNITS, strict=True))]
    body = [
        [
            name,
            *(
                NOT_OBSERVABLE if p in hidden.get(name, ()) else f.format(v)
                for p, f, v in zip(PARAMETER_NAMES, _FORMATS, to_display(theta), strict=True)
            ),
        ]
        for name, theta in rows.items()
    ]
    return _render([header, *body])


def steps_table(
    stats: dict[str, dict[str, dict]],
    has_truth: bool,
    steps: tuple[str, ...] = ("step1", "step5"),
    not_observable: set[str] | None = None,
) -> str:
    """Per parameter and step: median, IQR and, given the truth, bias and RMSE.

    Medians in display units (m, mm, m, mm·s²/m); IQR, bias and RMSE in mm (mm·s²/m for d).
    With Steps 1 and 5 the IQR reduction is shown next to the paper's. Parameters in
    ``not_observable`` show ``n/o`` instead of numbers; steps without a usable batch ``none``.
    """
    columns = ["median", "iqr"] + (["bias", "rmse"] if has_truth else [])
    header = ["parameter"]
    for step in steps:
        header += [f"{step} {c}" for c in columns]
    compare = steps == ("step1", "step5")
    if compare:
        reduction = iqr_reduction(stats["step1"], stats["step5"])
        header += ["IQR cut %", "paper %"]
    body = []
    for i, name in enumerate(PARAMETER_NAMES):
        spread = "mm·s²/m" if name == "d" else "mm"
        row = [f"{name} [{DISPLAY_UNITS[i]}; {spread}]"]
        for step in steps:
            entry = stats[step][name]
            if name in (not_observable or ()):
                row += [NOT_OBSERVABLE] + ["-"] * (len(columns) - 1)
                continue
            if entry["median"] is None:
                row += ["none"] + ["-"] * (len(columns) - 1)
                continue
            row.append(_FORMATS[i].format(entry["median"] * DISPLAY_SCALE[i]))
            row += [f"{entry[c] * DEVIATION_SCALE[i]:.3f}" for c in columns[1:]]
        if compare:
            cut = reduction[name]
            row += ["n/a" if cut is None else f"{cut:.0f}", f"{PAPER_IQR_REDUCTION[name]:.0f}"]
        body.append(row)
    return _render([header, *body])


Z95 = 1.959964  # two-sided 95 % quantile of the standard normal


def interval_table(
    theta: np.ndarray,
    covariance: np.ndarray,
    verdicts: dict[str, str],
    crb: np.ndarray | None = None,
    truth: np.ndarray | None = None,
    *,
    estimated: np.ndarray | None = None,
) -> str:
    """Theta with 1σ, its 95 % interval and the verdict of each parameter.

    Values in display units; σ and interval half-widths in mm (mm·s²/m for d). Every
    parameter's value is its estimate with its σ and interval, whatever its verdict (one
    not observable is its prior's, about), except one held by the vehicle profile (its
    nominal) and one whose verdict says it is not trusted: its σ is not honest. ``estimated``
    (``(4,)`` bool) marks the parameters that are estimates (default: all not held).
    """
    sigma = np.sqrt(np.diag(covariance))
    header = ["parameter", "value", "1σ", "95 % interval"]
    header += (["CRB 1σ"] if crb is not None else []) + (["error"] if truth is not None else [])
    header.append("verdict")
    body = []
    for i, name in enumerate(PARAMETER_NAMES):
        spread = "mm·s²/m" if name == "d" else "mm"
        value = theta[i] * DISPLAY_SCALE[i]
        row = [f"{name} [{DISPLAY_UNITS[i]}; {spread}]", _FORMATS[i].format(value)]
        held = verdicts[name] == HELD_VERDICT
        estimate = not held and (estimated is None or bool(estimated[i]))
        if verdicts[name].startswith("not trusted"):
            row += ["-", "none: not trusted"]
        elif estimate:
            half = Z95 * sigma[i] * DISPLAY_SCALE[i]
            row += [
                f"{sigma[i] * DEVIATION_SCALE[i]:.3f}",
                f"{_FORMATS[i].format(value - half)} … {_FORMATS[i].format(value + half)}",
            ]
        else:
            row += ["-", "nominal value, held"]
        if crb is not None:
            row.append(f"{np.sqrt(crb[i, i]) * DEVIATION_SCALE[i]:.3f}" if estimate else "-")
        if truth is not None:
            row.append(f"{(theta[i] - truth[i]) * DEVIATION_SCALE[i]:+.3f}" if estimate else "-")
        row.append(verdicts[name])
        body.append(row)
    return _render([header, *body])


def estimates_table(estimated: dict, unit: LengthUnit = METRES) -> str:
    """The sensor quantities estimated with theta
    (:mod:`graphcal.pipeline.methods.sensor_estimates`) with 1σ and the verdict (detected
    ones are corrected in the log): the time offset in ms, the lever arm in the vehicle's
    length ``unit``; ``-`` for one not estimated (not observable, or left out of the graph),
    never a prior's 0 ± its σ; a lever arm names the point it is measured from."""
    labels = {
        "time_offset": "time offset (wheels late)",
        "lever_arm_longitudinal": "lever arm, ahead",
        "lever_arm_lateral": "lever arm, left",
    }
    rows = [["sensors, estimated with θ", "value", "1σ", "verdict"]]
    slip_label = "rear axle's slip angle per lateral acceleration"
    for name, e in estimated.items():
        base, _, run = name.partition(":")
        label = labels.get(base, base)
        if getattr(e, "reference_point", ""):
            label = f"{label} of the {e.reference_point}"
        if run:
            label = f"{label}, run {run}"
        if base == "time_offset":
            symbol, value, sigma = "ms", f"{e.value * 1e3:+.1f}", f"{e.sigma * 1e3:.1f}"
        elif base == "rear_slip_gain":
            label, symbol = slip_label, "mrad per m/s²"
            value, sigma = f"{e.value * 1e3:+.2f}", f"{e.sigma * 1e3:.2f}"
        elif base in labels:
            symbol, value, sigma = unit.name, unit.format(e.value, sign=True), unit.spread(e.sigma)
        else:
            symbol, value, sigma = "SI", f"{e.value:+.4f}", f"{e.sigma:.4f}"
        if not e.observable:  # its prior's sigma is no estimate's
            value, sigma = "-", "-"
        rows.append([f"{label} [{symbol}]", value, sigma, e.verdict])
    return _render(rows)


def validation_table(errors: dict[str, float], unit: LengthUnit = METRES) -> str:
    """E_p per named theta, in the vehicle's length ``unit``."""
    return _render(
        [
            [f"validation error E_p [{unit.name}]", "mean"],
            *([name, unit.format(value)] for name, value in errors.items()),
        ]
    )


def _render(rows: list[list[str]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = [
        "  ".join(
            cell.ljust(w) if i == 0 else cell.rjust(w)
            for i, (cell, w) in enumerate(zip(row, widths, strict=True))
        )
        for row in rows
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
