"""The encoder resolution read from a log of tick counts (:func:`ticks_per_revolution`): the
smallest resolution that fits, unmoved by isolated samples off the tick grid.

The logs are built here with numpy alone: a smooth speed profile, the wheel's cumulative angle
floored to whole ticks, differenced per interval."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.log.quantization import ticks_per_revolution


def _speed(t: np.ndarray, low: float, high: float) -> np.ndarray:
    """A smooth speed profile [m/s] between ``low`` and ``high`` (a few incommensurate waves)."""
    shape = (
        0.5
        + 0.25 * np.sin(2 * np.pi * t / 97.0)
        + 0.15 * np.sin(2 * np.pi * t / 31.0 + 1.0)
        + 0.1 * np.sin(2 * np.pi * t / 13.0 + 2.0)
    )
    return low + (high - low) * shape


def _angles(
    seconds: float, rate: float, low: float, high: float, circumference: float
) -> np.ndarray:
    """Cumulative wheel angles [rev] (N+1, 2) at ``rate`` Hz: left and a slightly faster right."""
    t = np.arange(int(seconds * rate) + 1) / rate
    angle = np.concatenate([[0.0], np.cumsum(_speed(t[:-1], low, high)) / rate]) / circumference
    return np.column_stack([angle, 1.003 * angle])


def _counted(angles: np.ndarray, ticks: int, seed: int = 0) -> np.ndarray:
    """Per-interval rotations [rev] (N, 2) of counters of ``ticks`` per revolution."""
    phase = np.random.default_rng(seed).uniform(0.0, 1.0, 2)
    return np.diff(np.floor(angles * ticks + phase), axis=0) / ticks


def _car(rate: float = 100.0, seconds: float = 2000.0, ticks: int = 96, seed: int = 0):
    """A car at 0–20 m/s, wheel circumference 2 m."""
    return _counted(_angles(seconds, rate, 0.0, 20.0, 2.0), ticks, seed)


RATES = (100.0, 40.0)


@pytest.mark.parametrize("rate", RATES)
def test_a_clean_count_log_gives_its_resolution(rate):
    assert ticks_per_revolution(_car(rate)) == 96


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.slow
def test_a_first_sample_off_the_tick_grid_does_not_change_it(rate):
    """The counter's first reading from another epoch: the first interval is no whole count
    (the case that gave 1056 = 11 × 96)."""
    for offset in (0.13, 0.37, 0.5, 0.81):
        rotations = _car(rate)
        rotations[0] += offset / 96
        assert ticks_per_revolution(rotations) == 96, offset


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_tenth_of_a_percent_of_glitched_samples_does_not_change_it(rate, seed):
    rotations = _car(rate, seed=seed)
    rng = np.random.default_rng(seed)
    glitched = rng.choice(rotations.size, rotations.size // 1000, replace=False)
    rotations.reshape(-1)[glitched] += rng.uniform(0.05, 0.95, len(glitched)) / 96
    assert ticks_per_revolution(rotations) == 96


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.slow
def test_a_counter_reset_or_wrap_does_not_change_it(rate):
    reset = _car(rate)
    reset[len(reset) // 3, 0] -= 51234.0 / 96  # the counter restarted at 0: hugely negative
    assert ticks_per_revolution(reset) == 96
    wrapped = _car(rate)
    wrapped[len(wrapped) // 2] += 65536 / 96  # a 16-bit wrap read as a raw difference
    assert ticks_per_revolution(wrapped) == 96
    spike = _car(rate)
    spike[-1] += 12345.678  # one huge interval, off the grid too
    assert ticks_per_revolution(spike) == 96


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.slow
def test_a_continuous_signal_has_no_resolution(rate):
    angles = _angles(2000.0, rate, 0.0, 20.0, 2.0)
    smooth = np.diff(angles, axis=0)
    assert ticks_per_revolution(smooth) is None
    noisy = smooth + np.random.default_rng(4).normal(0.0, 5e-4, smooth.shape)
    assert ticks_per_revolution(noisy) is None
    noisy[0] += 0.0123  # and off-grid samples do not make it look counted
    assert ticks_per_revolution(noisy) is None


def test_a_robot_with_a_fine_encoder_gives_its_resolution():
    """2797 ticks/rev at 40 Hz, 0.1–1.5 m/s on a 0.26 m wheel: 27–400 ticks per interval; the
    neighbours 2796 and 2798 fit about 3 % worse (1 − 2π² var(rotation [rev]))."""
    rotations = _counted(_angles(600.0, 40.0, 0.1, 1.5, 0.26), 2797)
    assert ticks_per_revolution(rotations) == 2797
    rotations[0] += 0.4 / 2797
    assert ticks_per_revolution(rotations) == 2797


@pytest.mark.parametrize("ticks", [64, 192, 500, 1024])
@pytest.mark.slow
def test_a_resolution_is_not_mistaken_for_a_divisor_or_a_multiple(ticks):
    rotations = _car(100.0, 600.0, ticks)
    assert ticks_per_revolution(rotations) == ticks
    rotations[0] += 0.3 / ticks
    assert ticks_per_revolution(rotations) == ticks


def test_counts_with_a_little_white_noise_on_top_give_the_resolution():
    """White noise σ on the counts lowers a multiple's resultant by exp(−2π²(σ k T)²): the
    resolution itself fits best."""
    rotations = _car(40.0, 600.0)
    rotations += np.random.default_rng(5).normal(0.0, 0.05 / 96, rotations.shape)
    rotations[0] += 0.5 / 96
    assert ticks_per_revolution(rotations) == 96


# --- issue 43: counts that stay the same through long cruises -------------------------------


def _cruising(
    rate: float, ticks: int, count: int, seconds: float = 1200.0, share: float = 0.7
) -> np.ndarray:
    """Angles [rev] (N+1, 2) of a city drive whose cruises (``share`` of the time) turn the
    wheels ``count`` + 0.003 ticks per interval: the counters (each at its own phase) read
    ``count`` over and over."""
    t = np.arange(int(seconds * rate)) / rate
    per = _speed(t, 0.0, 20.0) / 2.0 / rate  # rev per interval of a 2 m wheel
    cruise = np.sin(2 * np.pi * t / 400.0) > np.cos(np.pi * share)
    per[cruise] = (count + 0.003) / ticks
    angle = np.concatenate([[0.0], np.cumsum(per)])
    return np.column_stack([angle, angle])


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize(("ticks", "count"), [(16, 3), (96, 17), (96, 18), (500, 71), (4096, 573)])
def test_counts_that_stay_the_same_through_cruises_give_the_resolution(rate, ticks, count):
    """17 ticks per interval over and over: second differences 0, yet every rotation sits on
    the 1/96 grid (issue 43: found none, c_d 7.6σ off). An even cruise count (18 = 2 × 9) is
    on the grids of 48 and 32 too; the rest of the drive tells them apart."""
    rotations = _counted(_cruising(rate, ticks, count), ticks)
    same = np.mean(np.diff(np.round(rotations[:, 0] * ticks)) == 0)
    assert same > 0.7  # the counts mostly repeat
    assert ticks_per_revolution(rotations) == ticks
    rotations[0] += 0.37 / ticks  # a first reading from another epoch
    assert ticks_per_revolution(rotations) == ticks


def test_a_cruise_of_two_counts_with_each_first_reading_off_the_grid_gives_the_resolution():
    """A 1 km straight at one speed on 1849-tick wheels (campaign seed 32's shape 151): two
    counts (595 and 596 per interval) and each wheel's first interval from another epoch.
    Counted among the values, those two halved the share on the grid (chance 1.5·10⁻³:
    found none)."""
    per = np.full(1560, 595.4 / 1849)
    angle = np.concatenate([[0.0], np.cumsum(per)])
    rotations = _counted(np.column_stack([angle, 1.0001 * angle]), 1849)
    rotations[0] += np.array([0.37, 0.61]) / 1849
    assert len(np.unique(np.round(rotations[1:] * 1849))) == 2
    assert ticks_per_revolution(rotations) == 1849


def test_a_counter_that_reads_one_or_two_ticks_per_interval_gives_its_resolution():
    """A 16-tick wheel at 100 Hz, 0–20 m/s on a 2 m wheel: counts of 0, 1 or 2 (a spread of
    a fraction of a tick), 98 % of them 1."""
    rotations = _car(100.0, 600.0, 16)
    assert ticks_per_revolution(rotations) == 16


@pytest.mark.parametrize("rate", RATES)
def test_a_continuous_signal_that_cruises_has_no_resolution(rate):
    """The same cruises, continuous: exactly at a count per interval (no noise) and with the
    paper's wheel noise (5e-4 rev); and a narrow range of speeds (a robot)."""
    angles = _cruising(rate, 96, 17, share=0.9)
    exact = np.diff(angles, axis=0)
    assert ticks_per_revolution(exact) is None
    noisy = exact + np.random.default_rng(6).normal(0.0, 5e-4, exact.shape)
    assert ticks_per_revolution(noisy) is None
    narrow = np.diff(_angles(600.0, rate, 0.9, 1.1, 0.26), axis=0)
    assert ticks_per_revolution(narrow) is None
    narrow += np.random.default_rng(7).normal(0.0, 5e-4, narrow.shape)
    assert ticks_per_revolution(narrow) is None


@pytest.mark.parametrize("rate", RATES)
def test_a_counter_slower_than_a_tick_per_interval_gives_its_resolution(rate):
    """A skid-steer robot's 16-tick wheels (0.8 m circumference at 0.1–0.5 m/s): every
    positive rotation is one tick, the intervals around it none (campaign seed 24's shape
    15: found none). One value alone would sit on many grids by chance; beside the
    standstills it is a counter's."""
    rotations = _counted(_angles(600.0, rate, 0.1, 0.5, 0.8), 16)
    assert set(np.unique(np.round(rotations * 16))) == {0.0, 1.0}
    assert ticks_per_revolution(rotations) == 16


@pytest.mark.parametrize("rate", RATES)
def test_a_continuous_signal_that_stops_and_cruises_has_no_resolution(rate):
    """Exact zeros where a robot stands, and one exact value at its cruise speed (an encoder
    rate quantized by the logger, say): a few samples lie beside a standstill, not a counter's
    share."""
    per = np.full(int(600 * rate), 0.03)  # rev per interval
    stops = (np.arange(len(per)) // int(20 * rate)) % 2 == 1  # 20 s cruising, 20 s standing
    per[stops] = 0.0
    rotations = np.column_stack([per, per])
    assert ticks_per_revolution(rotations) is None
