"""A fleet run's summary puts each log in one of calibrated now, kept or failed (issue 44,
row 6: 2 good and 2 broken logs gave "4 calibrated now, 0 kept from an earlier run, 2
failed")."""

from __future__ import annotations

import pytest

from graphcal.cli import main


@pytest.mark.slow
def test_broken_logs_are_not_counted_as_calibrated(tmp_path, capsys):
    fleet = tmp_path / "fleet"
    args = ["simulate", "--fleet", str(fleet), "--vehicles", "1", "--days", "2"]
    assert main([*args, "--change", "none", "--length-km", "1.5"]) == 0
    for day in ("day3", "day4"):
        (fleet / "v1" / f"{day}.csv").write_text("t,px\n0,1\n")
    out = tmp_path / "out"
    main(["fleet", str(fleet), "--out", str(out), "--workers", "1"])
    printed = capsys.readouterr()
    head = next(
        line for line in (printed.out + printed.err).splitlines() if "logs of 1 vehicles" in line
    )
    assert "2 calibrated now, 0 kept from an earlier run, 2 failed" in head, head
    main(["fleet", str(fleet), "--out", str(out), "--workers", "1"])
    printed = capsys.readouterr()
    head = next(
        line for line in (printed.out + printed.err).splitlines() if "logs of 1 vehicles" in line
    )
    assert "0 calibrated now, 2 kept from an earlier run, 2 failed" in head, head
