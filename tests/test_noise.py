"""The heading's white noise read from the log (graphcal.log.noise), on uniform and on
sparse logs: what sets the heading's weight, so an overstated noise biases t_r and d; the
wheel rates' white noise, what the wheel-rotation corrections are weighted by; the fixes'
white noise, what a first solve weights fixes far noisier than the settings assume by."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.log.noise import MIN_FIX_TRIPLES, heading_noise, position_noise, rate_wheel_noise
from graphcal.log.quantization import quantization_sigma
from graphcal.model import THETA_NOMINAL
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import NoiseLevels, simulate_drive

WHITE = np.deg2rad(0.3)  # the heading_bias defect's white noise


@pytest.fixture(scope="module")
def counted():
    """6 km with a 0.3° fused heading (and its slow bias), 96-tick wheels, 10 Hz fixes."""
    drive = simulate_drive(6.0, seed=3)
    return degrade(drive, parse_defects("gnss10hz,heading_bias,ticks"), 3).measured


def test_a_uniform_logs_heading_noise_is_its_white_noise():
    drive = simulate_drive(6.0, seed=3)
    log = degrade(drive, parse_defects("heading_bias"), 3).measured
    assert heading_noise(log) == pytest.approx(WHITE, rel=0.1)


def test_sparse_headings_between_rows_of_fixes(counted):
    """Headings at most rows (not at a fix between rows): runs of consecutive rows."""
    assert counted.sparse
    assert heading_noise(counted, THETA_NOMINAL) == pytest.approx(WHITE, rel=0.1)


def _headings_every(log, rows: int):
    """``log`` with its heading kept at every ``rows``-th row only, midway between fixes."""
    measured = log.measured.copy()
    phase = (np.flatnonzero(measured[:, 0])[0] + 2) % rows
    measured[np.arange(len(measured)) % rows != phase, 1] = False
    return dataclasses.replace(log, measured=measured)


def test_headings_at_10_hz_are_measured_on_their_own(counted):
    """10 Hz headings: their own second differences (the motion over 0.1 s is far below
    0.3°), whatever the wheels' ticks."""
    log = _headings_every(counted, 4)
    assert heading_noise(log, THETA_NOMINAL) == pytest.approx(WHITE, rel=0.1)


def test_headings_at_1_hz_discount_the_wheels_tick_rounding():
    """1 Hz headings: measured against the wheels' yaw (nominal theta), whose 96-tick
    rounding adds about 0.3° to each second difference. The discount takes the rounding out
    without understating the noise (an understated heading noise overweights the heading:
    0.11–0.15° for 0.3° put t_r 6–23σ off); what remains over 1 s is the nominal yaw's own
    error (t_r, the load transfer), an overstatement (0.42° here)."""
    defects = dataclasses.replace(parse_defects("gnss10hz,ticks"), heading_white=WHITE)
    log = _headings_every(degrade(simulate_drive(6.0, seed=3), defects, 3).measured, 40)
    rounding = quantization_sigma(96)
    discounted = heading_noise(log, THETA_NOMINAL, 0.0005, rounding)
    assert 0.95 * WHITE < discounted < heading_noise(log, THETA_NOMINAL)


@pytest.mark.slow
def test_position_noise_is_read_from_the_solve_and_used():
    """Fixes noisier than the settings assume (0.6 m against 0.2 m): the whole-log solve's
    residuals give the fixes' own noise, the log is solved again with it, and the σ is
    honest (χ²/dof about 1, the truth within 3σ)."""
    from graphcal.pipeline.end_to_end.run import run_calibration
    from graphcal.simulate.drive import NoiseLevels

    drive = simulate_drive(6.0, seed=4, noise=NoiseLevels(position=0.6))
    run = run_calibration(drive.measured, method="whole", workers=1)
    assert run.whole.position_noise == pytest.approx(0.6, rel=0.1)
    assert run.settings.joint.position_sigma == pytest.approx(0.6, rel=0.1)
    assert run.whole.chi2_per_dof == pytest.approx(1.0, abs=0.1)
    sigma = np.sqrt(np.diag(run.covariance))
    assert np.all(np.abs(run.theta - drive.theta_true) < 3 * sigma)
    from graphcal.report.document import results_document

    noise = results_document(run)["noise"]  # reported with the result
    assert noise["position_sigma_m"] == pytest.approx(0.6, rel=0.1)
    assert noise["heading_sigma_deg"] == pytest.approx(1.5, rel=0.15)  # the drive's heading


