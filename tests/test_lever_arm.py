"""The GNSS antenna's lever arm: moved to the centre of gravity, estimated from χ² profiles."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.data.antenna import move_to_centre
from graphcal.pipeline.profile import APPLY, profile_estimate
from graphcal.pipeline.run import select
from graphcal.pipeline.settings import Settings
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive

SETTINGS = Settings()


def _estimate(log, names=("lever_arm_longitudinal", "lever_arm_lateral")):
    _, _, selected, _ = select(log, SETTINGS, lambda _line: None, fall_back_to_all=True)
    found = {}
    for name in names:
        grid = np.arange(-1.5, 1.75, 0.5)
        found[name] = profile_estimate(name, log, selected, SETTINGS.joint, grid)
        if found[name].observable:
            log = APPLY[name](log, found[name].value)
    return found


def test_moving_to_the_centre_undoes_the_arm():
    drive = simulate_drive(1.0, 4)
    moved = degrade(drive, parse_defects("lever_arm=1.2:0.5"), 4).measured
    back = move_to_centre(moved, (1.2, 0.5))
    error = np.hypot(back.px - drive.measured.px, back.py - drive.measured.py)
    assert np.median(error) < 0.01  # the smoothed heading rotates the arm; noise stays small
    assert np.median(np.hypot(moved.px - drive.measured.px, moved.py - drive.measured.py)) > 1.2


@pytest.mark.slow
def test_a_lever_arm_is_recovered_and_an_absent_one_is_zero():
    drive = simulate_drive(4.0, 1)
    present = _estimate(degrade(drive, parse_defects("lever_arm=1.2:0.5"), 1).measured)
    ahead, left = present["lever_arm_longitudinal"], present["lever_arm_lateral"]
    assert ahead.observable and abs(ahead.value - 1.2) < 0.2
    assert left.observable and abs(left.value - 0.5) < 0.1
    absent = _estimate(drive.measured)
    for found in absent.values():
        assert found.observable and abs(found.value) < 2 * found.sigma + 1e-3


@pytest.mark.slow
def test_a_straight_drive_cannot_show_a_longitudinal_arm():
    drive = simulate_drive(4.0, 1, route="straight")
    found = _estimate(degrade(drive, parse_defects("lever_arm"), 1).measured)
    assert not found["lever_arm_longitudinal"].observable
    assert found["lever_arm_longitudinal"].to_dict()["observable"] is False


@pytest.mark.slow
@pytest.mark.parametrize("flag", ["--estimate-lever-arm"])
def test_calibrate_reports_the_estimated_arm(tmp_path, capsys, flag):
    import json

    from graphcal.cli import main
    from graphcal.simulate.drive import write_synthetic_drive

    drive = degrade(simulate_drive(4.0, 1), parse_defects("lever_arm"), 1)
    path = tmp_path / "arm.csv"
    write_synthetic_drive(drive, path)
    out = tmp_path / "r"
    assert main(["calibrate", str(path), "--method", "whole", flag, "--out", str(out)]) == 0
    assert "lever arm, ahead [m]" in capsys.readouterr().out
    result = json.loads((out / "calibration.json").read_text())
    assert result["estimated"]["lever_arm_longitudinal"]["value"] == pytest.approx(1.2, abs=0.2)
