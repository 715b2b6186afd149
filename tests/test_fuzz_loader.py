"""Fuzzing the drive-log loader: whatever the file holds, one clear line or a finite result.

Each case writes a damaged copy of a valid log (random bytes, a truncated file, swapped,
scaled or garbled columns, deleted or duplicated rows) and runs the command line on it. The
outcome must be exit 0 with finite output, or exit 2 with one line on stderr and no result
file — never a traceback. CI runs ``FUZZ_CASES`` (default 144: 16 of each of the 9 kinds of
damage, taken in turn) cases with a fixed seed; a longer run: ``GRAPHCAL_FUZZ_CASES=5000
GRAPHCAL_FUZZ_SEED=7 python -m pytest -m slow tests/test_fuzz_loader.py``.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main

FUZZ_CASES = int(os.environ.get("GRAPHCAL_FUZZ_CASES", "144"))
FUZZ_SEED = int(os.environ.get("GRAPHCAL_FUZZ_SEED", "20261123"))
#: The kinds of damage :func:`_damaged` makes; case ``i`` makes kind ``i % KINDS``.
KINDS = 9
#: Every this-many-th case also runs a whole-log calibration (slower) and checks its files;
#: 16 is coprime to :data:`KINDS`, so the default sweep calibrates each kind once.
CALIBRATE_EVERY = 16


def _damaged(valid: pd.DataFrame, text: str, kind: int, rng: np.random.Generator) -> bytes:
    """A randomly damaged version of a valid log, by damage of ``kind`` (0 to 8)."""
    frame = valid.copy()
    columns = list(frame.columns)
    if kind == 0:  # random bytes
        return rng.integers(0, 256, rng.integers(0, 2000)).astype(np.uint8).tobytes()
    if kind == 1:  # truncated anywhere
        data = text.encode()
        return data[: rng.integers(0, len(data))]
    if kind == 2:  # two columns swapped (the header stays)
        a, b = rng.choice(len(columns), 2, replace=False)
        frame[[columns[a], columns[b]]] = frame[[columns[b], columns[a]]].to_numpy()
    elif kind == 3:  # a column scaled: a unit mistake or a sign flip
        column = columns[rng.integers(len(columns))]
        frame[column] *= rng.choice([-1.0, 1e-3, 0.01, 0.1, 10.0, 57.29578, 100.0, 1000.0])
    elif kind == 4:  # rows deleted
        frame = frame.drop(index=rng.choice(len(frame), rng.integers(1, 50), replace=False))
    elif kind == 5:  # rows duplicated
        rows = rng.choice(len(frame), rng.integers(1, 20))
        frame = pd.concat([frame, frame.iloc[rows]]).sort_index(kind="stable")
    elif kind == 6:  # one value garbled
        value = rng.choice(["abc", "", "nan", "1e400", "-inf", "1,5", "0x10", " "])
        frame = frame.astype(object)
        frame.iat[rng.integers(len(frame)), rng.integers(len(columns))] = value
    elif kind == 7:  # a column dropped or renamed
        column = columns[rng.integers(len(columns))]
        if rng.random() < 0.5:
            frame = frame.drop(columns=column)
        else:
            frame = frame.rename(columns={column: column.upper()})
    else:  # a short log: only the first rows
        frame = frame.iloc[: rng.integers(0, 200)]
    return frame.to_csv(index=False, float_format="%.17g").encode()


@pytest.fixture(scope="module")
def valid(drive) -> pd.DataFrame:
    """The first 90 s of the test drive (about 1 km), a valid log."""
    return drive.measured.to_dataframe().iloc[:3600].reset_index(drop=True)


@pytest.mark.slow  # a sweep of hundreds of runs; the README's test command and CI run it
@pytest.mark.ci
def test_the_loader_never_fails_with_a_traceback(valid, tmp_path, capsys):
    rng = np.random.default_rng(FUZZ_SEED)
    text = valid.to_csv(index=False, float_format="%.17g")
    outcomes = {0: 0, 2: 0}
    for case in range(FUZZ_CASES):
        path = tmp_path / f"case{case}.csv"
        path.write_bytes(_damaged(valid, text, case % KINDS, rng))
        calibrate = case % CALIBRATE_EVERY == 0
        out = tmp_path / f"out{case}"
        args = ["calibrate", str(path), "--out", str(out), "--batches", "0", "--workers", "1"]
        args = args if calibrate else ["check", str(path)]
        status = main(args)
        printed = capsys.readouterr()
        assert status in (0, 2), (case, status, printed.err)
        outcomes[status] += 1
        assert "Traceback" not in printed.err, (case, printed.err)
        if status == 2:  # one error line (after calibrate's progress lines, if any)
            errors = [line for line in printed.err.splitlines() if line.startswith("graphcal:")]
            assert len(errors) == 1 and printed.err.endswith(errors[0] + "\n"), (case, printed.err)
            assert not out.exists(), case
            continue
        assert "nan" not in printed.out.lower() and "inf " not in printed.out.lower(), case
        if calibrate:
            doc = json.loads((out / "calibration.json").read_text())
            assert all(math.isfinite(v) for v in doc["theta"].values()), case
    # Both outcomes occur: the damage is neither always fatal nor always harmless.
    assert outcomes[0] > 0 and outcomes[2] > 0, outcomes
