"""The noise a whole-log solve's residuals show, made the settings of the next solve: the
fixes' white sigma and, when their errors wander together, the error they share (a
Gauss–Markov state, :mod:`graphcal.graph.construction.gauss_markov`); the heading's sigma; the
wheels' noise (:mod:`graphcal.pipeline.solvers.residual_noise` measures them)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from graphcal.factors import pose_sigmas
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.residual_noise import CORRELATED_ERRORS, ResidualNoise, honest_sigma
from graphcal.progress import muted, say

#: The fixes' noise from the solve replaces the settings' when they differ by more than this
#: share (a variance component; one more solve): at most √1.5 − 1, so that noise left as
#: found never fails the trust check's χ²/dof ≤ 1.5 (at 0.25, a car's 1.10 m white fixes
#: weighted as 0.887 m were left so, χ²/dof 1.58, "not trusted").
POSITION_NOISE_TOLERANCE = 0.2
#: The fixes' white sigma stays at least this share of their residuals' RMS when a shared
#: error explains the rest (the tracking residuals never near-hard).
MIN_WHITE_SHARE = 0.1
#: Fixes found this many times as noisy as the settings weighted them (or less than its
#: inverse) were fitted under far wrong weights: the heading residuals and the wheel
#: corrections of that solve show the misfit, not their own noise, and are judged after
#: the solve under the fixes' own noise (:func:`fixes_reweighted`). A delivery robot's fixes
#: sharing 1.1 m of error, weighted as the profile's RTK 0.05 m, put its wheel corrections
#: at χ² 5.8 per row: wheel noise ×2.4 of their true 0.00063 rev.
REWEIGHTED = 3.0


def with_noise_levels(
    whole: JointCalibration,
    settings: JointSettings,
    has_heading: bool,
    dt: float,
    fixes: bool = True,
) -> JointSettings:
    """``settings`` with the noise the whole-log solve's residuals show
    (:class:`~graphcal.pipeline.solvers.residual_noise.ResidualNoise`; ``dt`` the log's sample
    interval [s]), else ``settings`` itself:

    * the fixes' position sigma (their RMS, inflated when their errors are correlated:
      :func:`~graphcal.pipeline.solvers.residual_noise.honest_sigma`) when it differs from the
      settings' by more than :data:`POSITION_NOISE_TOLERANCE` — or, when their errors wander
      together, the white part of it and the error they share (:func:`slow_fix_error`);
    * the heading's sigma (the RMS of its residuals, not inflated for their correlation: a
      heading that drifts from the model's over seconds is a defect, the heading biases'
      or the model check's, not noise to weigh away) and the wheel noise when the residuals
      show them larger by more than that share — only larger: a heading's white noise
      (from the log) and a profile's wheel noise are floors, and data that determine the
      corrections only in part show a χ² below 1 however right the wheel noise is.

    A real robot with motion capture (a profile's 0.0002 rev, the heading's 0.09° white
    noise) showed corrections at χ² 4 per row and heading residuals of 0.2°: χ²/dof 5.

    ``fixes`` false: the fixes' noise stays the settings' where they share a modelled error
    (:func:`fixes_reweighted`).

    A solve that stopped creeping under too tight weights
    (:attr:`~graphcal.graph.optimization.solve_options.SolveStatus.MISWEIGHTED`) left
    residuals that carry its own unfinished fit, alike from fix to fix: the fixes are
    weighted white at their RMS, and whether they share an error is read after the solve
    under it (a robot's 1.7 m white fixes read from such residuals as 4.5 m shared and
    1.8 m white: the solve under that was indeterminate, exit 2).
    """
    converged = not whole.outcome.crept
    return with_residual_noise(whole.noise, settings, has_heading, dt, fixes, converged)


def noise_levels_change(
    settings: JointSettings, has_heading: bool, dt: float
) -> Callable[[ResidualNoise], bool]:
    """Whether a solve's residual ``noise`` would change ``settings``' noise levels
    (:func:`with_noise_levels`, its lines unsaid): then that solve is solved again under
    them, and its robust rounds and slip screen can stop at its first round
    (:func:`~graphcal.pipeline.solvers.joint.solve_joint`'s ``stop_if``)."""

    def changes(noise: ResidualNoise) -> bool:
        with muted():
            return with_residual_noise(noise, settings, has_heading, dt) is not settings

    return changes


def with_residual_noise(
    noise: ResidualNoise,
    settings: JointSettings,
    has_heading: bool,
    dt: float,
    fixes: bool = True,
    converged: bool = True,
) -> JointSettings:
    """:func:`with_noise_levels` of a solve's residual ``noise`` (``converged`` false: of a
    solve that stopped creeping, the fixes white at their RMS)."""
    x, y, _ = settings.pose_weights
    sigmas = pose_sigmas(settings.pose_weights, settings.position_sigma)
    position, heading, wheel = float(sigmas[0]), float(sigmas[2]), settings.wheel_noise
    fixes = fixes or settings.fix_error_sigma == 0.0  # white fixes: their RMS is theirs
    converged = converged and not noise.unfinished
    correlated = fixes and converged  # an unfinished fit's residuals are alike by themselves
    drift = slow_fix_error(noise, settings, dt) if correlated else None
    found = honest_sigma(noise.position, noise.position_correlation) if correlated else None
    if fixes and not converged:
        found = noise.position
    few = few_fixes_error(noise, settings, position) if correlated else None
    if few is not None:
        drift = few
    if drift is not None:
        found = drift[0]
    elif fixes and settings.fix_error != "off" and settings.fix_error_sigma > 0:
        found = noise.position  # the shared error is the settings' and in the graph: white
    if found is not None:
        if few is None:  # (few_fixes_error said its own)
            _say_position_noise(noise, found, drift)
        if drift is not None or abs(found / position - 1.0) > POSITION_NOISE_TOLERANCE:
            if drift is None:
                say(f"  not the {position:g} m the settings assume: solved again with it")
            position = found
    slow = {} if drift is None else {"fix_error_sigma": drift[1], "fix_error_time": drift[2]}
    if fixes_reweighted(
        settings, dataclasses.replace(settings, position_sigma=position * np.sqrt(x), **slow)
    ):
        say("  the heading's and the wheels' noise judged after a solve under the fixes' own")
        has_heading, chi2 = False, None  # a misfit of far wrong fix weights, not their noise
    elif not converged:  # an unfinished fit's misfit (a start far off), not their noise
        has_heading, chi2 = False, None
    else:
        chi2 = noise.wheel_chi2
    found = noise.heading  # white: a correlated misfit of the heading is a defect, not noise
    if has_heading and found is not None and found > heading * (1 + POSITION_NOISE_TOLERANCE):
        say(
            f"heading residuals {np.degrees(found):.3g}° RMS, not the {np.degrees(heading):.3g}° "
            "assumed: solved again with them"
        )
        heading = found
    if chi2 is not None and np.sqrt(chi2) > 1 + POSITION_NOISE_TOLERANCE:
        wheel = float(settings.wheel_noise * np.sqrt(chi2))
        say(
            f"wheel corrections at χ² {chi2:.2f} per row: wheel noise {wheel:.3g} rev per "
            f"step, not the {settings.wheel_noise:g} assumed: solved again with it"
        )
    if drift is None and (position, heading, wheel) == (
        float(sigmas[0]),
        float(sigmas[2]),
        settings.wheel_noise,
    ):
        return settings
    weight = float(f"{(position / heading) ** 2:.6g}")
    return dataclasses.replace(
        settings,
        position_sigma=position * np.sqrt(x),
        pose_weights=(x, y, weight),
        wheel_noise=wheel,
        **slow,
    )


def _say_position_noise(
    noise: ResidualNoise, found: float, drift: tuple[float, float, float] | None
) -> None:
    """The fixes' noise the residuals show, and how it is weighted: ``found`` [m] per axis,
    white, with the error they share (``drift``: white, shared [m], time [s]) if any."""
    say(f"position noise {noise.position:#.3g} m per axis (the fixes' residuals)")
    alike = (
        f"  the fixes' errors are alike from fix to fix (a mean of many varies "
        f"{noise.position_correlation:.1f}× as much as white noise's): "
    )
    if drift is not None:
        say(
            f"{alike}{drift[1]:#.2g} m of it modelled as an error they share, correlated "
            f"over {drift[2]:.0f} s, {found:#.2g} m white"
        )
    elif found != noise.position:
        say(f"{alike}weighted as {found:#.3g} m")


def _fix_sigma(white: float, shared: float) -> float:
    """The fixes' whole sigma [m] per axis: white and shared error together."""
    return float(np.hypot(white, shared))


def fixes_reweighted(before: JointSettings, after: JointSettings) -> bool:
    """Whether ``after`` weights the fixes :data:`REWEIGHTED` times away from ``before``
    (their white and shared sigma together): the solve under ``before`` fitted them under far
    wrong weights; its values are no start, nor its residuals a judge of the other noise.
    The next solve's judge the heading and the wheels, not the fixes again: once a shared
    error is modelled, the residuals' RMS is not the white part (what the fixes share within
    a chunk stays in it): taken as white, 0.035 m at 40 Hz against the 0.052 m of the first
    solve's variogram, a delivery robot's segment groups scattered 2.1–2.3× beyond their σ
    of c_e and t_r."""
    old = _fix_sigma(
        float(pose_sigmas(before.pose_weights, before.position_sigma)[0]), before.fix_error_sigma
    )
    new = _fix_sigma(
        float(pose_sigmas(after.pose_weights, after.position_sigma)[0]), after.fix_error_sigma
    )
    return not 1.0 / REWEIGHTED <= new / old <= REWEIGHTED


def few_fixes_error(
    noise: ResidualNoise, settings: JointSettings, position: float
) -> tuple[float, float, float] | None:
    """``(white, shared, time)`` [m, m, s] for fixes too few to measure their noise
    (:attr:`~graphcal.pipeline.solvers.residual_noise.ResidualNoise.few_fixes`) where the
    settings leave the shared error to the residuals; else ``None``. Too few to tell white
    noise from an error they share, they are weighted as both: white at their RMS, never
    below the ``position`` [m] the settings assume (a fit of few fixes takes part of their
    error into its start poses), and a shared error as large over ``fix_error_time``. A car's
    25 fixes at 0.5 Hz over 54 s of straight road, sharing 0.34 m over 19 s, weighted as the
    profile's white 0.2 m: c_e 3.9σ off "calibrated"."""
    if noise.few_fixes is None or settings.fix_error != "auto" or settings.fix_error_sigma > 0:
        return None
    count, rms = noise.few_fixes
    white = max(rms, position)
    say(
        f"position noise {rms:#.3g} m per axis from only {count} fixes: too few to tell white "
        f"noise from an error they share, weighted as {white:#.2g} m of each (the shared "
        f"correlated over {settings.fix_error_time:.0f} s)"
    )
    return float(white), float(white), float(settings.fix_error_time)


def slow_fix_error(
    noise: ResidualNoise, settings: JointSettings, dt: float
) -> tuple[float, float, float] | None:
    """``(white, shared, time)``: the fixes' white sigma [m], and the stationary sigma [m]
    and correlation time [s] of the error they share, when their errors are alike from fix
    to fix (:data:`~graphcal.pipeline.solvers.residual_noise.CORRELATED_ERRORS`) and the settings
    leave it to the residuals (``fix_error`` auto, ``fix_error_sigma`` 0); else ``None``. ``dt``:
    the log's sample interval [s].

    A fit's residuals show a slow error only over short lags (its trajectory bends with the
    rest): their variogram's slope there is the error's drift rate ``q² / τ``
    (:func:`~graphcal.pipeline.solvers.residual_noise.drift_fit`), and τ is the settings'
    ``fix_error_time`` (consumer GNSS errors wander over tens of seconds to minutes), so that
    ``q = √(rate · τ)``. A τ shorter than the error's claims the error averages out sooner
    than it does: a skid-steer robot's fixes sharing 1.2 m over 59 s, read with 30 s as
    0.83 m, left c_e and t_r "calibrated" 2.3σ and 1.9σ off on average (mean (e/σ)² 6.9 and
    5.0 over 10 recording seeds); with 60 s, 1.2 m, and both rightly not calibrated.
    Within a chunk the fixes are weighted white at ``√(w² + n · (γ(h) − w²))``: ``w`` the
    variogram's white part, ``γ(h)`` the variogram at half a chunk ``h``, ``n`` the fixes in
    ``h`` (the variance of their mean is the white part's over n plus the part they share
    whole). Weighted at ``√γ(h)`` as though each fix's share were its own, 50 Hz fixes sharing
    0.74 m over 35 s on a 250 m yard drive left t_r at mean (e/σ)² 2.86 over 16 recording
    seeds (0.85 now; 1 Hz fixes, one per half chunk or fewer, are weighted as before).
    Weighted as white noise of an inflated sigma instead, fixes whose
    errors wander together over a minute left c_e 5.2σ off "calibrated" on a straight road
    (1.8 m, 53 s), and 2.9–5.1σ on 2 of 8 seeds of a 4 km town drive (1 m, 30 s)."""
    if settings.fix_error != "auto" or settings.fix_error_sigma > 0:
        return None
    if noise.position_drift is None or noise.position is None:
        return None
    if (noise.position_correlation or 1.0) < CORRELATED_ERRORS or noise.position_drift <= 0:
        return None
    time, rate = settings.fix_error_time, noise.position_drift
    # The chunks' error is linear between their ends: what the fixes' error does within half
    # a chunk (their variogram there: white noise, the drift, errors alike over less than a
    # chunk) stays with the white noise — but only the variogram's white part is white: the
    # rest the fixes of half a chunk share, and n of them carry its information once.
    lags, gamma = noise.position_variogram
    half = settings.chunk_steps * dt / 2.0
    white2 = noise.position_white**2
    alike = max(float(np.interp(half, lags, gamma)) - white2, 0.0)
    sharing = max(half / float(noise.fix_interval or dt), 1.0)  # fixes in half a chunk
    white = max(np.sqrt(white2 + sharing * alike), MIN_WHITE_SHARE * noise.position)
    return float(white), float(np.sqrt(rate * time)), float(time)
