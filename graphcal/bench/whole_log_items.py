"""The benchmark's items of the whole-log solve: (i) with and without the defect model, (j)
one graph against segment by segment, (l) the batch study's joint batches on their own and
from the segments' systems (:mod:`graphcal.bench.run` lists them all).

Each item records its rows with ``record`` (:class:`~graphcal.bench.recording.Recorder`'s
call) and returns what the report keeps of it.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from graphcal.bench.recording import timed
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.covariance import marginal_covariance
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, make_batches
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.methods.joint_batches import solve_joint_batches
from graphcal.pipeline.solvers.joint import solve_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings, without_defect_model


def segmented_items(record: Callable[..., None], data: SegmentData, repeats: int) -> dict[str, Any]:
    """(j) The joint solve of all selected segments with its covariance (the defaults' graph:
    theta, time offset, lever arm, heading biases), as one graph under GTSAM's
    Levenberg–Marquardt optimizer with GTSAM's marginals (the formulation before issue 14),
    and segment by segment (:mod:`graphcal.graph.optimization.partitioned`) in one and two
    processes, one after the other; returns the ratios and the largest relative theta and covariance
    differences to the single graph."""
    spec = JointSettings().graph_spec()
    shared = shared_keys(spec)

    def single_graph() -> tuple[np.ndarray, np.ndarray]:
        built = build_segment_graph(data, spec)
        result, _ = solve_lm(built.graph, built.values, SolveOptions(50, 1e-7, "single graph"))
        covariance = marginal_covariance(built.graph, result, shared, "single graph")
        return np.asarray(result.atVector(keys.THETA)), covariance[:4, :4]

    single_s, (theta, covariance) = timed(single_graph, repeats)
    record("(j) whole-log joint solve, one graph (GTSAM LM)", single_s, segments=len(data))
    out: dict[str, Any] = {"segments": len(data), "single_graph_s": single_s}
    for workers in (1, 2):
        seconds, solution = timed(
            lambda w=workers: solve_segment_graph(
                data, spec, SolveOptions(50, 1e-7, "segmented", workers=w)
            ),
            repeats,
        )
        scale = np.sqrt(np.outer(np.diag(covariance), np.diag(covariance)))
        theta_difference = float(np.max(np.abs(solution.theta - theta) / np.abs(theta)))
        covariance_difference = float(np.max(np.abs(solution.covariance - covariance) / scale))
        record(
            f"(j) whole-log joint solve, segment by segment, {workers} process(es)",
            seconds,
            over_single=seconds / single_s,
            theta_rel_difference=theta_difference,
            covariance_rel_difference=covariance_difference,
        )
        out[f"segmented_{workers}_s"] = seconds
        out[f"single_over_segmented_{workers}"] = single_s / seconds
        out[f"theta_rel_difference_{workers}"] = theta_difference
        out[f"covariance_rel_difference_{workers}"] = covariance_difference
    return out


def batch_study_items(
    record: Callable[..., None], data: SegmentData, count: int, workers: int
) -> dict[str, Any]:
    """(l) The joint batch study of ``count`` batches of 9: solved one batch after the other
    (``"exact"``, the formulation before issue 14, timed on the first ``min(count, 10)``)
    and from the segments' systems at the whole-log solution (``"linearized"``, all
    ``count``), each per batch; with the largest theta difference in the exact solves' σ."""
    settings = dataclasses.replace(JointSettings(), robust_threshold=0.0, slip="off")
    batches = make_batches(len(data), min(9, len(data)), count, seed=0)
    start = time.perf_counter()
    _, values = solve_joint(data, settings, workers)
    whole_s = time.perf_counter() - start
    start = time.perf_counter()
    linearized = solve_joint_batches(data, batches, settings, "linearized", values, workers)
    linearized_s = (time.perf_counter() - start) / len(batches)
    few = batches[: min(len(batches), 10)]
    start = time.perf_counter()
    exact = solve_joint_batches(data, few, settings, "exact", workers=workers)
    exact_s = (time.perf_counter() - start) / len(few)
    difference = max(
        (
            float(np.max(np.abs(lin.theta - ex.theta) / np.sqrt(np.diag(ex.covariance))))
            for lin, ex in zip(linearized, exact, strict=False)
            if lin is not None and ex is not None
        ),
        default=None,
    )
    record("(l) joint batch, solved on its own (exact)", exact_s, batches=len(few))
    record(
        "(l) joint batch, from the segments' systems",
        linearized_s,
        batches=len(batches),
        exact_over_linearized=exact_s / linearized_s,
        max_theta_difference_sigma=difference,
        whole_log_solve_s=whole_s,
    )
    return {
        "batches": len(batches),
        "exact_per_batch_s": exact_s,
        "linearized_per_batch_s": linearized_s,
        "whole_log_solve_s": whole_s,
        "exact_over_linearized": exact_s / linearized_s,
        "max_theta_difference_sigma": difference,
    }


def whole_log_items(record: Callable[..., None], log: DriveLog, repeats: int) -> float:
    """(i) The whole-log solve (the recommended theta) of ``log`` with the defect model (the
    defaults) and without it (``--no-defect-model``), one after the other; returns the ratio
    of their median times (issue 13 asks at most 1.5 on a clean 24 km drive)."""
    settings = Settings()
    plain = dataclasses.replace(settings, joint=without_defect_model(settings.joint))
    plain_s, _ = timed(lambda: run_calibration(log, plain, "whole"), repeats)
    record("(i) whole-log solve, no defect model", plain_s)
    model_s, _ = timed(lambda: run_calibration(log, settings, "whole"), repeats)
    ratio = model_s / plain_s
    record("(i) whole-log solve, defect model (default)", model_s, over_plain=ratio)
    return ratio
