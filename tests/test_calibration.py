"""Batch calibration and the end-to-end ``graphcal calibrate`` run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.evaluation import Truth, evaluate
from graphcal.log.segments import (
    SegmentData,
    gather_segments,
    select_segments,
    split_segments,
)
from graphcal.pipeline.configuration.settings import SegmentSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.methods.selection import NoUsableSegments
from graphcal.pipeline.solvers.batch_calibration import (
    BatchSettings,
    calibrate_batch,
    held_start_batches,
)
from graphcal.simulate.drive import write_synthetic_drive


def test_noise_free_drive_gives_the_true_theta(clean_drive):
    log = clean_drive.measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    for estimate_start in (True, False):
        result = calibrate_batch(data, BatchSettings(estimate_start_poses=estimate_start))
        # Only the weak prior at nominal pulls: micrometres on c_e, c_d, t_r.
        error = np.abs(result.theta - clean_drive.theta_true)
        assert np.all(error < [1e-6, 1e-7, 2e-5, 1e-6]), error


@pytest.mark.slow
def test_noisy_drive_calibrates_close_to_truth(drive):
    run = run_calibration(
        drive.measured, Settings(segments=SegmentSettings(stride=50.0)), method="whole"
    )
    evaluation = evaluate(run, Truth(drive.theta_true))
    error = np.abs(evaluation.theta_error)
    # Well inside the nominal-to-truth distance (15 mm, 1.2 mm, 35 mm, 1.5 mm·s²/m).
    assert np.all(error < [2e-3, 0.3e-3, 25e-3, 0.4e-3])
    assert run.validation_error("calibrated") < 0.5 * run.validation_error("nominal")
    # Close to the reachable limit.
    assert run.validation_error("calibrated") < evaluation.reachable_error + 0.3


def test_holding_the_start_pose_is_worse_than_estimating_it(drive):
    # docs/method.md: freeing the start pose removes most of the c_e and d error of Step 1.
    log = drive.measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0, stride=25.0)))
    held = calibrate_batch(data, BatchSettings(estimate_start_poses=False)).theta
    free = calibrate_batch(data, BatchSettings(estimate_start_poses=True)).theta
    truth = drive.theta_true
    assert abs(free[0] - truth[0]) < abs(held[0] - truth[0])


def test_staged_method_refuses_a_straight_drive(straight_log, tmp_path, capsys):
    from graphcal.log.drive_log import write_drive_log

    log = straight_log
    with pytest.raises(NoUsableSegments, match=r"highest: 0\.000 rad/s"):
        run_calibration(log, method="staged")
    path = tmp_path / "straight.csv"
    write_drive_log(log, path)
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--method", "staged"]) == 2
    err = capsys.readouterr().err
    assert "no 150 m segment has mean |yaw rate| above 0.15 rad/s" in err
    assert "use --method joint" in err
    assert "Traceback" not in err and not out.exists()


@pytest.mark.slow
def test_cli_calibrate_writes_complete_deterministic_results(drive, tmp_path, capsys):
    log_path = tmp_path / "drive.csv"
    write_synthetic_drive(drive, log_path)
    outputs = []
    for name in ("a", "b"):
        out = tmp_path / name
        args = ["calibrate", str(log_path), "--out", str(out), "--segment-stride", "50"]
        assert main([*args, "--method", "whole"]) == 0
        outputs.append(out)
    printed = capsys.readouterr().out
    assert "c_d [mm]" in printed and "calibrated" in printed
    a, b = outputs
    names = {"calibration.json", "validation.csv", "route.png", "validation.png", "trajectory.png"}
    assert json.loads((outputs[0] / "calibration.json").read_text())["method"] == "whole"
    assert {p.name for p in a.iterdir()} == names  # no temporary files left behind
    for name in ("calibration.json", "validation.csv"):
        assert (a / name).read_text() == (b / name).read_text()
    text = (a / "calibration.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    theta = np.array([doc["theta"][n] for n in ("c_e", "c_d", "t_r", "d")])
    assert np.all(np.abs(theta - drive.theta_true) < [2e-3, 0.3e-3, 25e-3, 0.4e-3])
    assert doc["theta_display"]["c_d [mm]"] == pytest.approx(theta[1] * 1e3)
    assert doc["segments"]["selected"] > 0
    assert doc["validation_error_m"]["calibrated"] < doc["validation_error_m"]["nominal"]


@pytest.mark.slow
def test_joint_solve_recovers_theta_on_noise_free_data(clean_drive):
    from graphcal.pipeline.solvers.joint import calibrate_joint

    log = clean_drive.measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    result = calibrate_joint(data.take(np.arange(min(4, len(data)))))
    error = np.abs(result.theta - clean_drive.theta_true)
    # Micrometre level: 0.002 mm on c_d, 0.005 mm·s²/m on d, 0.5 mm on t_r.
    assert np.all(error < [1e-6, 2e-6, 5e-4, 5e-6]), error
    np.testing.assert_allclose(result.start_states[:, :2], data.poses[:4, 0, :2], atol=1e-4)


@pytest.mark.slow
def test_cli_joint_method_end_to_end(drive, tmp_path, capsys):
    log_path = tmp_path / "drive.csv"
    write_synthetic_drive(drive, log_path)
    out = tmp_path / "joint"
    args = [
        "calibrate",
        str(log_path),
        "--out",
        str(out),
        "--method",
        "joint",
        "--segment-stride",
        "25",
        "--batches",
        "3",
    ]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "joint rmse" in printed and "95 % interval" in printed
    doc = json.loads((out / "calibration.json").read_text())
    assert doc["method"] == "joint" and set(doc["steps"]) == {"step1", "joint"}
    for name, truth in zip(("c_e", "c_d", "t_r", "d"), drive.theta_true, strict=True):
        entry = doc["parameters"][name]
        assert entry["status"] == "calibrated" and entry["sigma"] > 0
        low, high = entry["ci95"]
        assert low < entry["value"] < high
        # The truth lies within 4 sigma of the recommended value (the interval is honest).
        assert abs(entry["value"] - truth) < 4 * entry["sigma"]
        # The data's own σ is the Cramér–Rao bound; the σ reported adds slow slip that no
        # test can show (a drive's middle weighs more in a fit than its ends).
        scale = doc["wheel_slip"]["sigma_scale_for_unseen_slip"][name]
        assert entry["cramer_rao_sigma"] == pytest.approx(entry["sigma"] / scale, rel=0.1)
        assert scale >= 1.0
    assert (out / "batch_intervals.png").is_file()
    theta = np.array([doc["theta"][n] for n in ("c_e", "c_d", "t_r", "d")])
    assert np.all(np.abs(theta - drive.theta_true) < [1e-3, 0.3e-3, 15e-3, 0.3e-3])
    assert (out / "parameters.png").is_file() and (out / "batches.csv").is_file()
    uncertainty = doc["uncertainty"]["joint"]
    assert 0 < uncertainty["sigma_per_batch_median"]["c_d"] < 1e-3  # well under a mm
    assert uncertainty["nees_batches"] == 3 and np.isfinite(uncertainty["nees_mean"])
    header = (out / "batches.csv").read_text().splitlines()[0]
    assert "joint_sigma_t_r" in header


@pytest.mark.slow
def test_joint_covariance_matches_a_finite_difference_jacobian(drive):
    """Marginal covariance of theta vs the inverse of JᵀJ built from numerical derivatives."""
    import gtsam
    from numerical import retract_jacobian

    from graphcal.graph.construction.builder import build_segment_graph
    from graphcal.graph.construction.keys import THETA as THETA_KEY
    from graphcal.pipeline.solvers.joint import calibrate_joint
    from graphcal.pipeline.solvers.joint_settings import JointSettings

    log = drive.measured
    selected = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    first = selected.take([0, 1])
    n = np.minimum(first.n_steps, 60)  # two short segments keep the Jacobian small
    data = SegmentData(
        first.poses[:, :61],
        np.where(first.valid[:, 1:61, None], first.inputs[:, :60], 0.0),
        n,
        first.valid[:, :61] & (np.arange(61)[None] <= n[:, None]),
    )
    settings = JointSettings(chunk_steps=30)
    result = calibrate_joint(data, settings)
    built = build_segment_graph(data, settings.graph_spec())
    graph, values = built.graph, built.values
    # Linearize at the solution; the numerical Jacobian perturbs each tangent direction.
    optimum = gtsam.Values(values)
    optimum.update(THETA_KEY, result.theta)
    solved = gtsam.LevenbergMarquardtOptimizer(graph, optimum).optimize()

    def residuals(v: gtsam.Values) -> np.ndarray:
        # A factor linearized at v is A·dx − b with b the negated whitened error at v.
        return np.concatenate(
            [-graph.at(i).linearize(v).jacobian()[1] for i in range(graph.size())]
        )

    jacobian, columns = retract_jacobian(residuals, solved, solved.keys())
    theta = columns[THETA_KEY]
    covariance = np.linalg.inv(jacobian.T @ jacobian)[np.ix_(theta, theta)]
    marginal = gtsam.Marginals(graph, solved).marginalCovariance(THETA_KEY)
    np.testing.assert_allclose(marginal, covariance, rtol=1e-3, atol=1e-14)


@pytest.mark.slow
def test_whole_log_request_with_the_staged_method_is_a_one_line_error(drive_csv, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["calibrate", str(drive_csv), "--out", str(out), "--batches", "0", "--method", "staged"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--batches 0 (one solve over the whole log) needs --method joint or whole" in err
    assert err.count("\n") == 1 and not out.exists()


def test_held_start_batches_equal_their_own_solves(drive):
    """Step 1's batches from one solve and two Gauss–Newton steps each are each batch's own
    Levenberg–Marquardt solve, well within the batches' spread (the study's figure)."""
    log = drive.measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0, stride=25.0)))
    rng = np.random.default_rng(0)
    batches = np.array([rng.choice(len(data), 6, replace=False) for _ in range(8)])
    settings = BatchSettings(estimate_start_poses=False)
    shared = held_start_batches(data, batches, settings)
    own = np.array([calibrate_batch(data.take(b), settings).theta for b in batches])
    spread = own.std(axis=0)
    assert np.all(np.abs(shared - own) <= 0.01 * spread)
    with pytest.raises(ValueError, match="hold the start poses"):
        held_start_batches(data, batches, BatchSettings(estimate_start_poses=True))
