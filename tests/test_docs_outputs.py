"""The docs' commands run in any order in one folder, and quote what they print (issue 44,
rows 10–11: the README's robot example wrote ``robot/``, docs/real.md then used ``--out
robot`` and was refused; docs/fleet.md wrote ``results/fleet``, then docs/import.md's
``--out results/`` was refused; docs/robots.md quoted validation errors no command printed)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from graphcal.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
ROBOT = ROOT / "data" / "vehicles" / "mocap_robot.toml"
#: Options whose value is a directory a command writes.
DIRECTORY_OUTPUTS = re.compile(r"--(?:out|streams|fleet)\s+(\S+)")


def _directory_outputs() -> dict[str, set[str]]:
    """Per doc, the directories its shell commands write (a CSV ``--out`` left out: graphcal
    replaces its own drive logs)."""
    found: dict[str, set[str]] = {}
    for doc in DOCS:
        if doc.name == "changes.md":
            continue
        blocks = re.findall(r"```(?:bash|sh)\n(.*?)```", doc.read_text(), re.DOTALL)
        for line in "\n".join(blocks).splitlines():
            if not line.lstrip().startswith("graphcal "):
                continue
            for value in DIRECTORY_OUTPUTS.findall(line.split("#")[0]):
                if not value.endswith((".csv", ".json")):
                    found.setdefault(value.rstrip("/"), set()).add(doc.name)
    return found


def test_no_two_docs_write_the_same_or_a_nested_directory():
    outputs = _directory_outputs()
    assert outputs, "no commands found"
    for path, docs in outputs.items():
        assert len(docs) == 1, f"{path} written by {sorted(docs)}"
        for other, other_docs in outputs.items():
            if other != path and other.startswith(f"{path}/"):
                assert docs == other_docs, f"{other} ({other_docs}) inside {path} ({docs})"


@pytest.mark.slow
def test_robots_md_quotes_the_readme_robot_example(tmp_path, capsys, monkeypatch):
    pytest.importorskip("rosbags")
    monkeypatch.chdir(tmp_path)
    simulate = ["simulate", "--vehicle", str(ROBOT), "--streams", "robot", "--bag", "ros2"]
    assert main(simulate) == 0
    capsys.readouterr()
    calibrate = ["calibrate", "robot/drive_ros2", "--vehicle", str(ROBOT), "--out", "results"]
    assert main(calibrate) == 0
    printed = capsys.readouterr().out
    rows = dict(
        re.findall(r"^(nominal|calibrated|reachable \(true theta\))\s+(\S+)$", printed, re.M)
    )
    quoted = (ROOT / "docs" / "robots.md").read_text()
    expected = (
        f"{rows['nominal']} mm with the datasheet theta, {rows['calibrated']} mm calibrated, "
        f"{rows['reachable (true theta)']} mm"
    )
    assert expected in " ".join(quoted.split()), expected
