"""A run's figures drawn side by side in forked workers are the files one process draws."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from graphcal.report.rendering import png_bytes, rendered


def _figures(count: int) -> dict[str, Figure]:
    """``count`` figures with a line, a title and a legend each, by file name."""
    rng = np.random.default_rng(0)
    out = {}
    for i in range(count):
        fig = Figure(figsize=(4, 3), layout="constrained")
        ax = fig.add_subplot()
        ax.plot(np.cumsum(rng.normal(size=500)), label=f"path {i}")
        ax.set_title(f"figure {i}")
        ax.legend()
        out[f"figure_{i}.png"] = fig
    return out


def test_figures_drawn_by_two_workers_are_the_bytes_one_process_draws():
    images = _figures(3)
    alone = rendered(images, workers=1)
    together = rendered(images, workers=2)
    assert list(together) == list(images)  # in the figures' order
    assert together == alone
    assert all(png.startswith(b"\x89PNG\r\n\x1a\n") for png in alone.values())
    assert alone["figure_1.png"] == png_bytes(images["figure_1.png"])
    assert alone["figure_0.png"] != alone["figure_1.png"]
