"""A fleet run's result files: ``fleet.csv`` (one row per log), ``vehicles.csv`` (one row per
vehicle), ``fleet.parquet`` (if ``pyarrow`` is installed) and ``fleet.png``.

Columns are SI, as in ``batches.csv``: ``c_e``, ``c_d``, ``t_r`` [m], ``d`` [s²] and their
``sigma_*`` (every parameter's estimate with its marginal σ, ``verdict_*`` says how well it
is determined); empty where a log failed. ``fleet.csv`` also
has a ``verdict_*`` per parameter (after ``not_calibrated``; older files lack them):
``calibrated``, ``weakly determined`` or ``not observable``
(:mod:`graphcal.graph.solution.observability`).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from graphcal.files import atomic_save_figure, atomic_write_csv
from graphcal.fleet.history import VehicleHistory
from graphcal.graph.solution.observability import DEFAULT_MAX_SIGMA_RATIO as MAX_SIGMA_RATIO
from graphcal.model import PARAMETER_NAMES
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS


def fleet_table(results: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per log: vehicle, day, status, reason, the recommended theta and σ (SI: each
    parameter's posterior and marginal σ), the parameters
    not calibrated, each parameter's verdict (``verdict_d``), χ²/dof, trusted, distance,
    segments, warnings, seconds, path, key."""
    rows = []
    for r in results:
        row = {k: r.get(k) for k in ("vehicle", "day", "status", "reason")}
        theta, covariance = r.get("theta"), r.get("covariance")
        calibrated = r.get("calibrated") or [False] * len(PARAMETER_NAMES)
        for i, name in enumerate(PARAMETER_NAMES):
            row[name] = float(theta[i]) if theta is not None else None
            row[f"sigma_{name}"] = None if theta is None else float(np.sqrt(covariance[i][i]))
        row["not_calibrated"] = " ".join(
            n for n, ok in zip(PARAMETER_NAMES, calibrated, strict=True) if not ok
        )
        verdicts = result_verdicts(r)
        for name in PARAMETER_NAMES:
            row[f"verdict_{name}"] = None if verdicts is None else verdicts.get(name)
        row |= {k: r.get(k) for k in ("chi2_per_dof", "trusted", "distance_m", "segments")}
        row["warnings"] = len(r.get("warnings") or [])
        row |= {k: r.get(k) for k in ("seconds", "path", "key")}
        rows.append(row)
    return pd.DataFrame(rows)


def result_verdicts(result: dict[str, Any]) -> dict[str, str] | None:
    """A log's verdicts as its run gave them (:meth:`Observability.verdicts`; results kept
    from an earlier run carry their own, older wording); ``None`` for a failed log."""
    return result.get("verdicts")


def vehicles_table(histories: list[VehicleHistory]) -> pd.DataFrame:
    """One row per vehicle: days calibrated, changes, the current theta and σ (SI: the
    posterior of the days since the last change), the parameters those days do not
    determine, flags."""
    rows = []
    for h in histories:
        row: dict[str, Any] = {
            "vehicle": h.vehicle,
            "days": len(h.days),
            "changes": "; ".join(c.describe() for c in h.changes),
            "current_since": h.current_days[0] if h.current_days else None,
            "current_days": len(h.current_days),
        }
        for i, name in enumerate(PARAMETER_NAMES):
            row[name] = None if h.theta is None else float(h.theta[i])
            row[f"sigma_{name}"] = (
                None if h.covariance is None else float(np.sqrt(h.covariance[i, i]))
            )
        row["not_calibrated"] = ""
        if h.covariance is not None:
            ratio = np.sqrt(np.diag(h.covariance)) / h.days[-1].prior_sigmas
            row["not_calibrated"] = " ".join(
                n for n, r in zip(PARAMETER_NAMES, ratio, strict=True) if r > MAX_SIGMA_RATIO
            )
        row["flags"] = "; ".join(h.flags)
        rows.append(row)
    return pd.DataFrame(rows)


