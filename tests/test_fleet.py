"""Fleet calibration on Dask (issue 15): sources, change tests, resumable runs, schedulers."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.errors import GraphcalError
from graphcal.fleet.history import DayEstimate, combine, vehicle_history
from graphcal.fleet.sources import discover_fleet
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL, THETA_PRIOR_SIGMAS
from graphcal.statistics import chi2_survival

pytest.importorskip("distributed")

#: The acceptance fleet: 3 vehicles × 3 days of 2 km, v3's c_e 3 mm lower from day 3 on (the
#: change among the unchanged days of the others).
VEHICLES, DAYS, LENGTH_KM = 3, 3, 2.0


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory) -> Path:
    from graphcal.simulate.fleet import FleetChange, simulate_fleet

    root = tmp_path_factory.mktemp("fleet") / "fleet"
    simulate_fleet(root, VEHICLES, DAYS, LENGTH_KM, seed=0, change=FleetChange(3, 3))
    return root


def _day(name, theta, sigmas):
    return DayEstimate(
        name,
        np.asarray(theta, float),
        np.diag(np.asarray(sigmas, float) ** 2),
        THETA_NOMINAL,
        THETA_PRIOR_SIGMAS,
    )


def test_chi2_survival_matches_tabulated_quantiles():
    # 0.1 % quantiles of χ² with 1 to 4 degrees of freedom
    for x, dof in ((10.828, 1), (13.816, 2), (16.266, 3), (18.467, 4)):
        assert chi2_survival(x, dof) == pytest.approx(1e-3, rel=1e-3)
    assert chi2_survival(0.0, 4) == 1.0


def test_combined_days_count_the_prior_once():
    sigmas = np.array([2e-4, 2e-4, 5e-3, 1e-4])
    theta, covariance = combine([_day("a", THETA_NOMINAL, sigmas)] * 3)
    one = 1.0 / sigmas**2 - 1.0 / THETA_PRIOR_SIGMAS**2  # the data's information of a day
    expected = 1.0 / (3 * one + 1.0 / THETA_PRIOR_SIGMAS**2)
    np.testing.assert_allclose(np.diag(covariance), expected, rtol=1e-9)
    np.testing.assert_allclose(theta, THETA_NOMINAL, atol=1e-12)


def test_a_step_in_c_e_is_found_on_its_day_and_named():
    sigmas = np.array([2e-4, 2e-4, 5e-3, 1e-4])
    base = THETA_NOMINAL + np.array([0.0, 1e-3, 0.03, 1e-3])
    days = [
        _day(f"day{i}", base + (i >= 3) * np.array([-3e-3, 0, 0, 0]), sigmas) for i in (1, 2, 3, 4)
    ]
    history = vehicle_history("v", days)
    assert [(c.day, c.parameter) for c in history.changes] == [("day3", "c_e")]
    assert history.current_days == ["day3", "day4"]
    np.testing.assert_allclose(history.theta[0], base[0] - 3e-3, atol=1e-9)
    steady = vehicle_history("w", [_day(f"d{i}", base, sigmas) for i in range(4)])
    assert steady.changes == []


def test_an_untrusted_day_is_flagged_and_left_out_of_the_change_test():
    """docs/fleet.md's fleet once reported "v2 day2: c_d −5.18 mm (−8.2σ)", a change that
    did not happen: the day was not trusted, its σ not honest, and it entered the test."""
    from graphcal.fleet.run import _histories

    sigmas = np.array([2e-4, 2e-4, 5e-3, 1e-4])

    def result(day, theta, trusted):
        return {
            "vehicle": "v2",
            "day": day,
            "status": "ok",
            "trusted": trusted,
            "posterior_theta": list(theta),
            "posterior_covariance": np.diag(sigmas**2).tolist(),
            "prior_mean": list(THETA_NOMINAL),
            "prior_sigmas": list(THETA_PRIOR_SIGMAS),
        }

    off = THETA_NOMINAL + [0.0, -5.18e-3, 0.0, 0.0]
    rows = [result("day1", THETA_NOMINAL, True), result("day2", off, False)]
    rows.append(result("day3", THETA_NOMINAL, True))
    (history,) = _histories(rows, 1e-3)
    assert history.changes == []
    assert history.current_days == ["day1", "day3"]
    assert history.flags == ["day2: calibration not trusted, left out of the change test"]
    rows[1]["trusted"] = True  # the same day trusted: a real change, found
    (history,) = _histories(rows, 1e-3)
    assert [c.day for c in history.changes][:1] == ["day2"]


@pytest.mark.slow
def test_tree_discovery_skips_truth_files_and_orders_days(fleet_dir):
    logs = discover_fleet(fleet_dir)
    assert len(logs) == VEHICLES * DAYS
    assert [(log.vehicle, log.day) for log in logs[:3]] == [
        ("v1", "day1"),
        ("v1", "day2"),
        ("v1", "day3"),
    ]
    assert not any(log.path.name.endswith("_truth.csv") for log in logs)


def test_bad_sources_give_one_line(tmp_path, capsys):
    assert main(["fleet", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o")]) == 2
    manifest = tmp_path / "fleet.csv"
    manifest.write_text("vehicle,path\nv1,a.csv\n")
    with pytest.raises(GraphcalError, match="missing column"):
        discover_fleet(manifest)
    assert main(["fleet", str(manifest), "--out", str(tmp_path / "o")]) == 2
    (tmp_path / "file").write_text("")
    assert main(["fleet", str(tmp_path), "--out", str(tmp_path / "file")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert all(line.startswith("graphcal: error:") for line in err) and len(err) == 3
    assert not (tmp_path / "o").exists()


def _wait_for_results(logs_dir: Path, count: int, process, timeout: float = 300.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if len(list(logs_dir.glob("*/*.json"))) >= count or process.poll() is not None:
            return
        time.sleep(0.2)
    raise AssertionError(f"fewer than {count} results after {timeout:.0f} s")


@pytest.mark.slow
def test_fleet_interrupted_and_resumed_finds_the_change(fleet_dir, tmp_path):
    """The acceptance run: interrupted after about half its logs, then restarted; nothing
    finished is recomputed, every log's theta is within 3σ of its truth, and the change is
    found on v3, day 3, and nowhere else."""
    out = tmp_path / "out"
    command = [
        sys.executable,
        "-m",
        "graphcal.cli",
        "fleet",
        str(fleet_dir),
        "--out",
        str(out),
        "--workers",
        "2",
        "--no-progress-bar",
    ]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_results(out / "logs", VEHICLES * DAYS // 2, process)
        process.send_signal(signal.SIGINT)
        process.wait(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    finished = {p: p.read_bytes() for p in (out / "logs").glob("*/*.json")}
    assert 0 < len(finished) < VEHICLES * DAYS
    assert not list((out / "logs").glob("*/.*"))  # no half-written file

    from graphcal.fleet.run import FleetOptions, run_fleet

    run = run_fleet(fleet_dir, out, options=FleetOptions(workers=2))
    assert run.reused == len(finished)
    assert run.computed == VEHICLES * DAYS - len(finished)
    assert all(path.read_bytes() == text for path, text in finished.items())
    assert run.failed == 0

    truth = pd.read_csv(fleet_dir / "fleet_truth.csv").set_index(["vehicle", "day"])
    for result in run.results:
        true = truth.loc[(result["vehicle"], result["day"]), list(PARAMETER_NAMES)].to_numpy()
        sigma = np.sqrt(np.diag(result["posterior_covariance"]))
        assert np.all(np.abs(np.asarray(result["posterior_theta"]) - true) < 3 * sigma), result
    changes = [(h.vehicle, c.day, c.parameter) for h in run.histories for c in h.changes]
    assert changes == [("v3", "day3", "c_e")]
    assert not any(h.flags for h in run.histories)
    table = pd.read_csv(out / "fleet.csv")
    assert len(table) == VEHICLES * DAYS and (table["status"] == "ok").all()
    vehicles = pd.read_csv(out / "vehicles.csv").set_index("vehicle")
    assert vehicles.loc["v3", "current_since"] == "day3"
    assert (out / "fleet.png").stat().st_size > 0


@pytest.mark.slow
def test_fleet_on_a_separately_started_scheduler(fleet_dir, tmp_path):
    """The changed vehicle's days through `dask scheduler` and two `dask worker` processes
    started by hand, reached by address, from a CSV manifest that also names a broken log: it
    fails alone, with its one-line reason, and the change is found as on the local cluster.
    (v3 alone: the unchanged vehicles' days are the local cluster's test; 9 logs took 51 s.)"""
    broken = tmp_path / "broken.csv"
    broken.write_text("t,px\n0,1\n")
    manifest = tmp_path / "fleet.csv"
    rows = ["vehicle,day,path"]
    logs = [log for log in discover_fleet(fleet_dir) if log.vehicle == "v3"]
    rows += [f"{log.vehicle},{log.day},{log.path}" for log in logs]
    rows.append(f"v9,day1,{broken}")
    manifest.write_text("\n".join(rows) + "\n")
    dask = shutil.which("dask", path=str(Path(sys.executable).parent)) or shutil.which("dask")
    assert dask is not None, "the dask command comes with dask[distributed]"
    scheduler_file = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    processes = [
        subprocess.Popen(
            [
                dask,
                "scheduler",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(scheduler_file),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    ]
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(scheduler_file.read_text())["address"]
        for _ in range(2):
            processes.append(
                subprocess.Popen(
                    [dask, "worker", address, "--nthreads", "1", "--no-dashboard"],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    env=env,
                )
            )
        from distributed import Client

        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        from graphcal.fleet.run import FleetOptions, run_fleet

        run = run_fleet(manifest, tmp_path / "out", options=FleetOptions(scheduler=address))
    finally:
        for process in processes[::-1]:
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
    failed = [r for r in run.results if r["status"] != "ok"]
    assert [r["vehicle"] for r in failed] == ["v9"]
    assert (tmp_path / "out" / "logs" / "v9" / "day1.json").exists()  # the log's own failure
    assert failed[0]["reason"] and "\n" not in failed[0]["reason"]
    assert run.computed == DAYS + 1
    changes = [(h.vehicle, c.day, c.parameter) for h in run.histories for c in h.changes]
    assert changes == [("v3", "day3", "c_e")]
    flagged = {h.vehicle for h in run.histories if h.flags}
    assert flagged == {"v9"}  # its failed day, nothing else


def test_a_vehicle_profile_in_the_tree_sets_that_vehicles_settings(tmp_path):
    from graphcal.fleet.run import _settings_per_log
    from graphcal.pipeline.configuration.settings import Settings

    robot = Path(__file__).resolve().parents[1] / "data" / "vehicles" / "delivery_robot.toml"
    for vehicle in ("car", "robot"):
        (tmp_path / vehicle).mkdir()
        (tmp_path / vehicle / "day1.csv").write_text("t\n")
    shutil.copy(robot, tmp_path / "robot" / "vehicle.toml")
    logs = discover_fleet(tmp_path)
    car, bot = _settings_per_log(logs, Settings(), keep=())
    np.testing.assert_allclose(car.joint.theta_initial, THETA_NOMINAL)
    np.testing.assert_allclose(bot.joint.theta_initial, [0.5, 0.0, 0.2, 0.0])


def test_a_log_the_worker_cannot_see_is_retried_not_kept(tmp_path):
    from graphcal.fleet.sources import FleetLog
    from graphcal.fleet.task import calibrate_fleet_log
    from graphcal.pipeline.configuration.settings import Settings

    result = calibrate_fleet_log(FleetLog("v", "d", tmp_path / "gone.csv"), Settings(), "k")
    assert result["status"] == "failed" and result["retry"] is True
    assert "not found" in result["reason"]


#: The smallest fleet that still has logs left when the first one finishes (1 km days).
SMALL_DAYS, SMALL_KM = 6, 1.0
#: A progress line of the CLI (``[   1.2 s] ...``); everything else on stderr is a message.
PROGRESS = re.compile(r"^\[\s*\d+\.\d s\] ")


@pytest.fixture(scope="module")
def small_fleet(tmp_path_factory) -> Path:
    from graphcal.simulate.fleet import simulate_fleet

    root = tmp_path_factory.mktemp("small") / "fleet"
    simulate_fleet(root, 1, SMALL_DAYS, SMALL_KM, seed=1)
    return root


def _interrupt_after_first_log(command: list[str]) -> tuple[int, list[str]]:
    """Run ``command`` in its own process group, send SIGINT to the whole group (as Ctrl-C
    in a terminal does) once its first log is done; its exit status and stderr lines."""
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    lines = []
    try:
        for line in process.stderr:
            lines.append(line.rstrip("\n"))
            if "fleet: 1/" in line:
                os.killpg(process.pid, signal.SIGINT)
                break
        lines += process.communicate(timeout=60)[1].splitlines()
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    return process.returncode, lines


@pytest.mark.slow
def test_ctrl_c_during_a_fleet_run_gives_one_line_and_the_rerun_resumes(small_fleet, tmp_path):
    """Ctrl-C reaches graphcal and the local cluster's workers alike (one process group):
    the user reads one line, the run exits with 130, leaves no half-written result, and
    running it again calibrates only what is missing."""
    out = tmp_path / "out"
    command = [
        sys.executable,
        "-m",
        "graphcal.cli",
        "fleet",
        str(small_fleet),
        "--out",
        str(out),
        "--workers",
        "2",
        "--no-progress-bar",
    ]
    status, lines = _interrupt_after_first_log(command)
    messages = [line for line in lines if not PROGRESS.match(line)]
    assert status == 130, lines
    assert len(messages) == 1 and messages[0].startswith("graphcal: interrupted"), lines
    assert lines[-1] == messages[0]
    finished = {p: p.read_bytes() for p in (out / "logs").glob("*/*.json")}
    assert finished and not list((out / "logs").glob("*/.*"))  # no half-written file

    from graphcal.fleet.run import FleetOptions, run_fleet

    run = run_fleet(small_fleet, out, options=FleetOptions(workers=2))
    assert run.reused == len(finished) and run.computed == SMALL_DAYS - len(finished)
    assert run.failed == 0 and len(pd.read_csv(out / "fleet.csv")) == SMALL_DAYS
    assert all(path.read_bytes() == text for path, text in finished.items())


@pytest.mark.slow
def test_an_interrupted_run_says_how_to_resume(small_fleet, tmp_path):
    """What ``graphcal: interrupted`` can name: how many results are kept, and that the
    same command continues."""
    from graphcal.fleet.run import FleetOptions, run_fleet

    def interrupt_after_first(line: str) -> None:
        if "fleet: 1/" in line:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(KeyboardInterrupt) as raised:
        run_fleet(
            small_fleet,
            tmp_path / "out",
            options=FleetOptions(workers=2),
            progress=interrupt_after_first,
        )
    kept = len(list((tmp_path / "out" / "logs").glob("*/*.json")))
    assert str(raised.value).startswith(f"{kept} of {SMALL_DAYS} logs' results kept in ")
    assert "run the same command again" in str(raised.value)


@pytest.mark.slow
def test_fleet_csv_gives_each_day_its_verdicts_and_honest_sigmas(tmp_path):
    """A 4 km day (issue 26's case, on the rigid car of issue 36: seed 20; before issue 43
    t_r was not observable from its 4 selected segments and d, held at t_r's prior, more than
    5 of its σ from its truth and "calibrated"). fleet.csv gives each parameter's verdict as
    the day's run gave it (a result kept from an earlier run in its own, older wording),
    lists the parameters not calibrated, and every value is within 3 of its σ of the truth."""
    from graphcal.fleet.report import write_fleet_report
    from graphcal.fleet.sources import FleetLog
    from graphcal.fleet.task import calibrate_fleet_log
    from graphcal.pipeline.configuration.settings import Settings
    from graphcal.simulate.drive import simulate_drive, write_synthetic_drive

    drive = simulate_drive(length_km=4.0, seed=20)
    path = tmp_path / "v1" / "day2.csv"
    write_synthetic_drive(drive, path)
    result = calibrate_fleet_log(FleetLog("v1", "day2", path), Settings(), "key")
    older = "calibrated given t_r = prior (σ conditional)"
    kept = {**result, "day": "day1", "verdicts": {**result["verdicts"], "d": older}}
    write_fleet_report([kept, result], [], tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / "fleet.csv").set_index("day")
    assert table.loc["day1", "verdict_d"] == older
    row = table.loc["day2"]
    left_out = [] if pd.isna(row["not_calibrated"]) else row["not_calibrated"].split()
    for i, name in enumerate(("c_e", "c_d", "t_r", "d")):
        verdict = row[f"verdict_{name}"]
        assert verdict == result["verdicts"][name]
        assert (verdict == "calibrated") == (name not in left_out), (name, verdict, left_out)
        assert abs(row[name] - drive.theta_true[i]) < 3 * row[f"sigma_{name}"], name
