"""What the whole-log solve found out about the sensors: the wheels' time offset, the GNSS
antenna's lever arm, and the fixes it down-weighted as outliers.

The joint graph estimates the time offset and the lever arm with theta
(:mod:`graphcal.graph.construction.builder`), each under a wide zero-mean prior; a component counts
as observable when the drive shrinks that prior's sigma to at most the same fraction that
theta's parameters need (:mod:`graphcal.graph.solution.observability`), and as detected when it is
observable and more than :data:`DETECTION_SIGMAS` σ from zero. Detected quantities are
corrected in the log (:func:`correct_log`) for the batch solves and the validation (an
estimate within noise of zero would only add its noise to every batch); a component the
drive cannot show (a lateral arm on straight roads) is reported not observable.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.graph.solution.estimates import NuisanceEstimate
from graphcal.log.antenna import move_to_centre
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData
from graphcal.log.timing import shift_wheel_rotations, whole_samples

#: Fixes with a robust weight below this are counted as down-weighted (an outlier's weight
#: is ``(k σ̂ / |r|)²``: below 0.9 means more than ~5 % beyond the threshold).
DOWN_WEIGHTED = 0.9
#: An observable estimate farther than this many σ from zero is detected (and corrected).
DETECTION_SIGMAS = 3.0
#: Each estimated quantity's name per component of a nuisance variable.
COMPONENTS = {
    "time_offset": ("time_offset",),
    "lever_arm": ("lever_arm_longitudinal", "lever_arm_lateral"),
    "rear_slip_gain": ("rear_slip_gain",),
}


@dataclass(frozen=True)
class SensorEstimate:
    """A sensor quantity estimated with theta (SI).

    Attributes:
        name: ``"time_offset"`` [s] (positive: wheels late against the pose; one per run,
            ``"time_offset:0"``, ``"time_offset:1"``, …, in a log of several runs),
            ``"lever_arm_longitudinal"`` or ``"lever_arm_lateral"`` [m] (ahead, left),
            ``"rear_slip_gain"`` [rad per m/s²] (a log without a sideslip: its rear axle moves
            at ``−gain · a_y`` to the heading).
        value, sigma: the estimate and its standard deviation.
        prior_sigma: the sigma of its zero-mean prior.
        observable: the drive determined it.
        reference_point: what a lever arm is measured from (the log's
            :meth:`~graphcal.log.drive_log.DriveLog.position_reference`: "centre of gravity"
            or "rear axle"); empty for a time offset.
    """

    name: str
    value: float
    sigma: float
    prior_sigma: float
    observable: bool
    reference_point: str = ""

    @property
    def detected(self) -> bool:
        """Observable and more than :data:`DETECTION_SIGMAS` σ from zero: corrected."""
        return self.observable and abs(self.value) > DETECTION_SIGMAS * self.sigma

    @property
    def verdict(self) -> str:
        """``"detected, corrected"``, ``"consistent with 0"`` or ``"not observable"``."""
        if self.detected:
            return "detected, corrected"
        return "consistent with 0" if self.observable else "not observable"

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json`` (``value`` is what the log was corrected by;
        a lever arm's ``from`` names its reference point)."""
        return {
            "value": self.value if self.detected else 0.0,
            "estimate": self.value,
            "sigma": self.sigma,
            "observable": self.observable,
            "verdict": self.verdict,
            "prior_sigma": self.prior_sigma,
            **({"from": self.reference_point} if self.reference_point else {}),
        }


def measured_from(estimated: dict[str, SensorEstimate], point: str) -> dict[str, SensorEstimate]:
    """``estimated`` with each lever-arm component's reference ``point`` named."""
    return {
        name: dataclasses.replace(e, reference_point=point)
        if name in COMPONENTS["lever_arm"]
        else e
        for name, e in estimated.items()
    }


def component_names(variable: str, size: int) -> tuple[str, ...]:
    """The names of a nuisance variable's ``size`` components: the time offset of a log of
    several runs has one per run (``"time_offset:0"``, ``"time_offset:1"``, …)."""
    if variable == "time_offset" and size > 1:
        return tuple(f"time_offset:{run}" for run in range(size))
    return COMPONENTS[variable]


def run_of(name: str) -> tuple[str, int | None]:
    """``"time_offset:2"`` → ``("time_offset", 2)``; a name without a run → ``(name, None)``."""
    base, _, run = name.partition(":")
    return base, (int(run) if run else None)


def time_offsets(estimates: dict[str, SensorEstimate], runs: int) -> list[SensorEstimate | None]:
    """The wheel time offset of each of ``runs`` runs (``None`` where not estimated)."""
    return [estimates.get(name) for name in component_names("time_offset", runs)]


def detected_offsets(estimates: dict[str, SensorEstimate], runs: int) -> np.ndarray:
    """``(runs,)`` each run's detected time offset [s] (0 where none was detected)."""
    return np.array(
        [e.value if e is not None and e.detected else 0.0 for e in time_offsets(estimates, runs)]
    )


