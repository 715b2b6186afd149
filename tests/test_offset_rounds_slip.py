"""A time-offset round after a shift of at most a sample keeps the slip screen's verdict of
the round before: it models slip from its start instead of solving without it, screening
again and solving once more (the real robot's last round: 6 iterations and a screen → 4)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from graphcal.pipeline.methods.time_offset_rounds import _screened_before
from graphcal.pipeline.solvers.joint_settings import JointSettings


def test_a_round_keeps_slip_found_before_a_shift_its_first_order_covered():
    found = SimpleNamespace(slip_modelled=True, slip_test=object())
    auto = JointSettings(slip="auto")
    assert _screened_before(found, auto, np.array([True, True])) is found
    # a run moved by more than a sample: the screen before it saw a misfit it did not cover
    assert _screened_before(found, auto, np.array([True, False])) is None
    # no slip found, or none screened (slip on or off by the settings): the round as before
    none_found = SimpleNamespace(slip_modelled=False, slip_test=object())
    assert _screened_before(none_found, auto, np.array([True])) is None
    for fixed in ("on", "off"):
        assert _screened_before(found, JointSettings(slip=fixed), np.array([True])) is None
