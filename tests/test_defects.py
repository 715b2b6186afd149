"""Degraded synthetic drives: each defect of real logs, its size, the truth kept, the seeds."""

from __future__ import annotations

import json

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.log.consistency import runs
from graphcal.log.drive_log import write_drive_log
from graphcal.log.load import load_drive_log
from graphcal.log.validation import validate_frame
from graphcal.simulate.defect_effects import ar1, gauss_markov
from graphcal.simulate.defects import (
    DEFECT_NAMES,
    DEFECTS_IN_ALL,
    HEADING_WHITE,
    Defects,
    degrade,
    parse_defects,
)
from graphcal.simulate.drive import SyntheticDrive, read_sidecar, simulate_drive


@pytest.fixture(scope="module")
def short() -> SyntheticDrive:
    """A 2 km city drive (about 230 s at 40 Hz) at the paper's noise levels."""
    return simulate_drive(2.0, seed=4)


def _wheels(drive: SyntheticDrive) -> np.ndarray:
    return np.column_stack([drive.measured.n_rl, drive.measured.n_rr])


def _white(clean: SyntheticDrive) -> np.ndarray:
    """The drive's own white wheel noise (measured − truth)."""
    return _wheels(clean) - np.column_stack([clean.truth.n_rl, clean.truth.n_rr])


def _positions(drive: SyntheticDrive) -> np.ndarray:
    return np.column_stack([drive.measured.px, drive.measured.py])


def test_no_defects_give_the_drive_back(short):
    same = degrade(short, Defects(), seed=1)
    for column in ("t", "px", "py", "psi", "n_rl", "n_rr", "beta", "ay"):
        np.testing.assert_array_equal(
            getattr(same.measured, column), getattr(short.measured, column)
        )
    assert same.defects == Defects() and same.defects.names == ()


@pytest.mark.parametrize("name", DEFECT_NAMES)
def test_each_defect_keeps_the_truth_and_changes_the_log(short, name):
    degraded = degrade(short, parse_defects(name), seed=2)
    assert degraded.truth is short.truth
    np.testing.assert_array_equal(degraded.theta_true, short.theta_true)
    assert degraded.defects.names == (name,) and degraded.defect_seed == 2
    assert len(degraded.measured) == len(short.measured)
    changed = [
        c
        for c in ("px", "py", "psi", "n_rl", "n_rr")
        if not np.array_equal(getattr(degraded.measured, c), getattr(short.measured, c))
    ]
    assert changed, name
    np.testing.assert_array_equal(degraded.measured.beta, short.measured.beta)


def test_outliers_move_half_a_percent_of_the_fixes_by_10_to_50_m(short):
    degraded = degrade(short, parse_defects("outliers"), seed=3)
    off = np.hypot(*(_positions(degraded) - _positions(short)).T)
    moved = off > 0
    assert moved.sum() == round(0.005 * len(off))
    assert off[moved].min() >= 10.0 and off[moved].max() <= 50.0
    direction = np.arctan2(*(_positions(degraded) - _positions(short))[moved].T[::-1])
    assert np.ptp(direction) > np.pi  # all around, not one way


def test_gnss_rate_writes_each_fix_once_at_its_own_time(short):
    """gnss10hz: a 10 Hz fix in every 4th row of the 40 Hz log, at its own time within the
    step before (``t_fix``), the other rows without a position; as a CSV and back alike."""
    sparse = degrade(short, parse_defects("gnss10hz"), seed=4).measured
    fixes = sparse.position_measured
    assert fixes.mean() == pytest.approx(0.25, abs=0.01)
    assert sparse.fix_lag is not None and np.all(sparse.fix_lag[fixes] < 0.025)
    interpolated = degrade(short, parse_defects("interpolated"), seed=4).measured
    assert interpolated.measured is None
    # the same fixes: between them the track is the interpolated log itself, and a fix row
    # holds the fix, not the interpolated value at the row (off by the travel within its lag
    # and a share of the next fix's noise)
    np.testing.assert_array_equal(sparse.px[~fixes], interpolated.px[~fixes])
    apart = np.hypot(sparse.px - interpolated.px, sparse.py - interpolated.py)[fixes]
    assert (apart > 0).mean() > 0.99 and np.all(apart < 1.0)


