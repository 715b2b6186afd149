"""Steps that turn the path: the chunk-boundary poses rolled out onto the odometry after each
Levenberg–Marquardt step (:mod:`graphcal.graph.optimization.rollout`), and the error the fixes
share with them.

graphcal's own skid-steer robot thinned to 2 Hz positions without heading (issue 43's
table, issue 45 row 1): the wheels' time offset turns the path by ``τ · ψ̇``, and before the
rollout every step along it left continuity gaps growing as its fourth power; the whole-log
solve crept 50 + 50 iterations to its limit, "not to be trusted", exit 3."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from graphcal.cli import main

ROOT = Path(__file__).resolve().parents[1]
SKID = ROOT / "data" / "vehicles" / "skid_steer_robot.toml"


def _thinned(directory: Path, every: int = 25) -> None:
    """The recording's 50 Hz poses thinned to every ``every``-th (2 Hz), heading dropped."""
    pose = pd.read_csv(directory / "pose.csv")
    pose.iloc[::every].drop(columns=["heading"]).to_csv(directory / "pose.csv", index=False)
    manifest = (directory / "manifest.toml").read_text()
    heading = 'heading = "heading"\nheading_unit = "rad"\nheading_convention = "enu"\n'
    assert heading in manifest
    (directory / "manifest.toml").write_text(manifest.replace(heading, ""))


def test_a_skid_steer_robot_at_2_hz_converges_in_a_few_steps(tmp_path, capsys):
    directory = tmp_path / "skid"
    assert main(["simulate", "--vehicle", str(SKID), "--streams", str(directory)]) == 0
    _thinned(directory)
    capsys.readouterr()
    out = tmp_path / "out"
    code = main(["calibrate", str(directory / "manifest.toml"), "--vehicle", str(SKID),
                 "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0, err
    assert "iteration limit" not in err, err
    iterations = [int(n) for n in re.findall(r"^\[[^]]*\]\s+(\d+) iterations", err, re.M)]
    assert iterations and max(iterations) <= 15, iterations  # before: 50 and 50
    doc = json.loads((out / "calibration.json").read_text())
    truth = json.loads((directory / "truth.json").read_text())["theta_true"]
    for name, entry in doc["parameters"].items():
        if str(entry.get("status", "")).startswith("calibrated"):
            assert abs(entry["value"] - truth[name]) < 3 * entry["sigma"], (name, entry, truth)


@pytest.mark.slow
def test_the_error_fixes_share_is_rolled_out_with_the_path(tmp_path):
    # Each step turned a segment within the error its fixes share (5° cost little there) and
    # the rollout moved the path onto its arc, not that error: every fix was left the turn's
    # second-order part, and the last solve crept 50 iterations to its limit, exit 3 (44 under
    # the noise-reading solve's 15 iterations). With the error following the path: 13.
    from campaign.invariants import calibrate
    from campaign.recording import write_recording
    from campaign.shape import Shape

    # campaign seed 54's shape 71: a differential robot's 161 m in a yard, 50 Hz fixes
    # sharing 1.2 m over 24 s, no heading, an IMU mounted turned 186°, 1 % outliers
    shape = Shape(
        vehicle="differential", route="yard", length_m=161.0, gnss_rate=50.0,
        noise_sigma=1.2, noise_tau_s=24.0, heading=False, imu=True, wheels="angular_speed",
        ticks=0, drives=1, gap_s=0.0, park_s=1.0, time_offset_s=-0.022,
        lever_arm=(-0.13, 0.0), seed=52305, outliers=0.01, mounting=(0.0, -0.0, 186.0),
    )  # fmt: skip
    result = calibrate(shape, write_recording(shape, tmp_path))
    assert result.broken == [], (result.verdicts, result.ratio, result.line)
    log = (tmp_path / "calibrate.log").read_text()
    iterations = [int(n) for n in re.findall(r"^\[[^]]*\]\s+(\d+) iterations", log, re.M)]
    assert iterations and max(iterations) <= 25, iterations


def test_a_links_gap_keeps_its_three_rows_not_the_chunks_jacobian():
    # Each part keeps its links' gaps from the elimination to the step: a view of the
    # linearized chunk factor's ~150 Jacobian rows kept those alive, 80 of the 145 MB the 24 km
    # graph's parts held between elimination and step (the 200 km main process 0.86 GB).
    from graphcal.graph.construction.builder import build_segment_graph
    from graphcal.graph.construction.graph_spec import shared_keys
    from graphcal.graph.optimization.partitioned import PartitionedGraph
    from graphcal.graph.optimization.rollout import chunk_links, linear_gaps
    from graphcal.graph.optimization.values import tangent_dims
    from graphcal.log.load import load_drive_log
    from graphcal.log.segments import gather_segments, select_segments, split_segments
    from graphcal.pipeline.solvers.joint_settings import JointSettings

    log = load_drive_log(ROOT / "data" / "sample_drive.csv")
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0))).take([0])
    spec = JointSettings().graph_spec()
    built = build_segment_graph(data, spec)
    part = PartitionedGraph(built.graph, built.values, shared_keys(spec)).parts[0]
    links = chunk_links(part.graph)
    linear = part.graph.linearize(part.values)
    gaps = linear_gaps(part.graph, linear, links, tangent_dims(part.values))
    assert len(gaps) >= 2
    for link, gap in zip(links, gaps, strict=True):
        rows = linear.at(link.factor).rows()
        assert rows > 3 and gap.a.shape[0] == 3
        assert gap.a.base is None and gap.b.base is None  # not views of the factor's rows
