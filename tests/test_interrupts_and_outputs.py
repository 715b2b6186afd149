"""What a new user hits around a run (issue 35): Ctrl-C, an output path onto a file graphcal
did not write, the modes of what it writes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from graphcal.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"
CAN_MANIFEST = ROOT / "data" / "real" / "comma2k19" / "can.toml"


def test_import_refuses_to_overwrite_a_file_it_did_not_write(tmp_path, capsys):
    mine = tmp_path / "afile.txt"
    mine.write_text("my notes\n")
    assert main(["import", str(CAN_MANIFEST), "--out", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "would overwrite a file graphcal did not write" in err, err
    assert mine.read_text() == "my notes\n"


def test_import_replaces_its_own_earlier_output(tmp_path, capsys):
    out = tmp_path / "drive.csv"
    assert main(["import", str(CAN_MANIFEST), "--out", str(out)]) == 0
    first = out.read_bytes()
    assert main(["import", str(CAN_MANIFEST), "--out", str(out)]) == 0
    assert out.read_bytes() == first


def test_a_result_directory_has_the_mode_of_the_users_umask(tmp_path):
    """As ``mkdir`` would make it (``mkdtemp``'s 0700 locked a shared results folder)."""
    out = tmp_path / "results"
    script = (
        "import os; os.umask(0o022)\n"
        "from graphcal.files import atomic_write_text\n"
        "from graphcal.report.result_set import replace_result_set\n"
        f"replace_result_set({str(out)!r}, lambda d: [atomic_write_text(d / 'a.json', '{{}}')])"
    )
    subprocess.run([sys.executable, "-c", script], check=True, capture_output=True)
    assert out.stat().st_mode & 0o777 == 0o755
    assert (out / "a.json").stat().st_mode & 0o777 == 0o644


def _interrupted(
    arguments: list[str], after: float, cwd: Path, said: str | None = None
) -> subprocess.CompletedProcess:
    """``graphcal ARGUMENTS`` run with its output in files, sent Ctrl-C (SIGINT to its process
    group, as a terminal does) ``after`` seconds in — after it has ``said`` that (a progress
    line's words), where given: a loaded machine took over 5 s to start a run that prints
    ``loaded`` 2 s in on an idle one, so a clock from the start missed the phase it meant."""
    out, err = cwd / "stdout.txt", cwd / "stderr.txt"
    with out.open("w") as stdout, err.open("w") as stderr:
        process = subprocess.Popen(
            [sys.executable, "-m", "graphcal.cli", *arguments],
            stdout=stdout,
            stderr=stderr,
            cwd=cwd,
            start_new_session=True,
        )
        deadline = time.monotonic() + 120.0
        while said is not None and said not in err.read_text() and process.poll() is None:
            if time.monotonic() > deadline:
                break
            time.sleep(0.02)
        time.sleep(after)
        os.killpg(process.pid, signal.SIGINT)
        code = process.wait(timeout=120)
    return subprocess.CompletedProcess(arguments, code, out.read_text(), err.read_text())


def _skip_before_the_interpreter(run: subprocess.CompletedProcess) -> None:
    """Skip a run whose Ctrl-C came while Python itself was starting (a loaded machine, an
    interrupt 0.3 s in): the interpreter's own fatal error, before any of graphcal ran."""
    if "Fatal Python error: init_import_site" in run.stderr:
        pytest.skip("Ctrl-C came before the interpreter had started: nothing of graphcal's")


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.parametrize(
    ("after", "method", "said"),
    [(0.3, "joint", None), (1.6, "joint", None), (3.0, "staged", "loaded")],
)
def test_ctrl_c_during_calibrate_says_one_line_exits_130_and_writes_nothing(
    tmp_path, after, method, said
):
    """At 0.3 s GTSAM is loading, at 1.6 s the whole-log solve runs on forked workers, 3 s
    after the staged method loaded its log its step-1 batch solves in a process pool (its
    220 batches of the sample take about a minute; the joint method's, solved from the
    segments' systems, end the whole run within 5 s)."""
    arguments = ["calibrate", str(SAMPLE), "--method", method, "--batches", "1000"]
    run = _interrupted([*arguments, "--workers", "2", "--out", "results"], after, tmp_path, said)
    if run.returncode == 0:  # finished before the interrupt: nothing to judge
        pytest.skip(f"the run ended within {after} s")
    _skip_before_the_interpreter(run)
    assert run.returncode == 130, run.stderr
    assert run.stderr.strip().splitlines()[-1].startswith("graphcal: interrupted"), run.stderr
    assert "Traceback" not in run.stderr, run.stderr
    if said is not None:  # what it said before is kept
        assert said in run.stderr, run.stderr
    assert not (tmp_path / "results").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.parametrize("after", [0.3, 1.0])
def test_ctrl_c_during_import_says_one_line_and_writes_nothing(tmp_path, after):
    run = _interrupted(["import", str(CAN_MANIFEST), "--out", "drive.csv"], after, tmp_path)
    if run.returncode == 0:
        pytest.skip(f"the import ended within {after} s")
    _skip_before_the_interpreter(run)
    assert run.returncode == 130, run.stderr
    assert "Traceback" not in run.stderr, run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stderr.txt", "stdout.txt"]


def _ctrl_c_in_the_worker(k: int) -> int:
    """A task whose worker gets Ctrl-C (its own SIGINT: it dies of it, as in a terminal)."""
    if k == 3:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)
    return k


def test_a_pool_broken_by_ctrl_c_ends_the_run_as_an_interrupt():
    """Under load the workers can die of Ctrl-C before the parent sees its own SIGINT: the
    pool breaks first. That is still an interrupt (exit 130, one line), not a crash."""
    from graphcal.pipeline.solvers.parallel import map_tasks

    with pytest.raises(KeyboardInterrupt):
        map_tasks(_ctrl_c_in_the_worker, [(k,) for k in range(8)], workers=2)


def test_a_pool_broken_by_ctrl_c_is_an_interrupt_where_the_host_reaps_the_workers():
    """A host that reaps its children as they end (SIGCHLD ignored; the full test suite
    did, on one run) leaves no exit code to read: the workers' own flag tells the Ctrl-C."""
    from graphcal.pipeline.solvers.parallel import map_tasks

    previous = signal.signal(signal.SIGCHLD, signal.SIG_IGN)
    try:
        with pytest.raises(KeyboardInterrupt):
            map_tasks(_ctrl_c_in_the_worker, [(k,) for k in range(8)], workers=2)
    finally:
        signal.signal(signal.SIGCHLD, previous)
