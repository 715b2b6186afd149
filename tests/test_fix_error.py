"""The error GNSS fixes share over tens of seconds (issue 43): measured from the residuals'
variogram (graphcal.pipeline.solvers.residual_noise), modelled as a Gauss–Markov state at each
chunk boundary (graphcal.graph.construction.chunk_processes), and the σ it gives judged against the
truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.factors import pose_sigmas
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import CorrectionPrior, SegmentGraphSpec
from graphcal.graph.optimization.solve_options import SolveOutcome, SolveStatus
from graphcal.log.segments import gather_segments, split_segments
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.methods.noise_levels import slow_fix_error, with_residual_noise
from graphcal.pipeline.solvers.joint_settings import JointSettings, without_defect_model
from graphcal.pipeline.solvers.residual_noise import ResidualNoise, drift_fit, error_variogram
from graphcal.simulate.defect_effects import gauss_markov
from graphcal.simulate.drive import simulate_drive

DT = 0.025


@pytest.fixture(scope="module")
def segments():
    drive = simulate_drive(2.0, seed=5)
    data = gather_segments(drive.measured, split_segments(drive.measured, 150.0))
    return data


def _residuals(data, error: np.ndarray) -> np.ndarray:
    """``(S, K+1, 2)`` residuals that are ``error (N, 2)`` at each segment sample."""
    return error[data.sample_index]


def test_the_variogram_slope_over_short_lags_is_the_drift_rate(segments):
    # 1 m over 30 s drifts at q²/τ = 0.033 m²/s; 0.2 m white noise is the intercept.
    rng = np.random.default_rng(1)
    n = int(segments.sample_index.max()) + 1
    error = gauss_markov(n, DT, 1.0, 30.0, rng, 2) + 0.2 * rng.standard_normal((n, 2))
    used = segments.position_fixes()
    white, rate, interval = drift_fit(*error_variogram(_residuals(segments, error), used, segments))
    assert white == pytest.approx(0.2, rel=0.15)
    assert rate == pytest.approx(1.0 / 30.0, rel=0.35)
    assert interval == pytest.approx(DT)


def test_white_errors_have_no_drift(segments):
    rng = np.random.default_rng(2)
    n = int(segments.sample_index.max()) + 1
    error = 0.5 * rng.standard_normal((n, 2))
    white, rate, _ = drift_fit(
        *error_variogram(_residuals(segments, error), segments.position_fixes(), segments)
    )
    assert white == pytest.approx(0.5, rel=0.05)
    assert rate < 0.01 * 0.25  # below a hundredth of the white variance per second


def test_the_variogram_along_the_travel_is_the_differences_component_along_it(segments):
    # Brute force over every pair of fixes of each chain: ½ mean of (u(t) · Δr)² per lag.
    rng = np.random.default_rng(3)
    residuals = rng.standard_normal(segments.poses.shape[:2] + (2,))
    angle = rng.uniform(0.0, 2.0 * np.pi, segments.poses.shape[:2])
    directions = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    used = segments.position_fixes() & (rng.random(angle.shape) < 0.3)
    lags, gamma, pairs = error_variogram(residuals, used, segments, directions=directions)
    tied = segments.tied()
    chain = np.cumsum(~tied) - 1
    rows, cols = np.nonzero(used)
    t = segments.sample_index[rows, cols]
    sums: dict[int, list[float]] = {}
    for c in np.unique(chain):
        mine = chain[rows] == c
        r, u, tt = residuals[rows[mine], cols[mine]], directions[rows[mine], cols[mine]], t[mine]
        lag = tt[None, :] - tt[:, None]
        first, second = np.nonzero(lag > 0)
        along = np.einsum("ij,ij->i", u[first], r[second] - r[first])
        for k, value in zip(lag[first, second], along**2, strict=True):
            sums.setdefault(int(k), []).append(float(value))
    for lag_s, g, n in zip(lags[:50], gamma[:50], pairs[:50], strict=True):
        found = sums[round(lag_s / segments.dt)]
        assert n == len(found)
        assert g == pytest.approx(0.5 * np.mean(found), rel=1e-9)


@pytest.mark.parametrize("directed", [False, True])
def test_the_variogram_over_chains_of_every_length_is_every_pairs(segments, directed):
    """Chains of 1 to 7 segments (their transforms of different sizes): at every lag, the
    pairs of fixes within a chain and half their mean squared difference (along the
    direction at the first with ``directed``), counted pair by pair."""
    rng = np.random.default_rng(4)
    residuals = rng.standard_normal(segments.poses.shape[:2] + (2,))
    angle = rng.uniform(0.0, 2.0 * np.pi, segments.poses.shape[:2])
    directions = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    used = segments.position_fixes() & (rng.random(angle.shape) < 0.3)
    tied = np.array([0, 0, 1, 0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1], bool)  # chains of 1, 2, 4, 7
    lags, gamma, pairs = error_variogram(
        residuals, used, segments, tied, directions if directed else None
    )
    chain = np.cumsum(~tied) - 1
    rows, cols = np.nonzero(used)
    t = segments.sample_index[rows, cols]
    counts, sums = np.zeros(t.max() + 1), np.zeros(t.max() + 1)
    for c in np.unique(chain):
        mine = chain[rows] == c
        r, u, tt = residuals[rows[mine], cols[mine]], directions[rows[mine], cols[mine]], t[mine]
        first, second = np.nonzero(tt[None, :] > tt[:, None])
        lag = tt[second] - tt[first]
        if directed:
            squares = np.einsum("ij,ij->i", u[first], r[second] - r[first]) ** 2
        else:
            squares = ((r[second] - r[first]) ** 2).mean(axis=1)  # per component
        counts += np.bincount(lag, minlength=len(counts))
        sums += np.bincount(lag, squares, minlength=len(sums))
    steps = np.rint(lags / segments.dt).astype(int)
    assert np.array_equal(steps, np.flatnonzero(counts))  # every lag with a pair, no other
    assert np.array_equal(pairs, counts[steps])
    assert np.allclose(gamma, 0.5 * sums[steps] / counts[steps], rtol=1e-9)


def test_along_the_travel_a_slow_error_drifts_at_its_own_rate(segments):
    # The same Gauss–Markov error as above, its rate read from the component along the track.
    from graphcal.pipeline.solvers.residual_noise import travel_directions

    rng = np.random.default_rng(1)
    n = int(segments.sample_index.max()) + 1
    error = gauss_markov(n, DT, 1.0, 30.0, rng, 2) + 0.2 * rng.standard_normal((n, 2))
    directions, fast = travel_directions(segments)
    assert np.allclose(np.linalg.norm(directions, axis=-1), 1.0)
    assert fast[segments.valid].mean() > 0.9  # a car's drive
    white, rate, _ = drift_fit(
        *error_variogram(
            _residuals(segments, error), segments.position_fixes(), segments,
            directions=directions,
        )
    )  # fmt: skip
    assert white == pytest.approx(0.2, rel=0.15)
    assert rate == pytest.approx(1.0 / 30.0, rel=0.35)


def _noise(**fields) -> ResidualNoise:
    lags = np.array([0.025, 0.5, 1.0, 2.0])
    base = dict(
        position=0.3,
        position_correlation=20.0,
        position_white=0.2,
        position_drift=1.0 / 30.0,
        fix_interval=0.025,
        position_variogram=(lags, 0.04 + lags / 30.0),
    )
    return ResidualNoise(**{**base, **fields})


def test_a_drift_is_modelled_with_the_settings_correlation_time():
    white, shared, time = slow_fix_error(_noise(), JointSettings(), DT)
    assert time == JointSettings().fix_error_time == 60.0
    assert shared == pytest.approx(np.sqrt(60.0 / 30.0))  # √(rate · τ)
    # the white part keeps what the error does within half a chunk (0.625 s), the share of it
    # beyond white noise (γ there less 0.04) once for the 25 fixes of that half chunk
    assert white == pytest.approx(np.sqrt(0.04 + 25 * 0.625 / 30.0))
    # fixes one per half chunk or fewer: each its own share
    sparse = _noise(fix_interval=1.0)
    white, _, _ = slow_fix_error(sparse, JointSettings(), DT)
    assert white == pytest.approx(np.sqrt(0.04 + 0.625 / 30.0))


def test_white_or_declared_or_switched_off_errors_model_no_drift():
    assert slow_fix_error(_noise(position_correlation=1.2), JointSettings(), DT) is None
    assert slow_fix_error(_noise(), JointSettings(fix_error_sigma=1.5), DT) is None
    assert slow_fix_error(_noise(), without_defect_model(JointSettings()), DT) is None


def test_residuals_of_a_solve_that_stopped_creeping_weight_the_fixes_white_at_their_rms():
    # Residuals alike from fix to fix: from a converged solve, an error the fixes share;
    # from one that stopped creeping short of its minimum, its own unfinished fit — white.
    profile = JointSettings(position_sigma=0.05)
    converged = with_residual_noise(_noise(), profile, False, DT)
    assert converged.fix_error_sigma == pytest.approx(np.sqrt(60.0 / 30.0))  # √(rate · τ)
    crept = with_residual_noise(_noise(), profile, False, DT, converged=False)
    assert crept.fix_error_sigma == 0.0
    assert pose_sigmas(crept.pose_weights, crept.position_sigma)[0] == pytest.approx(0.3)


def test_fixes_too_few_to_measure_are_weighted_as_white_and_shared_noise_never_lighter():
    # 25 fixes at 0.1 m RMS under the profile's 0.2 m: too few to tell white from shared; the
    # RMS of a fit of few fixes is no floor below the settings' (it took their error in).
    few = ResidualNoise(few_fixes=(25, 0.1))
    settings = with_residual_noise(few, JointSettings(position_sigma=0.2), False, DT)
    assert settings.position_sigma == pytest.approx(0.2)
    assert settings.fix_error_sigma == pytest.approx(0.2)
    assert settings.fix_error_time == JointSettings().fix_error_time
    noisier = with_residual_noise(ResidualNoise(few_fixes=(29, 0.47)), JointSettings(), False, DT)
    assert noisier.position_sigma == pytest.approx(0.47)
    assert noisier.fix_error_sigma == pytest.approx(0.47)
    # a shared error the user declared, or switched off, is theirs
    declared = JointSettings(fix_error_sigma=0.5)
    assert with_residual_noise(few, declared, False, DT).fix_error_sigma == 0.5
    off = with_residual_noise(few, JointSettings(fix_error="off"), False, DT)
    assert off.fix_error_sigma == 0.0


def test_the_fix_error_chain_goes_on_across_tied_segments(segments):
    # Tied segments are one trajectory: the fixes' error at the end of one segment is the
    # error at the start of the next (one variable), and only the first gets a stationary
    # prior.
    spec = SegmentGraphSpec(
        theta=np.array([2.0, 0.0, 1.55, 0.0]),
        tracking_sigmas=np.array([0.2, 0.2, 0.03]),
        start_prior_sigmas=np.array([0.2, 0.2, 0.03]),
        chunk_steps=50,
        corrections=CorrectionPrior(sigma=5e-4),
        fix_error_sigma=1.0,
        fix_error_time=30.0,
        tie_segments=True,
    )
    data = segments.take(np.arange(3))
    built = build_segment_graph(data, spec)
    letters = [chr(k >> 56) for k in built.values.keys()]
    n_chunks = [len(b) - 1 for b in built.bounds]
    assert data.tied()[1:].all()
    assert letters.count("e") == sum(n_chunks) + 1  # one per boundary, shared where tied


@pytest.mark.slow
def test_fixes_wandering_together_give_honest_sigmas(caplog):
    """A 4 km drive whose fixes wander by 1 m over 30 s (seed 7): weighted as inflated white
    noise c_e came out +4.2σ off, "calibrated"; with the shared error modelled it is within
    2σ, and c_d, t_r, d keep their σ (0.08 mm, 4.5 mm, 0.05 mm·s²/m)."""
    drive = simulate_drive(4.0, seed=7)
    log = drive.measured
    error = gauss_markov(len(log.t), log.dt, 1.0, 30.0, np.random.default_rng([7, 99]), 2)
    log = dataclasses.replace(log, px=log.px + error[:, 0], py=log.py + error[:, 1])
    with caplog.at_level("INFO", logger="graphcal.progress"):
        run = run_calibration(log, Settings(), "joint", workers=1)
    assert "modelled as an error they share" in caplog.text
    sigma = np.sqrt(np.diag(run.covariance))
    errors = (run.theta - drive.theta_true) / sigma
    assert np.all(np.abs(errors) < 3.0), errors
    assert run.observability.calibrated.all()


def test_a_declared_shared_error_leaves_the_white_part_uninflated():
    # With the receiver's shared error given, the residuals are those of the fixes less it:
    # their RMS is the white part, not to be inflated for a correlation the graph models.
    from types import SimpleNamespace

    from graphcal.pipeline.methods.noise_levels import with_noise_levels

    declared = JointSettings(fix_error_sigma=1.0, position_sigma=0.05)
    converged = SolveOutcome(SolveStatus.CONVERGED, 5, 50)
    whole = SimpleNamespace(
        noise=_noise(position=0.3, position_correlation=20.0), outcome=converged
    )
    out = with_noise_levels(whole, declared, has_heading=False, dt=DT)
    assert out.position_sigma == pytest.approx(0.3)
    assert out.fix_error_sigma == 1.0


def test_fix_residuals_with_each_trajectorys_start_fitted_read_the_noise_unbiased():
    """Fixes of white noise σ on trajectories whose start pose (x, y, heading) is fitted to
    them: the residuals' RMS, corrected for the fitted starts, reads σ (without the
    correction, 4 fixes per trajectory read 0.79 σ); a one-fix trajectory takes its fix's
    two coordinates and leaves nothing."""
    from graphcal.pipeline.solvers.residual_noise import fitted_start_correction

    rng = np.random.default_rng(7)
    sigma, draws = 0.7, 4000
    fixes_per_trajectory = np.array([4, 9, 1])
    squares, coordinates = 0.0, 0
    for n in fixes_per_trajectory:
        angle = np.linspace(0.0, 1.2, n)
        path = 20.0 * np.column_stack([np.sin(angle), 1.0 - np.cos(angle)])
        # small rigid moves are linear in (x, y, heading): x + ψ·(−p_y), y + ψ·p_x
        jacobian = np.zeros((2 * n, 3))
        jacobian[0::2, 0], jacobian[1::2, 1] = 1.0, 1.0
        jacobian[0::2, 2], jacobian[1::2, 2] = -path[:, 1], path[:, 0]
        noise = sigma * rng.standard_normal((draws, 2 * n))
        fitted, *_ = np.linalg.lstsq(jacobian, noise.T, rcond=None)
        squares += float(np.sum((noise.T - jacobian @ fitted) ** 2))
        coordinates += 2 * n * draws
    rms = np.sqrt(squares / coordinates)
    used = np.zeros((3, 10), bool)
    for row, n in enumerate(fixes_per_trajectory):
        used[row, :n] = True
    correction = fitted_start_correction(used, np.zeros(3, bool))
    assert rms * correction == pytest.approx(sigma, rel=0.01)
    assert rms < 0.9 * sigma
    # tied segments are one trajectory: one start fitted for the three
    assert fitted_start_correction(used, np.array([False, True, True])) == pytest.approx(
        np.sqrt(28 / 25)
    )
