"""A recording's shape: what vehicle, road and sensors made it, drawn by ``hypothesis``."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

from hypothesis import strategies as st

VEHICLES = ("car", "differential", "skid-steer")
#: Wheel signals a shape draws: ``[wheels] kind`` of the manifest.
WHEEL_KINDS = ("speed", "angular_speed", "ticks")


@dataclass(frozen=True)
class Shape:
    """One recording shape (SI). ``length_m`` is each drive's; ``drives`` drives share one
    clock, ``gap_s`` apart (every stream stops), each parked ``park_s`` at its start and end.
    ``noise_tau_s`` 0 is white position noise, else a Gauss–Markov error with that
    correlation time. ``time_offset_s`` > 0: the wheels are stamped late. ``lever_arm`` is
    the antenna's (ahead, left) [m] of the wheels' reference point. ``ticks`` is the
    counter's resolution [ticks/rev] when ``wheels == "ticks"`` (else 0). ``outliers``: the
    share of fixes 10–50 m off; ``outage_s``: the fixes stop that long amid the first drive
    (the wheels go on); ``slip``: the amplitude of a slow wheel slip (the rotations scaled
    by 1 + slip · sin, over minutes: none on average where the fixes see it);
    ``mounting``: the IMU's (roll, pitch, yaw) [deg] in the vehicle (its three axes logged
    in its own frame; the manifest gives the angles, or ``"estimate"`` with
    ``mounting_estimated``); ``sideslip``: the fixes log the rear axle's sideslip (a car's
    tyre slip angle)."""

    vehicle: str
    route: str
    length_m: float
    gnss_rate: float
    noise_sigma: float
    noise_tau_s: float
    heading: bool
    imu: bool
    wheels: str
    ticks: int
    drives: int
    gap_s: float
    park_s: float
    time_offset_s: float
    lever_arm: tuple[float, float]
    seed: int
    outliers: float = 0.0
    outage_s: float = 0.0
    slip: float = 0.0
    mounting: tuple[float, float, float] | None = None
    mounting_estimated: bool = False
    sideslip: bool = False

    def label(self) -> str:
        """The shape in one short line."""
        noise = f"{self.noise_sigma:.2g} m " + (
            f"GM {self.noise_tau_s:.0f} s" if self.noise_tau_s else "white"
        )
        wheels = f"ticks {self.ticks}" if self.wheels == "ticks" else self.wheels
        drives = f", {self.drives} drives gap {self.gap_s:.0f} s" if self.drives > 1 else ""
        return (
            f"{self.vehicle} {self.route} {self.length_m / 1e3:.2g} km, {self.gnss_rate:.3g} Hz "
            f"{noise}, {'heading' if self.heading else 'no heading'}, "
            f"{'IMU' if self.imu else 'no IMU'}, {wheels}{drives}, park {self.park_s:.0f} s, "
            f"late {self.time_offset_s * 1e3:.0f} ms, arm ({self.lever_arm[0]:.2g}, "
            f"{self.lever_arm[1]:.2g}) m{self._defects()}, seed {self.seed}"
        )

    def _defects(self) -> str:
        """The label's part for outliers, an outage, slip and a mounted IMU (if drawn)."""
        parts = []
        if self.outliers:
            parts.append(f"outliers {self.outliers:.1%}")
        if self.outage_s:
            parts.append(f"outage {self.outage_s:.0f} s")
        if self.slip:
            parts.append(f"slip {self.slip:.2%}")
        if self.mounting is not None:
            angles = ", ".join(f"{a:.0f}" for a in self.mounting)
            parts.append(f"IMU at ({angles})°" + (" estimated" if self.mounting_estimated else ""))
        if self.sideslip:
            parts.append("sideslip logged")
        return "".join(f", {part}" for part in parts)


