"""The wheel-vs-pose time offset: undone by interpolation of the cumulative rotation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.log.timing import (
    coarse_wheel_lag,
    masked_for_the_clock_lag,
    shift_wheel_rotations,
    wheel_lag_from_turns,
)
from graphcal.model import THETA_NOMINAL, step_increments
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import NoiseLevels, simulate_drive


@pytest.fixture(scope="module")
def clean():
    return simulate_drive(4.0, 1)


@pytest.fixture(scope="module")
def late(clean):
    return degrade(clean, parse_defects("latency"), 1)  # wheels 0.05 s late


def test_shifting_the_wheels_undoes_a_latency(clean, late):
    truth = clean.truth
    undone = shift_wheel_rotations(late.measured, 0.05)
    inner = slice(10, -10)  # the ends continue at the edge rates
    residual = undone.n_rl[inner] - truth.n_rl[inner]
    late_residual = late.measured.n_rl[inner] - truth.n_rl[inner]
    assert np.std(residual) < 1.2 * clean.noise.wheel_rotation  # only the white noise is left
    assert np.std(late_residual) > 1.5 * np.std(residual)  # 0.05 s late: 1.9x here
    np.testing.assert_allclose(undone.n_rl.sum(), late.measured.n_rl.sum(), rtol=1e-3)


@pytest.mark.parametrize("latency", [-0.3, 0.0, 0.05, 0.35])
def test_the_wheels_lag_is_found_from_the_turns_before_any_solve(clean, latency):
    """What a user of a recording with late wheels gets before the first solve: the lag at
    which the wheels' turns fit the heading's (1.5° of heading noise), to the sample."""
    defects = "none" if latency == 0.0 else f"latency={latency}"
    log = degrade(clean, parse_defects(defects), 1).measured
    found = wheel_lag_from_turns(log, THETA_NOMINAL)
    assert found.shape == (1,)
    assert abs(found[0] - latency) <= log.dt + 1e-9
    assert found[0] / log.dt == pytest.approx(round(found[0] / log.dt))  # whole samples


def test_no_lag_is_claimed_without_a_measured_heading_or_beyond_the_search(clean):
    late = degrade(clean, parse_defects("latency=0.2"), 1).measured
    measured = np.ones((len(late.t), 2), bool)
    measured[:, 1] = False  # positions only
    no_heading = dataclasses.replace(late, measured=measured)
    assert not wheel_lag_from_turns(no_heading, THETA_NOMINAL).any()
    # 0.2 s late, searched within 0.1 s: the best fit is the search's edge, not a lag
    assert not wheel_lag_from_turns(late, THETA_NOMINAL, max_lag=0.1).any()


def test_each_run_has_its_own_lag(clean):
    """Two drives on one clock, the second's wheels 0.25 s late: each run's own lag."""
    on_time = clean.measured
    late = degrade(clean, parse_defects("latency=0.25"), 1).measured
    half = len(on_time.t) // 2
    run = (np.arange(len(on_time.t)) >= half).astype(np.int64)
    joined = dataclasses.replace(
        on_time,
        n_rl=np.where(run == 1, late.n_rl, on_time.n_rl),
        n_rr=np.where(run == 1, late.n_rr, on_time.n_rr),
        run=run,
    )
    found = wheel_lag_from_turns(joined, THETA_NOMINAL)
    np.testing.assert_allclose(found, [0.0, 0.25], atol=on_time.dt + 1e-9)
    assert found[1] - found[0] > 0.2


@pytest.mark.parametrize("latency", [-18.0, 10.0])
def test_clocks_seconds_apart_are_found_and_the_rows_left_without_wheels_masked(clean, latency):
    """Wheels logged on a clock 18 s off the pose's (GPS time against UTC) or 10 s late:
    found to the sample from their turns before any solve (searched within ±1 s they were
    not, and a 10 s lag ran 37 s of solves to exit 2 blaming the wheels' units), then the
    rotations taken that much later and the rows whose interval left the log masked."""
    log = shift_wheel_rotations(clean.measured, -latency)  # read `latency` earlier
    found = wheel_lag_from_turns(log, THETA_NOMINAL)
    assert abs(found[0] - latency) <= log.dt + 1e-9
    masked_log = masked_for_the_clock_lag(log, found)
    masked = np.flatnonzero(masked_log.masked)
    assert len(masked) == pytest.approx(abs(latency) / log.dt, abs=1)
    assert (masked[0] == 0) if latency < 0 else (masked[-1] == len(log.t) - 1)
    assert "clock's lag" in masked_log.mask_notes[-1]


def test_a_small_lag_is_left_to_the_solve_and_a_steady_turn_claims_none(clean):
    small = degrade(clean, parse_defects("latency=0.35"), 1).measured
    lag = wheel_lag_from_turns(small, THETA_NOMINAL)
    assert lag[0] == pytest.approx(0.35, abs=small.dt)
    assert masked_for_the_clock_lag(small, lag) is small
    # turning at one rate throughout, the turns fit at every lag alike: no clock is claimed
    n = len(clean.measured.t)
    steady = dataclasses.replace(
        clean.measured,
        psi=0.01 * np.arange(n),
        n_rl=np.full(n, 0.10),
        n_rr=np.full(n, 0.10 + 0.01 * THETA_NOMINAL[2] / THETA_NOMINAL[0]),
    )
    turned = np.concatenate([[0.0], np.cumsum(step_increments(steady.inputs, THETA_NOMINAL)[1])])
    usable = np.ones(n, bool)
    assert coarse_wheel_lag(turned, steady.psi, usable, steady.dt, 0, n - 1) == 0


@pytest.mark.slow
def test_wheels_seconds_late_calibrate_and_their_held_apart_check_shifts_both_folds(clean):
    """A 4 km drive whose wheels are 3 s late, calibrated as a user would: the lag found and
    reported, theta within 3σ of the truth, and the model check's held-apart segments taken
    from the shifted wheels too (from the unshifted ones they were predicted 12.4 m off)."""
    late = shift_wheel_rotations(clean.measured, -3.0)
    run = run_calibration(late, method="whole", workers=1)
    assert run.estimated["time_offset"].value == pytest.approx(3.0, abs=0.005)
    sigma = np.sqrt(np.diag(run.covariance))
    assert np.all(np.abs(run.theta - clean.theta_true) < 3.0 * sigma)
    assert run.model_check.defect_model_error < 1.0


def test_no_lag_is_claimed_from_a_sparse_heading_and_coarse_wheel_ticks():
    """A car's heading measured every 2 s (0.01° noise), its wheels counting 16 ticks a
    revolution, no lag: the turns over 2 s windows fit alike from −150 to +100 ms, and the
    best of them is the wheels' tick noise. Campaign seed 56's shape 67 was shifted 100 ms
    by it, and its solve kept −95 ± 5 ms against the truth's 0."""
    claimed = []
    for seed in range(1, 9):
        quiet = NoiseLevels(position=1.0, heading=np.radians(0.01), wheel_rotation=0.0)
        log = simulate_drive(2.0, seed, noise=quiet).measured
        measured = np.ones((len(log.t), 2), bool)
        measured[:, 1] = np.arange(len(log.t)) % round(2.0 / log.dt) == 0

        def ticks(rotations: np.ndarray) -> np.ndarray:
            counted = np.floor(np.concatenate([[0.0], np.cumsum(rotations)]) * 16)
            return np.diff(counted) / 16

        coarse = dataclasses.replace(
            log, measured=measured, n_rl=ticks(log.n_rl), n_rr=ticks(log.n_rr)
        )
        claimed.append(wheel_lag_from_turns(coarse, THETA_NOMINAL)[0])
    assert not np.any(claimed), claimed
