"""Plain-text tables of theta in the paper's display units (m, mm, m, mm·s²/m)."""

from __future__ import annotations

import numpy as np

from graphcal.model import PARAMETER_NAMES
from graphcal.units import DISPLAY_UNITS, to_display

_FORMATS = ("{:.4f}", "{:.3f}", "{:.4f}", "{:.3f}")


def theta_table(rows: dict[str, np.ndarray]) -> str:
    """A table with one row per named theta (SI in, display units out, units in the header)."""
    header = ["", *(f"{n} [{u}]" for n, u in zip(PARAMETER_NAMES, DISPLAY_UNITS, strict=True))]
    body = [
        [name, *(f.format(v) for f, v in zip(_FORMATS, to_display(theta), strict=True))]
        for name, theta in rows.items()
    ]
    return _render([header, *body])


def error_table(errors: dict[str, np.ndarray]) -> str:
    """Median / 75th percentile / max of validation errors [m] per theta."""
    header = ["validation error [m]", "median", "75 %", "max"]
    body = [
        [name, f"{np.median(e):.3f}", f"{np.percentile(e, 75):.3f}", f"{np.max(e):.3f}"]
        for name, e in errors.items()
    ]
    return _render([header, *body])


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
