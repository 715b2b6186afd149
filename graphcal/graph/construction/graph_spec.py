"""The shape of a segment graph: which variables, priors and weights it has
(:func:`graphcal.graph.construction.builder.build_segment_graph` builds it)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.factors import CONTINUITY_SIGMAS
from graphcal.graph.construction import keys
from graphcal.log.segments import SegmentData

#: Default correlation time [s] of the fixes' shared error (``[joint] fix_error_time``): the
#: residuals show only its drift rate, and a shorter time claims it averages out sooner than
#: a receiver's minute-long wander does (docs/method.md, "Fixes whose errors wander together").
FIX_ERROR_TIME = 60.0


@dataclass(frozen=True)
class CorrectionPrior:
    """The prior on wheel-rotation corrections ``[dn_rl, dn_rr]`` [rev] of every step.

    Attributes:
        sigma: zero-mean size sigma [rev] (the wheel noise; or a floor with ``relative``).
        relative: size sigma as a fraction of the measured rotation, at least ``sigma``
            (the paper's ±5 % input bound, softened); 0 for an absolute sigma.
        smoothness_sigma: sigma [rev] of the change of a corrected rotation from one step to
            the next (the paper's R = 1000 is 0.032 rev), or ``None`` for no smoothness term.
        quantization: sigma [rev] of the rounding error of each wheel's cumulative count
            (tick quantization, :func:`~graphcal.factors.chunk_correction_prior`), or 0.
    """

    sigma: float
    relative: float = 0.0
    smoothness_sigma: float | None = None
    quantization: float = 0.0

    def size_sigmas(self, measured: np.ndarray) -> np.ndarray:
        """Per step and wheel size sigmas ``(L, 2)`` [rev] for measured rotations ``(L, 2)``."""
        return np.maximum(self.relative * np.abs(np.asarray(measured, float)), self.sigma)


@dataclass(frozen=True)
class SegmentGraphSpec:
    """The shape of a segment graph (SI).

    Attributes:
        theta: theta's initial value, or its fixed value when ``estimate_theta`` is false.
        estimate_theta: theta is a variable (key :data:`~graphcal.graph.construction.keys.THETA`).
        theta_prior_sigmas: sigmas of a prior on theta at ``theta``, or ``None``.
        tracking_sigmas: ``[m, m, rad]`` of the tracking residuals.
        start_prior_sigmas: ``[m, m, rad]`` of the priors on free start poses (x and y
            equal), or ``None`` to hold each start at its measured pose.
        chunk_steps: steps per chunk factor; ``None`` for one chunk per segment.
        continuity_sigmas: ``[m, m, rad]`` of the chunk-boundary continuity.
        corrections: the corrections' prior, or ``None`` for no correction variables.
        slip_sigma: stationary sigma of a relative slip scale of each wheel per chunk (the
            rotation of wheel w becomes ``n_w · (1 + s_w)``; slow slip, a tyre's load), or
            ``None`` for none. The scales follow a first-order Gauss–Markov process with
            correlation time ``slip_time`` [s] from chunk to chunk.
        slip_time: that correlation time [s].
        time_offset_sigma: prior sigma [s] of the wheels' time offset (a variable,
            :data:`~graphcal.graph.construction.keys.TIME_OFFSET`, one element per run of the log),
            or ``None`` for none.
        time_offset_mean: that prior's mean [s] (and the variable's initial value): one for
            every run, or one per run.
        time_offset_runs: the runs the time offset has an element for (the log's; the
            builder sets it from the data, :meth:`for_runs`).
        lever_arm_sigma: prior sigma [m] of each component of the antenna's lever arm (a
            variable, :data:`~graphcal.graph.construction.keys.LEVER_ARM`), or ``None`` for none.
        heading_bias_sigma: prior sigma [rad] of a per-segment bias of the measured heading,
            or ``None`` for none.
        rear_slip_gain_sigma: prior sigma [rad per m/s²] of the rear tyres' slip gain, at
            zero (a variable, :data:`~graphcal.graph.construction.keys.REAR_SLIP_GAIN`: the
            rear axle of a log without a sideslip moves at ``−gain · a_y`` to the heading), or
            ``None`` for none.
        fix_error_sigma: stationary sigma [m] per axis of the error the fixes share over
            a chunk (a GNSS receiver's slowly varying error: one ``[east, north]`` 2-vector
            per chunk, a first-order Gauss–Markov process along each chain of tied segments,
            :mod:`graphcal.graph.construction.gauss_markov`), or ``None`` for white fix errors only.
        fix_error_time: that process's correlation time [s].
        tie_segments: a segment that starts where the one before it ends, in one continuous
            stretch of the log (:meth:`~graphcal.log.segments.SegmentData.tied`), starts at
            that segment's end pose (a continuity residual) instead of a free start under
            its measured pose: consecutive segments are one trajectory. Needs free starts.
    """

    theta: np.ndarray
    tracking_sigmas: np.ndarray
    estimate_theta: bool = True
    theta_prior_sigmas: np.ndarray | None = None
    start_prior_sigmas: np.ndarray | None = None
    chunk_steps: int | None = None
    continuity_sigmas: np.ndarray = field(default_factory=lambda: CONTINUITY_SIGMAS.copy())
    corrections: CorrectionPrior | None = None
    slip_sigma: float | None = None
    slip_time: float = 5.0
    time_offset_sigma: float | None = None
    time_offset_mean: float | tuple[float, ...] = 0.0
    time_offset_runs: int = 1
    lever_arm_sigma: float | None = None
    heading_bias_sigma: float | None = None
    rear_slip_gain_sigma: float | None = None
    fix_error_sigma: float | None = None
    fix_error_time: float = FIX_ERROR_TIME
    tie_segments: bool = False

    def for_runs(self, runs: int) -> SegmentGraphSpec:
        """This spec for a log of ``runs`` runs (one time offset element each)."""
        if runs == self.time_offset_runs:
            return self
        return dataclasses.replace(self, time_offset_runs=runs)

    def time_offset_means(self) -> np.ndarray:
        """``(time_offset_runs,)`` the time offset prior's mean per run [s]."""
        means = np.atleast_1d(np.asarray(self.time_offset_mean, float))
        if len(means) == 1:
            return np.full(self.time_offset_runs, float(means[0]))
        if len(means) != self.time_offset_runs:
            raise ValueError(
                f"time_offset_mean has {len(means)} values for {self.time_offset_runs} runs"
            )
        return means

    def held_start(self) -> SegmentGraphSpec:
        """The paper's Step 1 graph under this spec's theta, prior and tracking sigmas: each
        segment one chunk from its measured start (held), no wheel corrections, no sensor
        terms (slip, time offset, lever arm, heading bias, rear slip gain, shared fix error),
        no ties."""
        return dataclasses.replace(
            self,
            start_prior_sigmas=None,
            corrections=None,
            chunk_steps=None,
            tie_segments=False,
            slip_sigma=None,
            time_offset_sigma=None,
            lever_arm_sigma=None,
            heading_bias_sigma=None,
            rear_slip_gain_sigma=None,
            fix_error_sigma=None,
        )

    def tied(self, data: SegmentData) -> np.ndarray:
        """``(S,)`` which segments of ``data`` start at the end of the one before in this
        graph (``tie_segments`` with free starts;
        :meth:`~graphcal.log.segments.SegmentData.tied`)."""
        if not self.tie_segments or self.start_prior_sigmas is None:
            return np.zeros(len(data), bool)
        return data.tied()

    def nuisance_keys(self) -> dict[str, int]:
        """Graph-wide variables besides theta, by name: ``"time_offset"``, ``"lever_arm"``,
        ``"rear_slip_gain"``."""
        found = {}
        if self.time_offset_sigma is not None:
            found["time_offset"] = keys.TIME_OFFSET
        if self.lever_arm_sigma is not None:
            found["lever_arm"] = keys.LEVER_ARM
        if self.rear_slip_gain_sigma is not None:
            found["rear_slip_gain"] = keys.REAR_SLIP_GAIN
        return found


def shared_keys(spec: SegmentGraphSpec) -> list[int]:
    """The variables every segment of ``spec``'s graph shares: theta (if estimated), then
    the time offset and the lever arm (if present)."""
    found = [keys.THETA] if spec.estimate_theta else []
    return [*found, *spec.nuisance_keys().values()]
