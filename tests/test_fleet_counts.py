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


def test_a_small_synthetic_fleet_needs_no_change_option(tmp_path, capsys):
    # The default change (v3 from day 3) applies where the fleet has that vehicle and day:
    # `--vehicles 2` wrote nothing and said the change was outside the fleet.
    small = ["simulate", "--fleet", str(tmp_path / "small"), "--vehicles", "2", "--days", "2"]
    assert main([*small, "--length-km", "0.3"]) == 0
    assert "(no change)" in capsys.readouterr().err
    three = ["simulate", "--fleet", str(tmp_path / "three"), "--vehicles", "3", "--days", "3"]
    assert main([*three, "--length-km", "0.3"]) == 0
    assert "(c_e -3 mm on v3 from day3)" in capsys.readouterr().err
    asked = [*small[:2], str(tmp_path / "asked"), *small[3:], "--change", "3:3:-3"]
    assert main([*asked, "--length-km", "0.3"]) == 2
