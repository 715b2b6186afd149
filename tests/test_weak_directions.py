"""A direction the data barely determine is held by its prior, never a runaway that ends a
valid recording with "check the units" (issue 34)."""

from __future__ import annotations

import json
import re

import pytest

from graphcal.cli import main
from graphcal.simulate.drive import THETA_TRUE_DEFAULT
from graphcal.simulate.streams import simulate_streams, write_streams


def _plain_receiver(directory) -> str:
    """The recording's manifest without a heading, a sideslip and an IMU: 10 Hz fixes and
    CAN wheel speeds, what a plain receiver logs."""
    manifest = directory / "manifest.toml"
    text = re.sub(r"^(heading|sideslip)[^\n]*\n", "", manifest.read_text(), flags=re.M)
    plain = directory / "plain.toml"
    plain.write_text(text[: text.index("[imu]")])
    return str(plain)


@pytest.mark.slow
def test_a_2_km_straight_road_from_plain_fixes_calibrates_what_it_determines(tmp_path, capsys):
    """c_e and c_d within 3σ, t_r not observable near its prior (1.55 ± 0.2 m), exit 0. It was
    exit 2, "check the units", on 3 of 3 seeds (the first solve drove t_r to 0.49 m); then
    held at the prior when it ran out of range; since the rollout of each step
    (graphcal.graph.optimization.rollout) it no longer runs away (1.586 m, σ 189 mm)."""
    write_streams(simulate_streams(2.0, 0, route="straight"), tmp_path)
    out = tmp_path / "out"
    assert main(["calibrate", _plain_receiver(tmp_path), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "check the units" not in captured.out + captured.err
    result = json.loads((out / "calibration.json").read_text())
    parameters = result["parameters"]
    assert parameters["t_r"]["status"].startswith("not calibrated: not observable")
    assert parameters["t_r"]["value"] == pytest.approx(1.55, abs=0.2)  # where its prior has it
    for index, name in enumerate(("c_e", "c_d")):
        assert parameters[name]["status"].startswith("calibrated"), parameters[name]
        error = parameters[name]["value"] - THETA_TRUE_DEFAULT[index]
        assert abs(error) < 3 * parameters[name]["sigma"], (name, error)
