"""Progress goes through one channel, the ``graphcal.progress`` logger: an entry point's
``progress=`` hears every line of the steps it calls, once, and a logging handler does too."""

from __future__ import annotations

import logging

from graphcal import Settings, calibrate_file
from graphcal.progress import LOGGER, reporting_to, reports_progress, say


@reports_progress
def _inner(progress=None) -> None:
    say("inner step")


@reports_progress
def _outer(progress=None) -> None:
    say("outer step")
    _inner(progress=progress)  # an entry point called by another: still heard once


def test_an_entry_point_hears_its_steps_once_and_only_while_it_runs():
    heard: list[str] = []
    _outer(progress=heard.append)
    assert heard == ["outer step", "inner step"]
    say("after the run")  # nobody listens any more
    assert heard == ["outer step", "inner step"] and not LOGGER.handlers


def test_no_listener_no_output(capsys):
    _outer()
    with reporting_to(None):
        say("quiet")
    assert capsys.readouterr() == ("", "")


def test_a_logging_handler_hears_a_real_calibration(caplog):
    heard: list[str] = []
    with caplog.at_level(logging.INFO, logger="graphcal.progress"):
        calibrate_file("data/sample_drive.csv", Settings(), "whole", progress=heard.append)
    logged = [r.getMessage() for r in caplog.records if r.name == "graphcal.progress"]
    assert heard == logged
    assert any(line.startswith("loaded data/sample_drive.csv") for line in heard)
    assert any("joint solve over all" in line for line in heard)