def _wheel_rates(rate_hz: float, sigma: float, seed: int = 0):
    """Two wheels' rates [rev/s] at ``rate_hz`` over 200 s: a drive of accelerations,
    cruises and two stops (rates exactly 0) plus white noise of ``sigma`` [rev/s] while
    moving."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 200.0, 1.0 / rate_hz)
    true = 2.0 + 1.5 * np.sin(0.2 * t) + 0.3 * np.sin(1.3 * t)
    true[(t > 50) & (t < 60)] = 0.0
    true[(t > 150) & (t < 155)] = 0.0
    moving = true != 0.0
    left = np.where(moving, true + sigma * rng.standard_normal(len(t)), 0.0)
    right = np.where(moving, 1.01 * true + sigma * rng.standard_normal(len(t)), 0.0)
    return t, left, right


@pytest.mark.parametrize("rate_hz, step", [(100.0, 0.025), (50.0, 0.025), (20.0, 0.05)])
def test_wheel_rates_white_noise_is_the_random_walk_per_log_step(rate_hz, step):
    """White rate noise σ [rev/s] at Δt: a log step's rotation errs by σ √(Δt · step), the
    rate at which the summed rotations' error grows, whatever the two rates."""
    sigma = 0.04
    t, left, right = _wheel_rates(rate_hz, sigma)
    expected = sigma * np.sqrt(step / rate_hz)
    assert rate_wheel_noise(t, left, right, step) == pytest.approx(expected, rel=0.05)


def test_wheel_rates_from_a_slower_signal_are_not_measured():
    """Rates interpolated from a 10 Hz signal onto 100 Hz are not white per sample: no
    estimate (the profile's wheel noise stays), rather than a far too small one."""
    t, left, right = _wheel_rates(10.0, 0.04)
    fine = np.arange(t[0], t[-1], 0.01)
    interpolated = [np.interp(fine, t, x) for x in (left, right)]
    assert rate_wheel_noise(fine, *interpolated, 0.025) is None
    assert rate_wheel_noise(t[:50], left[:50], right[:50], 0.025) is None  # too few samples


def test_an_imported_recordings_wheel_noise_raises_the_profiles(tmp_path):
    """A delivery robot's 0.02 m/s wheel speeds at 100 Hz (0.00063 rev per 25 ms step; its
    profile says 0.0005): the imported log carries their noise and the prepared settings
    weight the corrections by it; with ``wheel_noise_from_log`` off, by the profile's."""
    from campaign.recording import write_recording
    from campaign.shape import Shape

    from graphcal.pipeline.configuration.settings import Settings
    from graphcal.pipeline.configuration.settings_file import load_vehicle
    from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle
    from graphcal.pipeline.methods.prepare import prepare_log
    from graphcal.recording.open_log import open_log

    shape = Shape(
        vehicle="differential", route="yard", length_m=120.0, gnss_rate=10.0,
        noise_sigma=0.05, noise_tau_s=0.0, heading=True, imu=False, wheels="speed", ticks=0,
        drives=1, gap_s=0.0, park_s=2.0, time_offset_s=0.0, lever_arm=(0.0, 0.0), seed=5,
    )  # fmt: skip
    manifest = write_recording(shape, tmp_path)
    vehicle = load_vehicle(tmp_path / "vehicle.toml")
    log, _ = open_log(manifest, vehicle)
    assert log.wheel_noise == pytest.approx(0.02 / 0.5 * np.sqrt(0.01 * 0.025), rel=0.1)
    settings = apply_vehicle(Settings(), vehicle)
    assert settings.joint.wheel_noise == 0.0005
    prepared = prepare_log(log, settings, fall_back_to_all=True)
    assert prepared.settings.joint.wheel_noise == log.wheel_noise
    off = dataclasses.replace(
        settings, joint=dataclasses.replace(settings.joint, wheel_noise_from_log=False)
    )
    assert prepare_log(log, off, fall_back_to_all=True).settings.joint.wheel_noise == 0.0005


