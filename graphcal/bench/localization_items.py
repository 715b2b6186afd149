"""The benchmark's localization items (f)–(g): the smoothing example with each odometry
factor kind, and the online fixed-lag update (:mod:`graphcal.bench.run` lists them all).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from graphcal.bench.localization import solve_smoothing
from graphcal.bench.recording import timed
from graphcal.localization.online import run_online
from graphcal.simulate.drive import simulate_drive


def localization_items(
    record: Callable[..., None],
    repeats: int,
    length_km: float = 4.0,
    seed: int = 7,
) -> dict[str, Any]:
    """Items (f)–(g): the smoothing example with each odometry factor kind, and the online
    update; returns the ratios measured in this run."""
    drive = simulate_drive(length_km, seed=seed)
    log, theta = drive.measured, drive.theta_true
    solves, medians = {}, {}
    for kind, estimate in (
        ("reintegrating", False),
        ("between", False),
        ("reintegrating", True),
        ("preintegrated", True),
    ):
        label = f"{kind}, theta {'variable' if estimate else 'fixed'}"
        seconds, solved = timed(
            lambda k=kind, e=estimate: solve_smoothing(log, k, theta, e), repeats
        )
        solves[label], medians[label] = solved, seconds
        record(
            f"(f) smoothing {length_km:g} km, {label}",
            seconds,
            iterations=solved.iterations,
            keyframes=len(solved.states),
        )
    seconds, python_driven = timed(
        lambda: solve_smoothing(log, "preintegrated", theta, True, driver="python"), repeats
    )
    medians["python-driven"] = seconds
    record(
        f"(f) smoothing {length_km:g} km, preintegrated, theta variable, LM driven from Python",
        seconds,
        iterations=python_driven.iterations,
        keyframes=len(python_driven.states),
    )
    fixed_old, fixed_new = solves["reintegrating, theta fixed"], solves["between, theta fixed"]
    var_old = solves["reintegrating, theta variable"]
    var_new = solves["preintegrated, theta variable"]
    difference = np.linalg.norm(fixed_old.states[:, :2] - fixed_new.states[:, :2], axis=1)
    online = run_online(simulate_drive(3.5, seed=11).measured)
    record(
        "(g) online fixed-lag update (3.5 km)",
        float(np.median(online.update_seconds)),
        mean_update_ms=float(online.update_seconds.mean() * 1e3),
        ms_per_drive_second=online.seconds_per_drive_second() * 1e3,
    )
    return {
        "keyframes": len(fixed_new.states),
        "theta_fixed_reintegrating_over_between": medians["reintegrating, theta fixed"]
        / medians["between, theta fixed"],
        "theta_fixed_max_position_difference_m": float(difference.max()),
        "theta_variable_reintegrating_over_preintegrated": medians["reintegrating, theta variable"]
        / medians["preintegrated, theta variable"],
        "theta_variable_max_theta_difference": (var_old.theta - var_new.theta).tolist(),
        "theta_variable_gtsam_lm_over_python_lm": medians["preintegrated, theta variable"]
        / medians["python-driven"],
        "python_lm_theta_difference": (python_driven.theta - var_new.theta).tolist(),
        "online_mean_update_ms": float(online.update_seconds.mean() * 1e3),
        "online_ms_per_drive_second": online.seconds_per_drive_second() * 1e3,
    }