def write_fleet_report(
    results: list[dict[str, Any]], histories: list[VehicleHistory], out: str | os.PathLike[str]
) -> list[Path]:
    """Write ``fleet.csv``, ``vehicles.csv``, ``fleet.parquet`` (with ``pyarrow``) and
    ``fleet.png`` into ``out``, each atomically; returns the paths."""
    out = Path(out)
    table = fleet_table(results)
    written = [
        atomic_write_csv(table, out / "fleet.csv"),
        atomic_write_csv(vehicles_table(histories), out / "vehicles.csv"),
    ]
    if importlib.util.find_spec("pyarrow") is not None:
        parquet = out / "fleet.parquet"
        tmp = parquet.with_name(f".{parquet.name}.{os.getpid()}.tmp")
        try:
            table.to_parquet(tmp, index=False)
            os.replace(tmp, parquet)
        finally:
            tmp.unlink(missing_ok=True)
        written.append(parquet)
    written.append(atomic_save_figure(fleet_figure(histories), out / "fleet.png"))
    return written


#: Vehicles in ``fleet.png`` at most: those with changes or flags first, then the others.
FIGURE_VEHICLES = 24


def fleet_figure(histories: list[VehicleHistory]):
    """c_e and c_d of the vehicles over their days with ±2σ, changes marked (red line at the
    first day of the new theta); at most :data:`FIGURE_VEHICLES`, those with changes or
    flags first."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    total = len(histories)
    noted = [h for h in histories if h.changes or h.flags]
    rest = [h for h in histories if not (h.changes or h.flags)]
    histories = sorted((noted + rest)[:FIGURE_VEHICLES], key=lambda h: h.vehicle)
    shown = [0, 1]  # c_e, c_d
    count = max(1, len(histories))
    figure, axes = plt.subplots(
        len(shown), count, figsize=(2.2 * count + 1.5, 5.5), squeeze=False, sharey="row"
    )
    for column, h in enumerate(histories):
        days = [d.day for d in h.days]
        x = np.arange(len(days))
        for row, i in enumerate(shown):
            ax = axes[row, column]
            if days:
                values = np.array([d.theta[i] for d in h.days]) * DISPLAY_SCALE[i]
                sigma = np.sqrt([d.covariance[i, i] for d in h.days]) * DISPLAY_SCALE[i]
                ax.errorbar(x, values, yerr=2 * sigma, fmt="o", capsize=3, color="C0")
                for change in h.changes:
                    at = days.index(change.day)
                    ax.axvline(at - 0.5, color="red", lw=1.5)
            ax.set_xticks(x, days, rotation=45, fontsize=7)
            if row == 0:
                title = h.vehicle + (" ⚑" if h.flags else "")
                ax.set_title(title, fontsize=9, color="red" if h.changes or h.flags else "black")
            if column == 0:
                ax.set_ylabel(f"{PARAMETER_NAMES[i]} [{DISPLAY_UNITS[i]}]")
    which = "" if total <= FIGURE_VEHICLES else f"{count} of {total} vehicles; "
    figure.suptitle(
        f"{which}per vehicle over days, ±2σ; red line: theta changed "
        f"(c_e in {DISPLAY_UNITS[0]}, c_d in {DISPLAY_UNITS[1]})",
        fontsize=10,
    )
    figure.tight_layout()
    return figure


def summary_lines(histories: list[VehicleHistory]) -> list[str]:
    """The end-of-run summary: changes and flags per vehicle (display units)."""
    lines = []
    for h in histories:
        for change in h.changes:
            lines.append(f"{h.vehicle}: theta changed on {change.describe()}")
        for flag in h.flags:
            lines.append(f"{h.vehicle}: flagged: {flag}")
    if not lines:
        lines.append("no vehicle's theta changed; no vehicle flagged")
    return lines