def test_gnss_rate_interpolates_and_hold_repeats_the_fixes(short):
    interpolated = degrade(short, parse_defects("interpolated"), seed=4).measured
    held = degrade(short, parse_defects("hold"), seed=4).measured
    # Linear between 10 Hz fixes: of four 40 Hz steps, the one across a fix differs from the
    # steps before and after it, and the other two pairs of steps are equal.
    steps = np.diff(interpolated.px)
    kinks = np.abs(np.diff(steps)) > 1e-9
    assert kinks.mean() == pytest.approx(0.5, abs=0.01)
    assert max(b - a + 1 for a, b in runs(~kinks)) == 2
    # Held: the position changes only at a fix, and stays put in between.
    moves = np.diff(held.px) != 0
    assert moves.mean() == pytest.approx(0.25, abs=0.01)
    assert max(b - a + 1 for a, b in runs(~moves[8:])) == 3  # after the first fix
    assert np.std(held.px - short.truth.px) > np.std(interpolated.px - short.truth.px)


def test_outages_hold_the_last_fix_for_30_s_and_leave_the_heading(short):
    degraded = degrade(short, parse_defects("outages"), seed=5)
    frozen = np.concatenate([[False], np.diff(degraded.measured.px) == 0])
    spans = [(a, b) for a, b in runs(frozen) if b - a > 10]
    assert len(spans) == 2
    for a, b in spans:
        assert (b - a + 1) * 0.025 == pytest.approx(30.0, abs=0.05)
        assert np.all(degraded.measured.py[a - 1 : b + 1] == degraded.measured.py[a - 1])
    np.testing.assert_array_equal(degraded.measured.psi, short.measured.psi)
    assert degraded.measured.masked is None  # for the screen to find, not marked


def test_dropouts_are_masked_and_the_log_validates(short, tmp_path):
    degraded = degrade(short, parse_defects("dropouts=1,outliers"), seed=6).measured
    assert degraded.masked is not None
    spans = runs(degraded.masked)
    assert len(spans) == 1 and len(degraded.mask_notes) == 1
    a, b = spans[0]
    assert (b - a) * 0.025 == pytest.approx(30.0, abs=0.1)
    assert "dropout" in degraded.mask_notes[0]
    log = validate_frame(degraded.to_dataframe(), "dropouts.csv")
    assert log.masked[a : b + 1].all()
    path = tmp_path / "dropouts.csv"
    write_drive_log(degraded, path)
    assert load_drive_log(path).masked[a : b + 1].all()


def test_heading_bias_is_slow_and_the_white_noise_is_0_3_deg(short):
    degraded = degrade(short, parse_defects("heading_bias"), seed=7)
    error = degraded.measured.psi - short.truth.psi
    white = np.std(np.diff(error)) / np.sqrt(2.0)
    assert white == pytest.approx(HEADING_WHITE, rel=0.05)
    second = 40  # samples
    slow = np.convolve(error, np.ones(second) / second, mode="valid")
    assert np.ptp(slow) > 5 * HEADING_WHITE / np.sqrt(second)  # the bias moves
    assert np.abs(np.diff(slow)).max() < 0.01  # ... slowly


