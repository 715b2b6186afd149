"""Progress goes through one channel, the ``graphcal.progress`` logger: an entry point's
``progress=`` hears every line of the steps it calls, once; without it a program's logging
hears them; a muted step and a worker say nothing."""

from __future__ import annotations

import logging
import re

from graphcal import Settings, calibrate_file
from graphcal.progress import LOGGER, muted, reporting_to, reports_progress, say


@reports_progress
def _inner(progress=None) -> None:
    say("inner step")
    with muted():
        say("a fold's detail")


@reports_progress
def _outer(progress=None) -> None:
    say("outer step")
    _inner(progress=progress)  # an entry point called by another: still heard once


def test_an_entry_point_hears_its_steps_once_and_only_while_it_runs():
    heard: list[str] = []
    _outer(progress=heard.append)  # a bound method: a new object at each access
    assert heard == ["outer step", "inner step"]
    say("after the run")  # nobody listens any more
    assert heard == ["outer step", "inner step"] and not LOGGER.handlers


def test_no_listener_no_output(capsys):
    _outer()
    with reporting_to(None):
        say("quiet")
    assert capsys.readouterr() == ("", "")


def _untimed(lines: list[str]) -> list[str]:
    """``lines`` without the iteration lines of a long solve (whether an iteration is long
    depends on the machine's load)."""
    return [line for line in lines if not re.match(r"\s*iteration \d+:", line)]


def test_a_programs_logging_hears_a_real_calibration_that_has_no_progress(caplog):
    with caplog.at_level(logging.INFO, logger="graphcal.progress"):
        calibrate_file("data/sample_drive.csv", Settings(), "whole")
    logged = [r.getMessage() for r in caplog.records if r.name == "graphcal.progress"]
    assert any(line.startswith("loaded data/sample_drive.csv") for line in logged)
    assert any("joint solve over all" in line for line in logged)
    caplog.clear()
    heard: list[str] = []
    with caplog.at_level(logging.INFO, logger="graphcal.progress"):
        calibrate_file("data/sample_drive.csv", Settings(), "whole", progress=heard.append)
    # The same lines, once: to progress=, not also to logging (a long solve's iteration lines
    # are said only when an iteration takes long, which differs from run to run).
    assert _untimed(heard) == _untimed(logged)
    assert not [r for r in caplog.records if r.name == "graphcal.progress"]
