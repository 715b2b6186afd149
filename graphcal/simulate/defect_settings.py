"""The defects of real drive logs a synthetic drive can be given: :class:`Defects` (what is
on and how large, SI), their names for ``graphcal simulate --defects`` and their realistic
defaults. :mod:`graphcal.simulate.defects` reads them from text and applies them
(:func:`~graphcal.simulate.defects.degrade`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

#: Correlation time [s] of the wheel slip: φ = exp(−dt/τ) is 0.995 per 40 Hz sample.
SLIP_TIME = -0.025 / float(np.log(0.995))
#: Random-walk rate [rad/√s] of the fused-heading bias when on: 0.5°/√min.
HEADING_BIAS_RATE = float(np.deg2rad(0.5)) / float(np.sqrt(60.0))
#: Correlation time [s] that bounds the heading bias (GNSS aiding): stationary σ ≈ 1.1°.
HEADING_BIAS_TIME = 600.0
#: White noise [rad] of a fused heading: 0.3° (the paper's heading has 1.5°).
HEADING_WHITE = float(np.deg2rad(0.3))


@dataclass(frozen=True)
class Defects:
    """Which defects of real logs to add, and how large (SI units; ``None``/0: absent).

    The realistic default of each (what :func:`parse_defects` switches on for a bare name)
    follows in brackets; they come from measured real logs.

    Attributes:
        gnss_rate: GNSS fix rate [Hz]: each fix written once, at its own time, in the first
            log row at or after it (sparse measurements, ``DriveLog.measured``; a row holding
            a fix between rows has no heading) (``None``: every log sample is a fix) [10 Hz].
        gnss_hold: sample-and-hold the fixes to the log rate instead (needs ``gnss_rate``).
        gnss_interpolate: interpolate the fixes linearly to the log rate instead, as a
            resampler does (needs ``gnss_rate``): each fix then counts as several.
        outlier_share: share of the fixes moved by multipath [0.005].
        outlier_range: ``(least, most)`` distance [m] a multipath fix is off, in a uniformly
            random direction [(10, 50) m].
        outages: number of GNSS outages, placed at random [2].
        outage_s: duration of each outage [s] [30 s].
        outage_hold: the receiver repeats its last fix during an outage (``True``); else a
            true dropout: no pose at all, bridged linearly and marked ``masked`` in the log.
        heading_bias_rate: random-walk rate [rad/√s] of a slow bias of the fused heading
            [0.5°/√min = 1.13e-3 rad/√s: about 0.25° over a 15 s segment].
        heading_bias_time: correlation time [s] of that bias (a Gauss–Markov process, bounded
            by the GNSS aiding: stationary σ = rate·√(τ/2)); ``None``: a pure random walk
            [600 s: σ ≈ 1.1°].
        heading_white: white noise [rad] of the fused heading, replacing the drive's own
            (``None``: keep it) [0.3°].
        latency: delay [s] of the wheel signals relative to the pose: the rotation logged over
            ``[t_k, t_k+1]`` is the true one over ``[t_k − latency, t_k+1 − latency]``
            (negative: wheels early) [0.05 s].
        lever_arm: GNSS antenna position ``(longitudinal, lateral)`` [m] from the centre of
            gravity in the body frame (forward, left); the fix is CG + R(ψ)·arm [(1.2, 0) m].
        ticks_per_revolution: the wheel rotations are counts of this many ticks per revolution
            (cumulative rotation floored, counters starting at a random phase) [96].
        slip_sigma: stationary σ of each rear wheel's slow relative slip (an AR(1) scale on its
            rotation, independent per wheel) [0.0015 = 0.15 %].
        slip_time: correlation time [s] of the slip [4.99 s: φ = 0.995 per 40 Hz sample].
    """

    gnss_rate: float | None = None
    gnss_hold: bool = False
    gnss_interpolate: bool = False
    outlier_share: float = 0.0
    outlier_range: tuple[float, float] = (10.0, 50.0)
    outages: int = 0
    outage_s: float = 30.0
    outage_hold: bool = True
    heading_bias_rate: float = 0.0
    heading_bias_time: float | None = HEADING_BIAS_TIME
    heading_white: float | None = None
    latency: float = 0.0
    lever_arm: tuple[float, float] | None = None
    ticks_per_revolution: int = 0
    slip_sigma: float = 0.0
    slip_time: float = SLIP_TIME

    def __post_init__(self) -> None:
        def fail(what: str) -> None:
            raise ValueError(f"Defects: {what}")

        def finite(value: float) -> bool:
            return bool(np.isfinite(value))

        if self.gnss_rate is not None and not (finite(self.gnss_rate) and self.gnss_rate > 0):
            fail(f"gnss_rate must be a positive rate in Hz, got {self.gnss_rate}")
        if self.gnss_hold and self.gnss_rate is None:
            fail("gnss_hold needs a gnss_rate to hold the fixes of")
        if self.gnss_interpolate and (self.gnss_rate is None or self.gnss_hold):
            fail("gnss_interpolate needs a gnss_rate and excludes gnss_hold")
        if not (finite(self.outlier_share) and 0 <= self.outlier_share < 1):
            fail(f"outlier_share must be in [0, 1), got {self.outlier_share}")
        low, high = self.outlier_range
        if not (finite(low) and finite(high) and 0 <= low <= high):
            fail(f"outlier_range must be (least, most) metres >= 0, got {self.outlier_range}")
        if int(self.outages) != self.outages or self.outages < 0:
            fail(f"outages must be a whole number >= 0, got {self.outages}")
        if not (finite(self.outage_s) and self.outage_s > 0):
            fail(f"outage_s must be positive, got {self.outage_s}")
        if not (finite(self.heading_bias_rate) and self.heading_bias_rate >= 0):
            fail(f"heading_bias_rate must be >= 0, got {self.heading_bias_rate}")
        if self.heading_bias_time is not None and not (
            finite(self.heading_bias_time) and self.heading_bias_time > 0
        ):
            fail(f"heading_bias_time must be positive or None, got {self.heading_bias_time}")
        if self.heading_white is not None and not (
            finite(self.heading_white) and self.heading_white >= 0
        ):
            fail(f"heading_white must be >= 0 or None, got {self.heading_white}")
        if not (finite(self.latency) and abs(self.latency) < 10.0):
            fail(f"latency must be under 10 s, got {self.latency}")
        if self.lever_arm is not None and not (
            len(self.lever_arm) == 2 and all(finite(a) for a in self.lever_arm)
        ):
            fail(f"lever_arm must be (longitudinal, lateral) metres, got {self.lever_arm}")
        ticks = self.ticks_per_revolution
        if int(ticks) != ticks or ticks < 0:
            fail(f"ticks_per_revolution must be a whole number >= 0, got {ticks}")
        if not (finite(self.slip_sigma) and 0 <= self.slip_sigma < 0.1):
            fail(f"slip_sigma must be in [0, 0.1), got {self.slip_sigma}")
        if not (finite(self.slip_time) and self.slip_time > 0):
            fail(f"slip_time must be positive, got {self.slip_time}")

    @property
    def names(self) -> tuple[str, ...]:
        """The defects switched on, by their :data:`DEFECT_NAMES` (empty: a clean drive)."""
        on = {
            "gnss10hz": self.gnss_rate is not None
            and not (self.gnss_hold or self.gnss_interpolate),
            "hold": self.gnss_hold,
            "interpolated": self.gnss_interpolate,
            "outliers": self.outlier_share > 0,
            "outages": self.outages > 0 and self.outage_hold,
            "dropouts": self.outages > 0 and not self.outage_hold,
            "heading_bias": self.heading_bias_rate > 0 or self.heading_white is not None,
            "latency": self.latency != 0,
            "lever_arm": self.lever_arm is not None and any(self.lever_arm),
            "ticks": self.ticks_per_revolution > 0,
            "slip": self.slip_sigma > 0,
        }
        return tuple(name for name in DEFECT_NAMES if on[name])

    def to_dict(self) -> dict:
        """JSON-ready: the names switched on and every field (SI units)."""
        fields = dataclasses.asdict(self)
        for key, value in fields.items():
            if isinstance(value, tuple):
                fields[key] = list(value)
        return {"names": list(self.names), "settings": fields}


#: Each defect's name, main knob (SI) and realistic default, for ``--defects`` and its help.
DEFECTS: dict[str, str] = {
    "gnss10hz": "GNSS fixes at RATE Hz, each at its own time (10)",
    "hold": "GNSS fixes at RATE Hz, sample-and-hold to the log rate (10)",
    "interpolated": "GNSS fixes at RATE Hz, interpolated to the log rate (10)",
    "outliers": "SHARE of the fixes off by 10–50 m, multipath (0.005)",
    "outages": "COUNT outages of 30 s, the receiver holding its last fix (2)",
    "dropouts": "COUNT outages of 30 s without any pose, masked in the log (2)",
    "heading_bias": "fused heading: bias random walk RATE rad/√s (1.13e-3 = 0.5°/√min, "
    "τ 600 s) + 0.3° white instead of the drive's",
    "latency": "wheel signals SECONDS late relative to the pose (0.05)",
    "lever_arm": "GNSS antenna LONG[:LAT] m from the centre of gravity (1.2:0)",
    "ticks": "wheel rotation counted in TICKS per revolution (96)",
    "slip": "per-wheel slow slip, AR(1) relative SIGMA, φ 0.995 per 40 Hz sample (0.0015)",
}
DEFECT_NAMES: tuple[str, ...] = tuple(DEFECTS)
#: What ``all`` switches on: every defect but ``hold`` and ``dropouts``, the alternatives to
#: interpolated fixes and to outages that hold the last fix (``all,hold`` or ``all,dropouts``
#: switches to them).
DEFECTS_IN_ALL: tuple[str, ...] = tuple(
    n for n in DEFECT_NAMES if n not in ("hold", "interpolated", "dropouts")
)
