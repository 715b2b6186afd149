"""Where a long log's whole-log solve starts: theta solved on a spread-out sample of it.

From the nominal theta a whole-log solve needs two Levenberg–Marquardt iterations before its
linearization is good (the datasheet theta is millimetres off, and the poses of every chunk
boundary start on the odometry of that theta). Each iteration linearizes every segment. A
sample of :data:`WARM_START_SEGMENTS` segments spread over the route determines theta to
within a few of the whole log's σ, at a fraction of one whole-log iteration; from there, with
the boundary poses on the odometry of that theta, the whole log's first step is already in
its quadratic range. The optimum is the whole log's either way: only the path to it changes.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.graph.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.segment_solve import solve_segment_graph
from graphcal.graph.solve_options import SolveOptions
from graphcal.log.segments import SegmentData, spread
from graphcal.progress import say

#: Segments of the sample a warm start solves.
WARM_START_SEGMENTS = 32
#: Logs with fewer selected segments than this start from the nominal theta: the sample would
#: not save a whole-log iteration's worth.
WARM_START_MIN_SEGMENTS = 3 * WARM_START_SEGMENTS


def warm_start(
    data: SegmentData, spec: SegmentGraphSpec, options: SolveOptions
) -> dict[int, np.ndarray] | None:
    """The graph-wide variables (theta, time offset, lever arm, by key) solved on
    :data:`WARM_START_SEGMENTS` of ``data``'s segments spread over the log, each on its own
    (untied), for the whole-log solve to start from. A shorter log whose segments the whole
    solve ties into chains gets its theta from all of them untied: a chain integrated with
    the nominal theta drifts metres from its fixes (the sample drive's first solve took 11
    iterations from χ²/dof 7087), one with a solved theta is moved onto them as one body.
    ``None`` for a shorter log without ties, a graph without theta, or a sample that cannot
    be solved (the whole log starts from ``spec`` then). The sample is solved as ``options``
    say, without a line per iteration."""
    if not spec.estimate_theta:
        return None
    if len(data) >= WARM_START_MIN_SEGMENTS:
        sample = spread(len(data), WARM_START_SEGMENTS)
        say(f"  start: theta from {len(sample)} segments spread over the log")
    elif spec.tied(data).any():
        sample = np.arange(len(data))
        say("  start: theta from the segments each on its own")
    else:
        return None
    quiet = dataclasses.replace(options, label="warm start", report_iterations=False)
    untied = dataclasses.replace(spec, tie_segments=False)
    try:
        solved = solve_segment_graph(data.take(sample), untied, quiet, covariance=False)
    except GraphcalError:
        return None
    return {key: np.asarray(solved.result.atVector(key)) for key in shared_keys(spec)}
