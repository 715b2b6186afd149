"""The GNSS antenna's lever arm: positions moved to the centre of gravity."""

from __future__ import annotations

import numpy as np

from graphcal.log.antenna import move_to_centre
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


def test_moving_to_the_centre_undoes_the_arm():
    drive = simulate_drive(1.0, 4)
    moved = degrade(drive, parse_defects("lever_arm=1.2:0.5"), 4).measured
    back = move_to_centre(moved, (1.2, 0.5))
    error = np.hypot(back.px - drive.measured.px, back.py - drive.measured.py)
    assert np.median(error) < 0.01  # the smoothed heading rotates the arm; noise stays small
    assert np.median(np.hypot(moved.px - drive.measured.px, moved.py - drive.measured.py)) > 1.2
