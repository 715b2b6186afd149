"""The robot's manoeuvres in the motion-capture hall, on the fine grid of its simulation.

:func:`plan_manoeuvres` draws ``runs`` runs (straight and gently curved pieces, some arcs of
small radius, timed with the fastest speed within the cruise speed, the bends' limits and the
acceleration ramps), each ended by a stop and followed by a spin on the spot that points the
robot roughly back to where it started; optionally it reverses a little after every second
run. It gives the distance [m] and yaw [rad] of every step of :data:`FINE_DT`, from which
:func:`graphcal.simulate.robot.simulate_robot` makes the wheel rotations and the true poses.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from graphcal.model import wrap_angle
from graphcal.simulate.robot_settings import FINE_DT

if TYPE_CHECKING:
    from graphcal.simulate.robot_settings import RobotSettings

#: Arc-length step [m] of a run's path before it is timed.
PATH_STEP = 0.002
#: Kinds of manoeuvre in the table of :func:`plan_manoeuvres`.
MANOEUVRES = ("stop", "run", "spin", "reverse")


def _trapezoid(total: float, peak: float, accel: float) -> np.ndarray:
    """Progress (distance or angle, from 0 to ``total`` >= 0) at ``k * FINE_DT`` of a move
    that accelerates at ``accel`` to at most ``peak``, holds and decelerates to rest."""
    peak = min(peak, math.sqrt(accel * total))
    t_ramp = peak / accel
    t_hold = (total - peak * t_ramp) / peak if peak > 0 else 0.0
    duration = 2.0 * t_ramp + t_hold
    t = FINE_DT * np.arange(math.ceil(duration / FINE_DT) + 1)
    up = 0.5 * accel * np.minimum(t, t_ramp) ** 2
    hold = peak * np.clip(t - t_ramp, 0.0, t_hold)
    down_t = np.clip(t - t_ramp - t_hold, 0.0, t_ramp)
    down = peak * down_t - 0.5 * accel * down_t**2
    return np.minimum(up + hold + down, total)


def _run_path(length: float, rng: np.random.Generator, s: RobotSettings) -> tuple[np.ndarray, ...]:
    """Arc length [m] and course change [rad] of a run at ``k * FINE_DT``."""
    n_pieces = math.ceil(length / min(s.piece_length[0], 0.5 * math.pi * s.tight_radius[0])) + 1
    tight = rng.random(n_pieces) < s.tight_share
    straight = ~tight & (rng.random(n_pieces) < 0.4)
    side = rng.choice([-1.0, 1.0], n_pieces)
    radius = rng.uniform(*s.tight_radius, n_pieces)
    turn = rng.uniform(0.5 * math.pi, math.pi, n_pieces)  # of a tight arc [rad]
    gentle = rng.uniform(*s.gentle_curvature, n_pieces)
    kappa_piece = side * np.where(tight, 1.0 / radius, np.where(straight, 0.0, gentle))
    piece = np.where(tight, radius * turn, rng.uniform(*s.piece_length, n_pieces))
    edges = np.cumsum(piece)
    arc = np.linspace(0.0, length, math.ceil(length / PATH_STEP) + 1)
    kappa = kappa_piece[np.minimum(np.searchsorted(edges, arc), n_pieces - 1)]
    # Curvature eased over 0.2 m (a moving average), as a robot's controller turns in.
    half = max(1, round(0.1 / PATH_STEP))
    padded = np.concatenate([np.full(half, kappa[0]), kappa, np.full(half, kappa[-1])])
    summed = np.concatenate([[0.0], np.cumsum(padded)])
    kappa = (summed[2 * half + 1 :] - summed[: -2 * half - 1]) / (2 * half + 1)

    # Fastest speed within the run's cruise speed, the bend's limits and the ramps: forward
    # v² <= 2 a s' over the distance s' from the start, backward likewise to the end.
    cruise = rng.uniform(*s.cruise_speed)
    abs_kappa = np.maximum(np.abs(kappa), 1e-9)
    v_max = np.minimum.reduce(
        [
            np.full(len(arc), cruise),
            np.sqrt(s.lateral_acceleration_limit / abs_kappa),
            s.yaw_rate_limit / abs_kappa,
        ]
    )
    v_max[0] = v_max[-1] = 0.0
    a2 = 2.0 * s.acceleration
    forward = a2 * arc + np.minimum.accumulate(v_max**2 - a2 * arc)
    backward = -a2 * arc + np.minimum.accumulate((v_max**2 + a2 * arc)[::-1])[::-1]
    speed = np.sqrt(np.maximum(np.minimum(forward, backward), 0.0))
    mean = 0.5 * (speed[1:] + speed[:-1])
    time_at = np.concatenate([[0.0], np.cumsum(np.diff(arc) / mean)])
    course = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(arc))])
    t = FINE_DT * np.arange(math.ceil(time_at[-1] / FINE_DT) + 1)
    s_t = np.interp(t, time_at, arc)
    return s_t, np.interp(s_t, arc, course)


def plan_manoeuvres(
    runs: int, rng: np.random.Generator, s: RobotSettings, heading0: float
) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """Distance [m] and yaw [rad] of every fine step of ``runs`` runs from rest at heading
    ``heading0`` [rad], and the manoeuvres' table (one row per manoeuvre: ``kind``,
    ``start``, ``end`` [s], ``distance`` [m] and ``yaw`` [rad])."""
    distance: list[np.ndarray] = []
    yaw: list[np.ndarray] = []
    rows: list[tuple[str, int, int, float, float]] = []
    position, heading = np.zeros(2), heading0
    steps = 0

    def add(kind: str, travel: np.ndarray, turn: np.ndarray) -> None:
        nonlocal position, heading, steps
        d, w = np.diff(travel), np.diff(turn)
        course = heading + np.concatenate([[0.0], np.cumsum(w)[:-1]]) + 0.5 * w
        position = position + np.array([np.sum(d * np.cos(course)), np.sum(d * np.sin(course))])
        heading += float(np.sum(w))
        distance.append(d)
        yaw.append(w)
        rows.append((kind, steps, steps + len(d), float(np.sum(d)), float(np.sum(w))))
        steps += len(d)

    def stop() -> None:
        n = math.ceil(rng.uniform(*s.stop_duration) / FINE_DT)
        add("stop", np.zeros(n + 1), np.zeros(n + 1))

    stop()
    for k in range(runs):
        travel, turn = _run_path(rng.uniform(*s.run_length), rng, s)
        add("run", travel, turn)
        stop()
        if s.reversing and k % 2 == 1:
            back = -_trapezoid(rng.uniform(*s.reverse_length), s.reverse_speed, s.acceleration)
            add("reverse", back, np.zeros_like(back))
            stop()
        if k == runs - 1:
            break
        # Spin to face roughly back to the start (±45°), by 90–360° either way.
        home = math.atan2(-position[1], -position[0]) + rng.uniform(-0.25, 0.25) * math.pi
        angle = float(wrap_angle(home - heading))
        low, high = s.spin_angle
        while abs(angle) < low:
            angle += math.copysign(2.0 * math.pi, angle if angle != 0 else 1.0)
        if abs(angle) > high:
            angle = math.copysign(rng.uniform(low, high), angle)
        spin = math.copysign(1.0, angle) * _trapezoid(
            abs(angle), rng.uniform(*s.spin_rate), s.spin_acceleration
        )
        add("spin", np.zeros_like(spin), spin)
        stop()
    frame = pd.DataFrame(rows, columns=["kind", "start", "end", "distance", "yaw"])
    frame["start"] *= FINE_DT
    frame["end"] *= FINE_DT
    return np.concatenate(distance), np.concatenate(yaw), frame
