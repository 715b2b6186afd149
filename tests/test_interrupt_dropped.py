"""A Ctrl-C that Python drops (raised inside a fork's callback, a finalizer) still ends the
run: exit 130, one line, nothing written (issue 44, row 3)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from graphcal.files import atomic_write_text
from graphcal.interrupt import remembering_interrupts

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"

# SIGINT sent from inside an at-fork callback (as logging's ``_releaseLock`` after the
# worker pool's fork): Python prints "Exception ignored in" and the run used to go on.
_DROPPED_AT_FORK = """
import os, signal, sys
from graphcal.cli import main
fired = []
def interrupt_once():
    if not fired:
        fired.append(1)
        os.kill(os.getpid(), signal.SIGINT)
os.register_at_fork(after_in_parent=interrupt_once)
sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_dropped_in_a_fork_callback_still_interrupts(tmp_path):
    run = subprocess.run(
        [sys.executable, "-c", _DROPPED_AT_FORK, "calibrate", str(SAMPLE)]
        + ["--batches", "4", "--workers", "2", "--out", "results"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 130, run.stderr
    assert run.stderr.strip().splitlines()[-1] == "graphcal: interrupted", run.stderr
    assert "Traceback" not in run.stderr and "Exception ignored" not in run.stderr, run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [], list(tmp_path.iterdir())


def test_a_dropped_ctrl_c_writes_no_file(tmp_path):
    """The flag alone (its KeyboardInterrupt lost) keeps a result file from appearing."""
    import graphcal.interrupt as interrupt

    with remembering_interrupts():
        interrupt._requested = True  # as the handler leaves it when its raise was dropped
        with pytest.raises(KeyboardInterrupt):
            atomic_write_text(tmp_path / "a.json", "{}")
    assert list(tmp_path.iterdir()) == []
