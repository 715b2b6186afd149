"""The code blocks of README.md and docs/*.md, run as written, so that the docs cannot drift.

Convention: a fenced block whose language is ``python``, ``bash``, ``sh`` or ``console`` and
whose fence is directly preceded by the line ``<!-- runnable -->`` (an HTML comment: GitHub
shows nothing) is run here, the way a user would run it pasted into a file or a terminal:

- in a fresh temporary directory holding a copy of the repository's ``data/``, so that
  ``data/sample_drive.csv`` resolves and nothing in the checkout is touched;
- a Python block as a script, ``python script.py`` in a subprocess (a Dask example without
  ``if __name__ == "__main__":`` fails here as it does for the user);
- a shell block with ``bash -euo pipefail``, the running interpreter's ``bin/`` first on
  ``PATH`` (``graphcal``, ``python``); in a ``console`` block only the lines after a ``$ ``
  prompt are run.

Each block must finish within ``TIMEOUT`` seconds: give examples small drives. Install
commands, output listings and commands that need files the user brings are left unmarked.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MARKER = "<!-- runnable -->"
LANGUAGES = {"python", "bash", "sh", "console"}
TIMEOUT = 180.0  # s, per block (the fleet example: 40 s on the loaded 2-core machine)

FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})\s*(?P<language>[\w+-]*)")


@dataclass(frozen=True)
class Block:
    document: Path
    line: int  # 1-based line of the opening fence
    language: str
    code: str

    @property
    def name(self) -> str:
        return f"{self.document.relative_to(ROOT)}:{self.line}"


def runnable_blocks(document: Path) -> list[Block]:
    """The blocks of ``document`` marked runnable; a marker before anything else is an error."""
    lines = document.read_text(encoding="utf-8").splitlines()
    blocks = []
    for i, line in enumerate(lines):
        if line.strip() != MARKER:
            continue
        where = f"{document.relative_to(ROOT)}:{i + 1}"
        opening = FENCE.match(lines[i + 1]) if i + 1 < len(lines) else None
        if opening is None or opening["language"] not in LANGUAGES:
            raise ValueError(f"{where}: {MARKER} not followed by a {sorted(LANGUAGES)} fence")
        indent, fence = opening["indent"], opening["fence"]
        body = []
        for j in range(i + 2, len(lines)):
            if lines[j].strip().startswith(fence) and not lines[j].strip().strip(fence[0]):
                break
            body.append(lines[j][len(indent) :] if lines[j].startswith(indent) else lines[j])
        else:
            raise ValueError(f"{where}: the block is not closed")
        blocks.append(Block(document, i + 2, opening["language"], "\n".join(body) + "\n"))
    return blocks


BLOCKS = [block for document in DOCUMENTS for block in runnable_blocks(document)]


def test_the_docs_have_runnable_blocks():
    """Guards the parser: a marker convention nobody's block follows would test nothing."""
    assert any(
        block.document.name == "README.md" and "run_calibration" in block.code for block in BLOCKS
    )
    assert any(block.document.name == "fleet.md" and "run_fleet" in block.code for block in BLOCKS)


def shell_code(block: Block) -> str:
    if block.language != "console":
        return block.code
    commands = [line[2:] for line in block.code.splitlines() if line.startswith("$ ")]
    return "\n".join(commands) + "\n"


@pytest.mark.slow
@pytest.mark.parametrize("block", BLOCKS, ids=[block.name for block in BLOCKS])
def test_block_runs_as_written(block: Block, tmp_path: Path):
    shutil.copytree(ROOT / "data", tmp_path / "data")
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.pop("PYTHONPATH", None)  # graphcal as installed, like the user's
    if block.language == "python":
        script = tmp_path / "example.py"
        script.write_text(block.code, encoding="utf-8")
        command = [sys.executable, script.name]
    else:
        script = tmp_path / "example.sh"
        script.write_text(shell_code(block), encoding="utf-8")
        command = ["bash", "-euo", "pipefail", script.name]
    try:
        done = subprocess.run(
            command,
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            check=False,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"{block.name} took longer than {TIMEOUT:.0f} s: give it a smaller drive")
    if done.returncode != 0:
        pytest.fail(
            f"{block.name} ({block.language}) exited with status {done.returncode}\n"
            f"--- code\n{block.code}--- stdout (end)\n{done.stdout[-3000:]}\n"
            f"--- stderr (end)\n{done.stderr[-3000:]}",
            pytrace=False,
        )
