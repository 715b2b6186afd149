"""scripts/recording_study.py: its axes, the robot's length mapping, the manifest edits and
the verdicts (fast: nothing is simulated or calibrated)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "recording_study.py"


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location("recording_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["recording_study"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("recording_study", None)


def _args(study, *argv):
    return study.build_arguments().parse_args(list(argv))


def test_without_the_new_axes_the_shapes_are_the_full_cross_product(study):
    args = _args(study)
    drives = study.drives_of(args)
    assert [(d.vehicle, d.length_km, d.route) for d in drives] == [("car", 12.0, "city")]
    assert len(study.cases_of(args)) == 3 * 2 * 2 * 2


def test_a_new_axis_restricts_the_car_to_the_representative_shapes(study):
    args = _args(study, "--lengths", "1", "24", "--routes", "city", "straight")
    cases = study.cases_of(args)
    assert len(cases) == 2 * 2 * len(study.REPRESENTATIVE)
    shapes = {(c.shape.rate, c.shape.heading, c.shape.imu, c.shape.wheels) for c in cases}
    assert shapes == set(study.REPRESENTATIVE)
    # a shape option given: the cross product of the shape options again
    args = _args(study, "--lengths", "1", "--rates", "10", "--wheels", "ticks")
    assert len(study.cases_of(args)) == 2 * 2


def test_the_robot_drives_runs_in_proportion_to_the_length_in_its_hall(study):
    args = _args(study, "--lengths", "1", "2", "0.05", "--routes", "city", "straight",
                 "--vehicles", "car", "robot")  # fmt: skip
    robot = [d for d in study.drives_of(args) if d.vehicle == "robot"]
    assert [(d.length_km, d.runs, d.route) for d in robot] == [
        (1.0, 10, "hall"),
        (2.0, 20, "hall"),
        (0.05, 1, "hall"),
    ]
    assert all(d.csv_rate == 50.0 for d in robot)
    cases = [c for c in study.cases_of(args) if c.drive.vehicle == "robot"]
    assert len(cases) == 3 and {c.shape.heading for c in cases} == {"mocap"}


def test_manifest_edits_drop_the_heading_and_the_imu(study):
    text = (
        'rate = 40.0\n[gnss]\nfile = "gnss.csv"\nheading = "heading"\nheading_unit = "deg"\n'
        'sideslip = "beta"\n[wheels]\nkind = "speed"\n[imu]\nfile = "imu.csv"\n'
    )
    edited = study.edit_manifest(text, drop_heading=True, drop_imu=True)
    assert "heading" not in edited and "sideslip" not in edited and "[imu]" not in edited
    assert "[wheels]" in edited and "gnss.csv" in edited


def _record(study, seed, z, trusted=True, failed=None, exit_status=0):
    parameters = {
        name: {"z": z, "sigma": 1.0, "observability": "calibrated"}
        for name in study.PARAMETER_NAMES
    }
    return {
        "seed": seed,
        "vehicle": "car",
        "length_km": 2.0,
        "route": "city",
        "failed": failed,
        "trusted": trusted,
        "exit": exit_status,
        "doubts": [] if trusted else ["a doubt"],
        "parameters": parameters,
    }


def test_the_acceptance_fails_a_failed_run_and_a_trusted_run_beyond_three_sigma(study):
    good = [_record(study, s, 0.5) for s in range(3)]
    assert study.acceptance(good)[0]
    untrusted = _record(study, 3, 5.0, trusted=False, exit_status=3)
    passed, reasons, notes = study.acceptance([*good, untrusted])
    assert passed and any("not trusted" in n for n in notes)  # exit 3 is a note only
    failed = _record(study, 4, 0.0, trusted=False, failed="GraphcalError: x", exit_status=2)
    passed, reasons, _ = study.acceptance([*good, failed])
    assert not passed and "1 of 4 runs failed (car 2 km city)" in reasons[0]
    passed, reasons, _ = study.acceptance([*good, _record(study, 5, 3.5)])
    assert not passed and any("beyond 3σ" in r for r in reasons)
    breaks = study.row_breaks([*good, failed, _record(study, 5, 3.5)])
    assert breaks[0] == "1 failed (exit 2)" and any("seed 5" in b for b in breaks)
