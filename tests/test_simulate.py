"""Synthetic drives: model consistency, realism limits, noise levels, determinism, files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.log.load import load_drive_log
from graphcal.model import integrate
from graphcal.simulate.drive import (
    THETA_TRUE_DEFAULT,
    NoiseLevels,
    read_sidecar,
    simulate_drive,
    truth_path,
)


def test_noise_free_inputs_reproduce_noise_free_poses(drive):
    truth = drive.truth
    states = integrate(truth.poses[0], truth.inputs[:-1], drive.theta_true)
    np.testing.assert_allclose(states, truth.poses, rtol=0, atol=1e-9)


def test_written_truth_file_reproduces_poses(drive_csv):
    truth = load_drive_log(truth_path(drive_csv))
    theta = read_sidecar(drive_csv)["theta_true"]
    states = integrate(truth.poses[0], truth.inputs[:-1], theta)
    np.testing.assert_allclose(states, truth.poses, rtol=0, atol=1e-9)


def test_motion_respects_the_driving_limits(drive):
    truth, dt = drive.truth, drive.truth.dt
    assert dt == pytest.approx(0.025)
    speed = np.hypot(np.diff(truth.px), np.diff(truth.py)) / dt
    assert speed.min() > 1.0 and speed.max() < 70 / 3.6 + 0.1
    yaw_rate = np.diff(truth.psi) / dt
    steady = 0.5 * (speed[1:] + speed[:-1]) * 0.5 * (yaw_rate[1:] + yaw_rate[:-1])
    assert np.abs(steady).max() < 2.5 + 0.1  # the profile's limit on speed x yaw rate
    assert np.percentile(np.abs(truth.ay), 99) < 2.5 + 0.5  # plus entering bends (l_r psi'')
    window = 20  # 0.5 s, as an accelerometer-free check from positions would use
    mean_speed = np.convolve(speed, np.ones(window) / window, mode="valid")
    acceleration = (mean_speed[window:] - mean_speed[:-window]) / (window * dt)
    assert acceleration.max() < 1.5 + 0.1 and acceleration.min() > -2.0 - 0.1
    assert np.abs(yaw_rate).max() > 0.3  # real turns, not just gentle bends
    assert np.abs(truth.beta).max() < np.deg2rad(15)


def test_noise_has_the_requested_levels(drive):
    residual = {
        "position": np.concatenate(
            [drive.measured.px - drive.truth.px, drive.measured.py - drive.truth.py]
        ),
        "heading": drive.measured.psi - drive.truth.psi,
        "wheel_rotation": np.concatenate(
            [drive.measured.n_rl - drive.truth.n_rl, drive.measured.n_rr - drive.truth.n_rr]
        ),
    }
    for name, r in residual.items():
        assert np.std(r) == pytest.approx(getattr(drive.noise, name), rel=0.03), name
        assert abs(np.mean(r)) < 0.03 * getattr(drive.noise, name), name


def test_same_seed_same_drive_and_other_seed_other_drive():
    a, b = simulate_drive(1.0, seed=5), simulate_drive(1.0, seed=5)
    c = simulate_drive(1.0, seed=6)
    np.testing.assert_array_equal(a.measured.px, b.measured.px)
    np.testing.assert_array_equal(a.measured.n_rl, b.measured.n_rl)
    assert len(a.measured) != len(c.measured) or not np.array_equal(a.measured.px, c.measured.px)


def test_default_theta_true_is_away_from_nominal(drive):
    np.testing.assert_array_equal(drive.theta_true, THETA_TRUE_DEFAULT)


def test_bad_noise_level_is_rejected():
    with pytest.raises(ValueError, match="wheel_rotation"):
        NoiseLevels(wheel_rotation=-1.0)


def test_cli_simulate_writes_csv_truth_and_sidecar(tmp_path):
    out = tmp_path / "sim.csv"
    assert (
        main(
            [
                "simulate",
                "--length-km",
                "1",
                "--seed",
                "3",
                "--out",
                str(out),
                "--theta-true",
                "1.99",
                "-0.5",
                "1.6",
                "2.0",
                "--wheel-noise",
                "0.001",
            ]
        )
        == 0
    )
    meta = json.loads((tmp_path / "sim.json").read_text())
    assert meta["seed"] == 3
    assert meta["theta_true"] == pytest.approx(
        {"c_e": 1.99, "c_d": -0.5e-3, "t_r": 1.6, "d": 2.0e-3}
    )
    assert meta["noise"]["wheel_rotation_rev"] == 0.001
    assert meta["truth_file"] == "sim_truth.csv"
    measured, truth = load_drive_log(out), load_drive_log(tmp_path / "sim_truth.csv")
    assert len(measured) == len(truth) == meta["samples"]


def test_cli_simulate_rejects_nonsense_theta(tmp_path, capsys):
    assert (
        main(
            [
                "simulate",
                "--length-km",
                "1",
                "--out",
                str(tmp_path / "x.csv"),
                "--theta-true",
                "0",
                "0",
                "1.55",
                "0",
            ]
        )
        == 2
    )
    assert "c_e and t_r must be positive" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
