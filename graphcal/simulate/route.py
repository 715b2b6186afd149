"""Random suburban/city routes as curvature profiles over arc length.

A route alternates straights with manoeuvres — bends, turns at crossroads, roundabouts and
S-curves — joined by clothoid transitions (curvature linear in arc length), so the heading is
smooth. Positive curvature turns left. Each piece carries a speed limit; the vehicle's speed
profile is computed from it in :mod:`graphcal.simulate.drive`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KMH = 1.0 / 3.6


@dataclass(frozen=True)
class Route:
    """A route sampled on arc length.

    Attributes:
        arc_length: sample positions along the route [m], ``(M,)``, uniform spacing.
        curvature: path curvature [1/m], ``(M,)``; positive turns left.
        speed_limit: legal/driver speed limit [m/s], ``(M,)``.
    """

    arc_length: np.ndarray
    curvature: np.ndarray
    speed_limit: np.ndarray


class _RouteBuilder:
    """Accumulates curvature knots (piecewise linear) and speed-limit breakpoints."""

    def __init__(self) -> None:
        self.knot_s: list[float] = [0.0]
        self.knot_kappa: list[float] = [0.0]
        self.limit_s: list[float] = [0.0]
        self.limit_v: list[float] = [50 * KMH]

    @property
    def length(self) -> float:
        return self.knot_s[-1]

    def sample(self, spacing: float) -> Route:
        """The route sampled every ``spacing`` metres of arc length."""
        arc_length = np.arange(0.0, self.length, spacing)
        curvature = np.interp(arc_length, self.knot_s, self.knot_kappa)
        piece = np.searchsorted(np.asarray(self.limit_s), arc_length, side="right") - 1
        return Route(arc_length, curvature, np.asarray(self.limit_v)[piece])

    def _knot(self, ds: float, kappa: float) -> None:
        self.knot_s.append(self.knot_s[-1] + ds)
        self.knot_kappa.append(kappa)

    def limit(self, speed: float) -> None:
        self.limit_s.append(self.length)
        self.limit_v.append(speed)

    def straight(self, length: float) -> None:
        self._knot(length, 0.0)

    def arc(self, radius: float, angle: float, transition: float) -> None:
        """A turn of ``angle`` [rad] (sign = direction) at ``radius`` [m] with clothoid ends."""
        turn = abs(angle)
        transition = min(transition, 0.5 * radius * turn)
        constant = radius * turn - transition  # arc length at full curvature
        kappa = np.sign(angle) / radius
        self._knot(transition, kappa)
        self._knot(constant, kappa)
        self._knot(transition, 0.0)


def generate_route(length: float, rng: np.random.Generator, spacing: float = 0.1) -> Route:
    """A random city/suburban route of at least ``length`` metres.

    Args:
        length: route length [m].
        rng: random generator (the route is a pure function of its state).
        spacing: arc-length sampling [m].
    """
    b = _RouteBuilder()
    deg = np.pi / 180.0
    while b.length < length:
        b.limit(rng.choice([50.0, 50.0, 60.0, 70.0]) * KMH)
        b.straight(rng.uniform(25.0, 180.0))
        kind = rng.choice(["bend", "turn", "roundabout", "s_curve"], p=[0.3, 0.38, 0.14, 0.18])
        side = rng.choice([-1.0, 1.0])
        if kind == "bend":
            b.arc(
                rng.uniform(30.0, 180.0),
                side * rng.uniform(25.0, 100.0) * deg,
                rng.uniform(8.0, 20.0),
            )
        elif kind == "turn":  # crossroads: tight 90° turn
            b.limit(30 * KMH)
            b.arc(
                rng.uniform(7.0, 14.0), side * rng.uniform(80.0, 100.0) * deg, rng.uniform(2.0, 5.0)
            )
        elif kind == "roundabout":  # right-hand traffic: in right, circle left, out right
            b.limit(30 * KMH)
            radius = rng.uniform(12.0, 22.0)
            b.arc(15.0, -35.0 * deg, 4.0)
            b.arc(radius, rng.choice([150.0, 240.0, 330.0]) * deg, 4.0)
            b.arc(15.0, -35.0 * deg, 4.0)
        else:  # S-curve: two opposite bends
            radius = rng.uniform(25.0, 80.0)
            angle = rng.uniform(25.0, 60.0) * deg
            b.arc(radius, side * angle, 8.0)
            b.straight(rng.uniform(0.0, 20.0))
            b.arc(radius, -side * angle, 8.0)
    b.limit(50 * KMH)
    b.straight(50.0)
    return b.sample(spacing)


def generate_straight_route(length: float, rng: np.random.Generator, spacing: float = 0.1) -> Route:
    """A straight road of at least ``length`` metres (a motorway-like drive with no bends).

    Speed limits change every few hundred metres (60–110 km/h), so the speed varies, but the
    yaw rate and lateral acceleration are zero throughout: t_r and d are not observable.
    """
    b = _RouteBuilder()
    while b.length < length:
        b.limit(rng.choice([60.0, 80.0, 90.0, 110.0]) * KMH)
        b.straight(min(rng.uniform(300.0, 1500.0), length - b.length + 1.0))
    return b.sample(spacing)


ROUTES = {"city": generate_route, "straight": generate_straight_route}
