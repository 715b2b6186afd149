"""Issue 26, row I: a run that failed a trust check (exit status 3) shows its theta as not
trusted everywhere, never as the prior value and never as the recommended theta."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from matplotlib.figure import Figure

from graphcal.evaluation import Evaluation, Truth, evaluate
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.solvers.joint_settings import without_defect_model
from graphcal.report.figures import figures
from graphcal.report.results import summary_text
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


@pytest.fixture(scope="module")
def untrusted() -> tuple[CalibrationRun, Evaluation]:
    """The GNSS antenna 1.2 m ahead of the centre of gravity with the defect model off, and
    the solves stopped after 1 iteration: not converged, so the run is not trusted (3 were
    enough to converge once the steps roll the boundary poses out,
    graphcal.graph.optimization.rollout)."""
    drive = degrade(simulate_drive(3.0, seed=11), parse_defects("lever_arm=1.2"), seed=1)
    settings = Settings(batches=BatchingSettings(count=2, size=4))
    joint = dataclasses.replace(without_defect_model(settings.joint), max_iterations=1)
    settings = dataclasses.replace(settings, joint=joint)
    run = run_calibration(drive.measured, settings, "joint", workers=1)
    assert not run.trust.trusted and run.observability.calibrated.all()
    return run, evaluate(run, Truth(drive.theta_true))


def _interval_rows(text: str) -> dict[str, str]:
    """The rows of the summary's table of theta with its 95 % interval, by parameter."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if "95 % interval" in line)
    rows = {}
    for line in lines[start + 2 :]:
        if not line.strip():
            break
        rows[line.split(" [")[0]] = line
    return rows


@pytest.mark.slow
def test_the_table_does_not_call_an_untrusted_estimate_the_prior(untrusted):
    run, evaluation = untrusted
    text = summary_text(run, evaluation)
    rows = _interval_rows(text)
    nominal = run.settings.vehicle.theta_nominal
    for i, name in enumerate(PARAMETER_NAMES):
        assert not np.isclose(run.theta[i], nominal[i])  # an estimate, not the prior
        assert "prior value" not in rows[name], rows[name]
        assert "not trusted" in rows[name], rows[name]
    assert "recommended θ" not in text
    assert "estimated (not trusted)" in text  # the theta and validation tables' row


def test_figures_do_not_recommend_an_untrusted_theta(untrusted):
    run, evaluation = untrusted
    drawn = figures(run, evaluation)
    assert {"validation.png", "parameters.png", "batch_intervals.png"} <= set(drawn)
    for name, fig in drawn.items():
        labels = _labels(fig)
        assert not [t for t in labels if "recommended" in t], (name, labels)
        if name != "route.png":  # the route shows no theta
            assert any("not trusted" in t for t in labels), (name, labels)


def _labels(fig: Figure) -> list[str]:
    """Every legend entry and line label of a figure (what names the lines)."""
    texts = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    for ax in fig.axes:
        texts += [str(artist.get_label()) for artist in [*ax.lines, *ax.patches]]
    return texts


def test_batch_intervals_draw_no_band_for_an_untrusted_theta(untrusted):
    """Issue 35: the figure drew an "estimated θ (not trusted) ±2σ" band the summary's table
    refuses to give; it says instead that the estimate is not trusted."""
    run, evaluation = untrusted
    fig = figures(run, evaluation)["batch_intervals.png"]
    bands = [p.get_label() for ax in fig.axes for p in ax.patches if "±2σ" in p.get_label()]
    assert not bands, bands
    assert all("not trusted" in ax.get_title() for ax in fig.axes)
    caption = " ".join(legend.get_title().get_text() for legend in fig.legends)
    assert "no ±2σ band" in " ".join(caption.split())