@pytest.mark.parametrize("sigma", [0.2, 2.0])
@pytest.mark.parametrize("defects", ["none", "gnss10hz", "gnss10hz,ticks"])
def test_the_fixes_white_noise_is_read_from_their_second_differences(sigma, defects):
    """40 Hz or 10 Hz fixes of 0.2 or 2 m, wheel speeds or 96-tick counts: the motion the
    wheels put in a second difference is taken out, what is left is the noise."""
    drive = simulate_drive(4.0, seed=3, noise=NoiseLevels(position=sigma))
    log = degrade(drive, parse_defects(defects), 3).measured
    assert position_noise(log, THETA_NOMINAL) == pytest.approx(sigma, rel=0.05)


@pytest.mark.parametrize(("rate", "sigma"), [(50.0, 0.45), (0.5, 2.0)])
def test_the_fixes_noise_is_read_from_fixes_at_uneven_times(tmp_path, rate, sigma):
    """A robot's 50 Hz receiver on the 40 Hz log (intervals of 20 and 40 ms) and a 0.5 Hz
    one whose fixes arrive ±25 ms about their grid: no two intervals alike, the noise read
    all the same (``None`` before: only evenly spaced triples counted, and the first solve
    weighted fixes of 0.45 m as the profile's 0.05 m and crept)."""
    from campaign.recording import write_recording
    from campaign.shape import Shape

    from graphcal.pipeline.configuration.settings_file import load_vehicle
    from graphcal.recording.open_log import open_log

    shape = Shape(
        vehicle="differential", route="yard", length_m=220.0, gnss_rate=rate,
        noise_sigma=sigma, noise_tau_s=0.0, heading=False, imu=False, wheels="speed", ticks=0,
        drives=1, gap_s=0.0, park_s=0.0, time_offset_s=0.0, lever_arm=(0.0, 0.0), seed=539,
    )  # fmt: skip
    manifest = write_recording(shape, tmp_path)
    vehicle = load_vehicle(tmp_path / "vehicle.toml")
    log, _ = open_log(manifest, vehicle)
    fixes = log.t[log.position_measured] - log.fix_lag[log.position_measured]
    spacing = np.diff(fixes)
    alike = np.abs(np.diff(spacing)) <= 1e-3 * (spacing[1:] + spacing[:-1])
    assert alike.sum() < MIN_FIX_TRIPLES  # too few evenly spaced triples to read them on
    assert position_noise(log, vehicle.theta_nominal) == pytest.approx(sigma, rel=0.1)


def test_a_first_solve_weights_fixes_far_noisier_than_the_settings_assume():
    """Fixes of 2 m under the default 0.2 m: the first solve weights them as the 2 m their
    second differences show, the heading's σ kept; fixes of 0.4 m (2×, within what the
    solve's residuals judge) keep the settings' 0.2 m."""
    from graphcal.factors import pose_sigmas
    from graphcal.pipeline.configuration.settings import Settings
    from graphcal.pipeline.methods.prepare import prepare_log

    settings = Settings()
    heading = pose_sigmas(settings.joint.pose_weights, settings.joint.position_sigma)[2]
    settings = dataclasses.replace(
        settings, joint=dataclasses.replace(settings.joint, heading_noise_from_log=False)
    )
    for sigma, weighted in ((2.0, 2.0), (0.4, 0.2)):
        log = simulate_drive(4.0, seed=3, noise=NoiseLevels(position=sigma)).measured
        joint = prepare_log(log, settings, True).settings.joint
        sigmas = pose_sigmas(joint.pose_weights, joint.position_sigma)
        assert sigmas[0] == pytest.approx(weighted, rel=0.05)
        assert sigmas[2] == pytest.approx(heading, rel=1e-5)
