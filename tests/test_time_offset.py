"""The wheel-vs-pose time offset: undone by interpolation, estimated from the χ² profile."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.data.timing import shift_wheel_rotations
from graphcal.pipeline.run import select
from graphcal.pipeline.settings import Settings
from graphcal.pipeline.time_offset import estimate_time_offset
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


@pytest.fixture(scope="module")
def clean():
    return simulate_drive(4.0, 1)


@pytest.fixture(scope="module")
def late(clean):
    return degrade(clean, parse_defects("latency"), 1)  # wheels 0.05 s late


def test_shifting_the_wheels_undoes_a_latency(clean, late):
    truth = clean.truth
    undone = shift_wheel_rotations(late.measured, 0.05)
    inner = slice(10, -10)  # the ends continue at the edge rates
    residual = undone.n_rl[inner] - truth.n_rl[inner]
    late_residual = late.measured.n_rl[inner] - truth.n_rl[inner]
    assert np.std(residual) < 1.2 * clean.noise.wheel_rotation  # only the white noise is left
    assert np.std(late_residual) > 1.5 * np.std(residual)  # 0.05 s late: 1.9x here
    np.testing.assert_allclose(undone.n_rl.sum(), late.measured.n_rl.sum(), rtol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize(("which", "true_offset"), [("late", 0.05), ("clean", 0.0)])
def test_the_offset_is_recovered_within_10_ms_and_zero_within_2_sigma(
    clean, late, which, true_offset
):
    log = (late if which == "late" else clean).measured
    settings = Settings()
    _, _, selected, _ = select(log, settings, lambda _line: None)
    found = estimate_time_offset(log, selected, settings.joint, search=0.15, step=0.05)
    assert not found.at_edge
    assert abs(found.value - true_offset) < 0.010
    assert abs(found.value - true_offset) < 3 * found.sigma + 1e-3
    if true_offset == 0.0:
        assert abs(found.value) < 2 * found.sigma + 1e-3


@pytest.mark.slow
def test_calibrate_estimates_and_reports_the_offset(late, tmp_path, capsys):
    import json

    from graphcal.cli import main
    from graphcal.simulate.drive import write_synthetic_drive

    path = tmp_path / "late.csv"
    write_synthetic_drive(late, path)
    out = tmp_path / "results"
    args = ["calibrate", str(path), "--method", "whole", "--estimate-time-offset"]
    assert main([*args, "--out", str(out), "--workers", "1"]) == 0  # trusted once corrected
    assert "time offset (wheels late) [ms]" in capsys.readouterr().out
    result = json.loads((out / "calibration.json").read_text())
    assert result["estimated"]["time_offset"]["value"] == pytest.approx(0.05, abs=0.01)
    assert result["settings"]["time_offset"]["estimate"] is True