def test_gauss_markov_and_ar1_have_their_statistics():
    rng = np.random.default_rng(0)
    x = gauss_markov(3000, 0.025, 0.0015, -0.025 / np.log(0.995), rng, width=400)
    assert np.std(x[-1]) == pytest.approx(0.0015, rel=0.1)  # stationary from the start
    assert np.std(x[0]) == pytest.approx(0.0015, rel=0.1)
    lag1 = np.mean(x[1:] * x[:-1]) / np.mean(x**2)
    assert lag1 == pytest.approx(0.995, abs=0.001)
    walk = gauss_markov(2400, 0.025, 0.01, None, rng, width=400)
    assert np.std(walk[-1]) == pytest.approx(0.01 * np.sqrt(60.0), rel=0.1)
    # The chunked recursion equals the plain one.
    x = ar1(1000, 0.97, 1.0, 2.0, np.random.default_rng(1), 1)[:, 0]
    w = np.random.default_rng(1).standard_normal((1024, 1))[:1000, 0] * np.r_[2.0, np.ones(999)]
    plain = np.empty(1000)
    plain[0] = w[0]
    for k in range(1, 1000):
        plain[k] = 0.97 * plain[k - 1] + w[k]
    np.testing.assert_allclose(x, plain, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("latency", [0.05, 0.03])
def test_latency_delays_the_cumulative_rotation(short, latency):
    degraded = degrade(short, parse_defects(f"latency={latency}"), seed=8)
    rotation = _wheels(degraded) - _white(short)  # the drive's white noise taken out
    truth = np.column_stack([short.truth.n_rl, short.truth.n_rr])
    times = np.append(short.truth.t, short.truth.t[-1] + 0.025)
    true_cumulative = np.vstack([[0.0, 0.0], np.cumsum(truth, axis=0)])
    measured_cumulative = np.vstack([[0.0, 0.0], np.cumsum(rotation, axis=0)])
    later = times >= times[0] + latency
    for wheel in range(2):
        earlier = np.interp(times[later] - latency, times, true_cumulative[:, wheel])
        offset = measured_cumulative[later, wheel] - earlier
        np.testing.assert_allclose(offset, offset[0], atol=1e-9)


def test_lever_arm_is_ahead_in_the_body_frame(short):
    degraded = degrade(short, parse_defects("lever_arm"), seed=9)
    d = _positions(degraded) - np.column_stack([short.truth.px, short.truth.py])
    c, s = np.cos(short.truth.psi), np.sin(short.truth.psi)
    body = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    np.testing.assert_allclose(body.mean(axis=0), [1.2, 0.0], atol=0.01)
    arm = degrade(short, parse_defects("lever_arm=-0.5:0.3"), seed=9).defects.lever_arm
    assert arm == (-0.5, 0.3)


def test_ticks_quantize_the_cumulative_rotation(short):
    degraded = degrade(short, parse_defects("ticks"), seed=10)
    rotation = _wheels(degraded) - _white(short)
    counts = np.cumsum(rotation, axis=0) * 96
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    truth = np.cumsum(np.column_stack([short.truth.n_rl, short.truth.n_rr]), axis=0)
    assert np.abs(np.cumsum(rotation, axis=0) - truth).max() <= 1 / 96 + 1e-9
    other = degrade(short, parse_defects("ticks"), seed=11)
    assert not np.array_equal(_wheels(other), _wheels(degraded))  # another counter phase


def test_slip_is_a_slow_relative_scale_per_wheel(short):
    degraded = degrade(short, parse_defects("slip"), seed=12)
    truth = np.column_stack([short.truth.n_rl, short.truth.n_rr])
    scale = (_wheels(degraded) - _white(short))[:-1] / truth[:-1] - 1.0
    for wheel in range(2):
        s = scale[:, wheel]
        assert np.std(s) == pytest.approx(0.0015, rel=0.4)  # ~45 correlation times
        assert np.corrcoef(s[1:], s[:-1])[0, 1] == pytest.approx(0.995, abs=0.003)
    assert abs(np.corrcoef(scale[:, 0], scale[:, 1])[0, 1]) < 0.5  # independent wheels


def test_same_seed_same_log_other_seed_other_log(short):
    defects = parse_defects("all")
    a, b, c = (degrade(short, defects, seed) for seed in (3, 3, 4))
    for column in ("px", "py", "psi", "n_rl", "n_rr"):
        np.testing.assert_array_equal(getattr(a.measured, column), getattr(b.measured, column))
        assert not np.array_equal(getattr(a.measured, column), getattr(c.measured, column))


def test_one_defect_does_not_change_another_realisation(short):
    alone = degrade(short, parse_defects("slip"), seed=5)
    with_others = degrade(short, parse_defects("slip,outliers,heading_bias,outages"), seed=5)
    np.testing.assert_array_equal(_wheels(alone), _wheels(with_others))
    outliers = degrade(short, parse_defects("outliers"), seed=5)
    with_wheels = degrade(short, parse_defects("outliers,slip,ticks,latency"), seed=5)
    np.testing.assert_array_equal(_positions(outliers), _positions(with_wheels))
    bias = degrade(short, parse_defects("heading_bias"), seed=5)
    with_gnss = degrade(short, parse_defects("heading_bias,gnss10hz,outliers,lever_arm"), seed=5)
    np.testing.assert_array_equal(bias.measured.psi, with_gnss.measured.psi)


def test_parse_defects_names_values_and_all():
    assert parse_defects("") == Defects() == parse_defects("none")
    d = parse_defects("outliers, latency=0.1,lever_arm=1.5")
    assert d.outlier_share == 0.005 and d.latency == 0.1 and d.lever_arm == (1.5, 0.0)
    assert parse_defects("all").names == DEFECTS_IN_ALL
    held = parse_defects("all,hold")
    assert held.gnss_hold and held.gnss_rate == 10.0 and "gnss10hz" not in held.names
    assert not parse_defects("all,dropouts").outage_hold
    assert parse_defects("hold=5").gnss_rate == 5.0
    assert parse_defects("outages=3").outages == 3
    assert parse_defects("ticks=512").ticks_per_revolution == 512


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("outliers,multipath", "unknown defect 'multipath'; known: all, gnss10hz, hold"),
        ("latency=soon", "latency=soon: not a number"),
        ("outages=1.5", "outages=1.5: must be a whole number"),
        ("outages,dropouts", "exclude each other"),
        ("gnss10hz,hold", "exclude each other"),
        ("outliers=2", "outlier_share must be in"),
        ("lever_arm=1:2:3", "LONGITUDINAL[:LATERAL]"),
    ],
)
def test_parse_defects_errors_are_one_line(text, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[")) as info:
        parse_defects(text)
    assert "\n" not in str(info.value)
    if "unknown" in message:
        assert all(name in str(info.value) for name in DEFECT_NAMES)


def test_degrade_refuses_a_degraded_drive_and_too_many_outages(short):
    once = degrade(short, parse_defects("latency"), seed=1)
    with pytest.raises(ValueError, match="already has defects"):
        degrade(once, parse_defects("slip"), seed=1)
    with pytest.raises(ValueError, match="too short for 5 outage"):
        degrade(short, parse_defects("outages=5"), seed=1)


def test_cli_simulate_all_defects_is_a_valid_log_with_its_defects_named(tmp_path, capsys):
    out = tmp_path / "all.csv"
    args = ["simulate", "--length-km", "2", "--seed", "2", "--out", str(out), "--defects", "all"]
    assert main(args) == 0
    meta = json.loads((tmp_path / "all.json").read_text())
    assert meta["defects"]["names"] == list(DEFECTS_IN_ALL)
    assert meta["defects"]["seed"] == 2
    assert meta["defects"]["settings"]["latency"] == 0.05
    assert read_sidecar(out, len(load_drive_log(out)))["theta_true"][0] == 1.985
    capsys.readouterr()
    assert main(["check", str(out)]) == 0
    assert "a held fix" in capsys.readouterr().out  # the screen masks the held outages


def test_cli_simulate_bad_defects_is_one_line_and_exit_2(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "--length-km", "1", "--out", str(out), "--defects", "wobble"]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown defect 'wobble'" in err and "\n" not in err
    assert not list(tmp_path.iterdir())
    streams = ["simulate", "--streams", str(tmp_path / "s"), "--defects", "latency"]
    assert main(streams) == 2
    assert "--defects applies to the drive-log output" in capsys.readouterr().err
