"""A run's figures rendered to PNG, side by side in forked processes when the run has
workers to spare.

Rendering is matplotlib's layout and drawing, one figure after another in one process: on the
2-core development machine 0.6–1.9 s a figure, 2.4 s for a real car's three, about 5 s for a
simulated drive's five (``docs/performance.md``). The figures are built here; a forked
worker inherits them (copy-on-write, nothing pickled but the PNG's bytes coming back) and
draws the ones it is handed. The bytes are the same wherever a figure is drawn.
"""

from __future__ import annotations

import io
import multiprocessing

from matplotlib.figure import Figure

from graphcal.pipeline.solvers.parallel import map_tasks

#: Resolution of the written figures [dots per inch].
DPI = 120

#: The figures a forked worker draws from: set before the workers fork, cleared after.
_INHERITED: dict[str, Figure] = {}


def png_bytes(figure: Figure, dpi: int = DPI) -> bytes:
    """``figure`` drawn as PNG at ``dpi``."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def rendered(images: dict[str, Figure], workers: int = 1, dpi: int = DPI) -> dict[str, bytes]:
    """Each of ``images`` (by file name) as PNG bytes, in file-name order of ``images``:
    drawn in up to ``workers`` forked processes where there are several figures and the
    platform forks (elsewhere, or with one worker, here one after another)."""
    names = list(images)
    workers = min(workers, len(names))
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return {name: png_bytes(images[name], dpi) for name in names}
    _INHERITED.update(images)
    try:
        tasks = [(name, dpi) for name in names]
        drawn = map_tasks(_inherited_png, tasks, workers, report=False, fork=True)
    finally:
        _INHERITED.clear()
    return dict(zip(names, drawn, strict=True))


def _inherited_png(name: str, dpi: int) -> bytes:
    """In a forked worker: the inherited figure ``name`` as PNG bytes."""
    return png_bytes(_INHERITED[name], dpi)