def sensor_estimates(
    nuisance: dict[str, NuisanceEstimate], max_sigma_ratio: float
) -> dict[str, SensorEstimate]:
    """One :class:`SensorEstimate` per component of the nuisance variables of a solve. A
    component whose estimate or σ is not a number (its information singular: the drive does
    not show it at all) is not observable, at its prior: no NaN goes on to correct the log
    or to set the batches' prior."""
    found = {}
    for variable, estimate in nuisance.items():
        observable = estimate.observable(max_sigma_ratio)
        for i, name in enumerate(component_names(variable, len(estimate.value))):
            value, sigma = float(estimate.value[i]), float(estimate.sigma[i])
            if not (np.isfinite(value) and np.isfinite(sigma)):
                found[name] = SensorEstimate(
                    name, 0.0, estimate.prior_sigma, estimate.prior_sigma, False
                )
                continue
            found[name] = SensorEstimate(
                name, value, sigma, estimate.prior_sigma, bool(observable[i])
            )
    return found


def not_estimated(left_out: dict[str, float]) -> dict[str, SensorEstimate]:
    """The components of nuisance variables left out of the graph because the drive cannot
    show them (name → prior sigma): not observable, at their prior (0)."""
    return {
        name: SensorEstimate(name, 0.0, sigma, sigma, False)
        for variable, sigma in left_out.items()
        for name in COMPONENTS[variable]
    }


def correct_log(
    log: DriveLog,
    estimates: dict[str, SensorEstimate],
    in_whole_samples: bool = False,
    move_antenna: bool = True,
) -> DriveLog:
    """``log`` with the detected estimates undone: wheels shifted by the time offset (rounded
    to whole samples with ``in_whole_samples``: the rest is then the graph's to model) and,
    with ``move_antenna``, positions moved from the antenna to the centre of gravity (along
    the measured heading: a graph that has the lever arm as a variable does better, with its
    predicted heading). A detected rear slip gain becomes the log's sideslip, ``−gain ·
    a_y`` (its position reference stays the rear axle)."""

    def value(name: str) -> float:
        e = estimates.get(name)
        return e.value if e is not None and e.detected else 0.0

    offset = detected_offsets(estimates, log.runs)
    if in_whole_samples:
        offset = np.array([whole_samples(o, log.dt) for o in offset])
    log = shift_wheel_rotations(log, offset)
    if value("rear_slip_gain") != 0.0:
        log = dataclasses.replace(log, beta=log.beta - value("rear_slip_gain") * log.ay)
    if not move_antenna:
        return log
    return move_to_centre(log, (value("lever_arm_longitudinal"), value("lever_arm_lateral")))


@dataclass(frozen=True)
class DownWeightedFixes:
    """Fixes the robust solve gave a weight below :data:`DOWN_WEIGHTED` (outliers).

    Attributes:
        rows: their rows in the log; times: their times [s]; weights: their weights.
        total: the fixes the solve used.
    """

    rows: np.ndarray
    times: np.ndarray
    weights: np.ndarray
    total: int

    @classmethod
    def from_solve(
        cls, data: SegmentData, weights: np.ndarray | None, times: np.ndarray
    ) -> DownWeightedFixes:
        """From a solve's per-segment ``weights`` ``(S, K+1)`` over ``data`` gathered from a
        log with sample ``times``."""
        fixes = data.position_fixes()
        if data.sample_index is None:
            return cls(np.zeros(0, int), np.zeros(0), np.zeros(0), int(fixes.sum()))
        fix_rows = np.zeros(len(times), bool)  # a fix two segments share counts once
        fix_rows[data.sample_index[fixes]] = True
        total = int(fix_rows.sum())
        if weights is None:
            return cls(np.zeros(0, int), np.zeros(0), np.zeros(0), total)
        per_row = log_weights(data, weights, len(times))
        rows = np.flatnonzero((per_row < DOWN_WEIGHTED) & fix_rows)
        return cls(rows, times[rows], per_row[rows], total)

    def summary(self) -> str:
        """One line: how many fixes were down-weighted, and when the first few were."""
        if not len(self.rows):
            return f"no fix down-weighted as an outlier (of {self.total})"
        shown = ", ".join(f"{t:.1f} s" for t in self.times[:5])
        more = f" and {len(self.rows) - 5} more" if len(self.rows) > 5 else ""
        return (
            f"{len(self.rows)} of {self.total} fixes down-weighted as outliers "
            f"(at {shown}{more}; calibration.json lists them)"
        )

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {
            "count": len(self.rows),
            "of": self.total,
            "times_s": self.times.tolist(),
            "weights": self.weights.tolist(),
        }


def log_weights(data: SegmentData, weights: np.ndarray, n_rows: int) -> np.ndarray:
    """Per log row ``(n_rows,)``: the smallest weight any segment gave that row's fix (1 for
    rows in no segment)."""
    per_row = np.ones(n_rows)
    index = data.sample_index[data.valid]
    np.minimum.at(per_row, index, weights[data.valid])
    return per_row
