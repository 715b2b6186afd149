"""Never confidently wrong: the checks that need no truth mark a wrong result as untrusted."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.graph.solve_options import SolveOutcome, SolveStatus
from graphcal.log.drive_log import write_drive_log
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.trust import (
    EXIT_UNTRUSTED,
    MAX_CHI2_PER_DOF,
    NORMAL_IQR,
    assess_trust,
    spread_ratio,
)

CLEAN = dict(
    solve=SolveOutcome(SolveStatus.CONVERGED, 4, 30),
    chi2_per_dof=0.97,
    batch_theta=None,
    batch_covariance=None,
    calibrated=np.ones(4, bool),
    validation_calibrated=0.3,
    validation_nominal=9.0,
)


def test_spread_ratio_of_honest_independent_batches_is_the_normal_iqr(rng):
    sigma = np.array([2e-4, 2e-4, 6e-3, 1e-4])
    theta = rng.normal(size=(4000, 4)) * sigma
    covariance = np.broadcast_to(np.diag(sigma**2), (4000, 4, 4))
    np.testing.assert_allclose(spread_ratio(theta, covariance), NORMAL_IQR, rtol=0.05)
    assert spread_ratio(theta[:5], covariance[:5]) is None  # too few batches to judge


def test_a_clean_run_is_trusted():
    trust = assess_trust(**CLEAN)
    assert trust.trusted and not trust.parameter_doubts and trust.to_dict()["trusted"]


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"solve": SolveOutcome(SolveStatus.ITERATION_LIMIT, 30, 30)}, "iteration limit"),
        ({"chi2_per_dof": MAX_CHI2_PER_DOF + 0.3}, "do not fit the noise model"),
        ({"validation_calibrated": 10.0}, "validates worse than the nominal"),
    ],
)
def test_each_check_makes_the_run_untrusted(change, says):
    trust = assess_trust(**{**CLEAN, **change})
    assert not trust.trusted and says in trust.doubts[0]
    assert set(trust.parameter_doubts) == {"c_e", "c_d", "t_r", "d"}


def test_batches_that_spread_beyond_their_sigma_distrust_only_those_parameters(rng):
    sigma = np.array([2e-4, 2e-4, 6e-3, 1e-4])
    theta = rng.normal(size=(200, 4)) * sigma * np.array([6.0, 1.0, 1.0, 1.0])
    covariance = np.broadcast_to(np.diag(sigma**2), (200, 4, 4))
    trust = assess_trust(**{**CLEAN, "batch_theta": theta, "batch_covariance": covariance})
    assert set(trust.parameter_doubts) == {"c_e"} and "c_e " in trust.doubts[0]
    assert trust.spread_ratio[0] == pytest.approx(6.0 * NORMAL_IQR, rel=0.15)
    # A parameter the data did not determine spreads with its prior; it is not judged.
    calibrated = np.array([False, True, True, True])
    kept = assess_trust(
        **{**CLEAN, "batch_theta": theta, "batch_covariance": covariance, "calibrated": calibrated}
    )
    assert kept.trusted


@pytest.mark.slow
def test_an_unmodelled_lever_arm_is_never_confidently_wrong(drive, tmp_path, capsys):
    # The GNSS antenna 1.2 m ahead of the centre of gravity, the defect model switched off:
    # the fixes' residuals follow the bends (correlated, 34× a white error's variance of a
    # mean) and the heading's are wider than its noise. Weighted by what they show, theta's
    # σ covers its error; were the run not trusted, it would say so in its exit status.
    truth = drive.truth
    log = dataclasses.replace(
        drive.measured,
        px=drive.measured.px + 1.2 * np.cos(truth.psi),
        py=drive.measured.py + 1.2 * np.sin(truth.psi),
    )
    path = tmp_path / "lever.csv"
    write_drive_log(log, path)
    out = tmp_path / "results"
    args = ["calibrate", str(path), "--method", "whole", "--no-defect-model"]
    status = main([*args, "--out", str(out)])
    captured = capsys.readouterr()
    assert "the fixes' errors are alike from fix to fix" in captured.out + captured.err
    result = json.loads((out / "calibration.json").read_text())
    if status == EXIT_UNTRUSTED:
        assert result["parameters"]["c_e"]["status"].startswith("not trusted")
        return
    assert status == 0
    for i, name in enumerate(PARAMETER_NAMES):
        entry = result["parameters"][name]
        if entry["status"].startswith("calibrated"):
            error = entry["value"] - drive.theta_true[i]
            assert abs(error) < 3 * entry["sigma"], (name, error, entry["sigma"])


def test_an_implausible_theta_names_its_likely_cause_before_units():
    """Issue 25: a straight road or slow fixes drove solves to "implausible theta ... check
    the units" when no unit was wrong. What drove it is named; units only when nothing is."""
    from graphcal.errors import CalibrationFailed
    from graphcal.graph.plausibility import check_plausible

    absurd = np.array([2.0, 0.0, 0.2, 0.0])  # t_r = 0.2 m on a car
    with pytest.raises(CalibrationFailed) as named:
        check_plausible(absurd, "joint solve", causes=lambda: ("position fixes at only 0.5 Hz",))
    assert "likely cause: position fixes at only 0.5 Hz" in str(named.value)
    assert "check the units" not in str(named.value)
    with pytest.raises(CalibrationFailed, match="check the units"):
        check_plausible(absurd, "joint solve", causes=lambda: ())
    called = []
    check_plausible(np.array([2.0, 0.0, 1.55, 0.0]), causes=lambda: called.append(1) or ())
    assert not called  # a plausible theta costs no diagnosis


def test_d_from_wheels_on_a_straight_road_is_not_calibrated():
    """A lateral acceleration taken from the wheels and a drive without bends: d · a_y can
    only fit the wheels' own noise, so d is said not observable, with the reason."""
    from graphcal.graph.observability import assess_observability

    observability = assess_observability(np.diag([1e-8, 1e-8, 0.04, 1e-8]), np.array(
        [0.1, 0.01, 0.2, 0.01]))  # fmt: skip
    assert observability.calibrated[3]
    held = observability.without("d", "its lateral acceleration comes from the wheels")
    assert not held.calibrated[3] and held.verdicts()["d"] == "not observable"
    assert "d not observable (its lateral acceleration comes from the wheels)" in held.message()


def test_a_solve_that_converged_on_its_last_allowed_iteration_is_converged():
    """Convergence is the solve's status, not a count: a solve that met its tolerance on its
    30th of 30 iterations converged; one that stopped because no step lowered the error is
    at its minimum."""
    for status in (SolveStatus.CONVERGED, SolveStatus.NOT_IMPROVING):
        trust = assess_trust(**{**CLEAN, "solve": SolveOutcome(status, 30, 30)})
        assert trust.trusted and trust.converged and trust.to_dict()["iterations"] == 30
    staged = assess_trust(**{**CLEAN, "solve": None})  # no whole-log solve to judge
    assert staged.trusted and staged.converged
