"""Fewer batches than asked are said, with why (issue 44, row 9: ``--batches 1000`` on the
sample drive gave "220 batches of 9 segments" without a word: 12 segments have only
C(12, 9) = 220 distinct batches of 9)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from graphcal.pipeline.configuration.settings import BatchingSettings
from graphcal.pipeline.end_to_end.run import _batches
from graphcal.progress import reporting_to


def _said(count: int, selected: int) -> list[str]:
    prepared = SimpleNamespace(
        settings=SimpleNamespace(batches=BatchingSettings(count=count)),
        selected=np.arange(selected),
    )
    lines: list[str] = []
    with reporting_to(lines.append):
        _batches(prepared, "joint", 2)
    return lines


def test_fewer_distinct_batches_than_asked_are_said():
    lines = _said(1000, 12)
    assert "only 220 distinct batches of 9 of the 12 selected segments: 220 instead of 1000" in (
        lines
    ), lines
    assert lines[-1] == "joint: 220 batches of 9 segments, 2 workers"


def test_as_many_as_asked_say_nothing_more():
    assert _said(100, 12) == ["joint: 100 batches of 9 segments, 2 workers"]