@contextlib.contextmanager
def drawn_from_the_seed_alone() -> Iterator[None]:
    """Within: hypothesis draws from its seed alone. Hypothesis (≥ 6.131) mixes literals of
    the local modules loaded so far (graphcal's, a script's) into its draws, so a seed's
    shapes changed with the code and with how the campaign was started (seed 30's shape 124
    was a skid-steer robot run as ``scripts/campaign.py``, a differential one looked up by
    ``runpy``). An internal of hypothesis: where it is missing, nothing changes."""
    from hypothesis.internal.conjecture import providers

    local = getattr(providers, "_get_local_constants", None)
    cache = getattr(providers, "CONSTANTS_CACHE", None)
    if local is None or cache is None or not hasattr(providers, "Constants"):
        yield
        return
    cache.cache.clear()
    providers._get_local_constants = providers.Constants
    try:
        yield
    finally:
        providers._get_local_constants = local
        cache.cache.clear()


def _rounded(low: float, high: float, digits: int) -> st.SearchStrategy[float]:
    return st.floats(low, high).map(lambda x: round(x, digits))


@st.composite
def shapes(
    draw: st.DrawFn,
    car_length_m: tuple[float, float] = (1000.0, 3000.0),
    robot_length_m: tuple[float, float] = (150.0, 400.0),
    vehicles: tuple[str, ...] = VEHICLES,
) -> Shape:
    """A recording shape: every axis drawn (lengths per drive in ``car_length_m`` or
    ``robot_length_m`` [m])."""
    vehicle = draw(st.sampled_from(vehicles))
    car = vehicle == "car"
    route = draw(st.sampled_from(["town", "straight"])) if car else "yard"
    lengths = car_length_m if car else robot_length_m
    wheels = draw(st.sampled_from(WHEEL_KINDS))
    ticks = draw(st.integers(16, 4096)) if wheels == "ticks" else 0
    drives = draw(st.sampled_from([1, 1, 2, 3]))
    tau = draw(st.sampled_from([0.0, 1.0])) * draw(_rounded(5.0, 60.0, 0))
    arm = (draw(_rounded(-1.5, 1.5, 2)), draw(_rounded(-0.5, 0.5, 2))) if car else (
        draw(_rounded(-0.3, 0.3, 2)), 0.0
    )  # fmt: skip
    fields = dict(
        vehicle=vehicle,
        route=route,
        length_m=draw(_rounded(*lengths, 0)),
        gnss_rate=draw(st.sampled_from([0.5, 1.0, 2.0, 2.5, 5.0, 10.0, 20.0, 50.0])),
        noise_sigma=draw(_rounded(0.2, 2.0, 2)),
        noise_tau_s=tau,
        heading=draw(st.booleans()),
        imu=draw(st.booleans()),
        wheels=wheels,
        ticks=ticks,
        drives=drives,
        gap_s=draw(_rounded(20.0, 60.0, 0)) if drives > 1 else 0.0,
        park_s=draw(_rounded(0.0, 8.0, 0)),
        time_offset_s=draw(_rounded(-0.05, 0.05, 3)),
        lever_arm=arm,
        seed=draw(st.integers(0, 2**16)),
    )
    return Shape(**fields, **_defect_axes(draw, car, fields["imu"]))


def _defect_axes(draw: st.DrawFn, car: bool, imu: bool) -> dict:
    """Outliers, an outage, slow slip, a mounted IMU, a logged sideslip: each in some of the
    shapes."""
    mounting = None
    if imu and draw(st.booleans()):
        yaw = draw(st.sampled_from([0.0, 90.0, 180.0, -90.0])) + draw(_rounded(-10.0, 10.0, 0))
        mounting = (draw(_rounded(-10.0, 10.0, 0)), draw(_rounded(-10.0, 10.0, 0)), yaw)
    return dict(
        outliers=draw(st.sampled_from([0.0, 0.0, 0.0, 0.002, 0.01])),
        outage_s=draw(st.sampled_from([0.0, 0.0, 1.0])) * draw(_rounded(10.0, 60.0, 0)),
        slip=draw(st.sampled_from([0.0, 0.0, 1.0])) * draw(_rounded(0.0005, 0.003, 4)),
        mounting=mounting,
        mounting_estimated=mounting is not None and car and draw(st.booleans()),
        sideslip=car and draw(st.booleans()),
    )
