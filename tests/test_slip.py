"""Slow per-wheel slip: detected from the χ² it explains, then modelled as Gauss–Markov scale
states, it no longer biases theta; a drive without slip is solved without them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.localization_inputs import wheel_model
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


def _run(drive, slip: str):
    settings = Settings()
    joint = dataclasses.replace(settings.joint, slip=slip)
    return run_calibration(drive.measured, dataclasses.replace(settings, joint=joint), "whole")


def _z(run, drive) -> np.ndarray:
    return np.abs(run.theta - drive.theta_true) / np.sqrt(np.diag(run.covariance))


@pytest.fixture(scope="module")
def slipping():
    return degrade(simulate_drive(4.0, 1), parse_defects("slip=0.003"), 1)


@pytest.mark.slow
def test_slip_is_detected_and_modelled(slipping):
    run = _run(slipping, "auto")
    assert run.whole.slip_modelled and run.whole.slip_test.z > 10
    assert wheel_model(run)["slip_sigma"] == run.settings.joint.slip_sigma > 0  # for localization
    assert _z(run, slipping).max() < 3
    # White wheel noise only: the segments' groups disagree, and their scatter scales σ.
    assert _run(slipping, "off").trust.agreement.sigma_scale.max() > 1.5


@pytest.mark.slow
def test_a_drive_without_slip_is_solved_without_slip_scales():
    clean = simulate_drive(4.0, 1)
    run = _run(clean, "auto")
    assert not run.whole.slip_modelled and abs(run.whole.slip_test.z) < 3
    assert wheel_model(run) == {"tick_quantization": 0.0, "slip_sigma": 0.0, "slip_time": 5.0}
    off = _run(clean, "off")
    np.testing.assert_allclose(run.theta, off.theta, rtol=1e-9)
    # σ: the data's, and with slip not modelled, the slow slip no test can show beside it
    scale = run.whole.slip_test.unseen_slip_scale()
    sigma, data_sigma = np.sqrt(np.diag(run.covariance)), np.sqrt(np.diag(off.covariance))
    np.testing.assert_allclose(sigma, data_sigma * scale, rtol=1e-6)
    assert scale[0] > 1.2  # c_e, which slow slip moves


@pytest.mark.slow
def test_slip_screened_on_a_spread_sample_decides_as_the_whole_log(slipping, monkeypatch):
    """A long log screens slip on segments spread over it; the sample's statistic is the
    whole log's to within its sampling noise, and the solve with slip that follows covers
    every segment."""
    import graphcal.pipeline.solvers.slip_screen as slip_screen

    whole = _run(slipping, "auto")
    monkeypatch.setattr(slip_screen, "SLIP_SCREEN_SEGMENTS", 5)
    monkeypatch.setattr(slip_screen, "SLIP_SCREEN_TIED_SEGMENTS", 0)  # as a long log's
    sampled = _run(slipping, "auto")
    assert len(whole.data) > 5
    per_chunk = [r.whole.slip_test.statistic / r.whole.slip_test.chunks for r in (whole, sampled)]
    assert sampled.whole.slip_modelled and sampled.whole.slip_test.z > 3
    assert sampled.whole.slip_test.chunks < whole.whole.slip_test.chunks  # another sample
    assert abs(per_chunk[1] - per_chunk[0]) < 0.5 * per_chunk[0]
    # Once slip is shown, the same solve with slip over all segments: the same theta.
    np.testing.assert_allclose(sampled.theta, whole.theta, rtol=1e-7)
    clean = _run(simulate_drive(4.0, 1), "auto")
    assert not clean.whole.slip_modelled


@pytest.mark.slow
@pytest.mark.parametrize("seed", [4, 5])
def test_a_little_slip_is_found_by_the_test_of_its_own_noise(seed):
    """Issue 43: 0.05 % slow slip left c_d 4-5σ off and "calibrated": its χ² drop per chunk
    (0.89-1.18 on those drives) stayed under the fixed threshold of 1.3, which drives without
    slip (0.49-0.60) left far below. The test against the drop the log's own noise would give
    finds it; the same drive without slip is left without slip scales."""
    clean = simulate_drive(8.0, seed)
    slipping = degrade(clean, parse_defects("slip=0.0005"), seed)
    found = _run(slipping, "auto")
    # Found; the model check may then keep theta alone where it predicts held-apart
    # segments as well (seed 5).
    shown = found.whole.slip_modelled or "slow wheel slip" in found.model_check.found
    assert shown and _z(found, slipping).max() < 3
    assert not _run(clean, "auto").whole.slip_modelled


def test_a_log_tied_into_chains_is_screened_whole():
    """A sample of a tied log breaks its chains: the untied sample is another estimator
    (three drives of 8 km: c_e's σ 0.37 mm on 32 of 43 segments, 0.07 mm tied whole) whose
    slip test and response to slip are not the log's (seed 39's shape 167: 0.07 % slip
    unseen, c_e −5.6σ; screened whole, the slow test's z 7.7 and slip modelled, −1.0σ).
    Up to 96 segments a tied log is screened whole; longer ones, and untied ones, on 32
    spread over them."""
    from graphcal.log.segments import gather_segments
    from graphcal.pipeline.methods.selection import select
    from graphcal.pipeline.solvers.joint_settings import JointSettings
    from graphcal.pipeline.solvers.slip_screen import SLIP_SCREEN_SEGMENTS, _screened

    log = simulate_drive(8.0, 1).measured
    every = select(log, Settings(), True)[0]  # all 54 of its 150 m segments, one chain
    data = gather_segments(log, every)
    tied = JointSettings().graph_spec(slip=True)
    assert len(data) > SLIP_SCREEN_SEGMENTS and tied.tied(data).any()
    np.testing.assert_array_equal(_screened(data, tied), np.arange(len(data)))
    untied = dataclasses.replace(tied, tie_segments=False)
    assert len(_screened(data, untied)) == SLIP_SCREEN_SEGMENTS


def test_the_slow_slip_test_on_a_long_logs_sample_is_over_what_its_chunks_resolve():
    """A 200 km log's screen: 32 segments of 14 chunks spread over 6 hours, 360 cosines per
    wheel sum and difference at 896 scales. Sampled so sparsely the cosines are nearly
    collinear: the test's null mean read 59,995 ± 0. Its basis is an orthonormal one of what
    the chunks resolve, and the test's null distribution over it is finite and positive."""
    from types import SimpleNamespace

    from graphcal.pipeline.solvers.slip_screen import _score_test, _slow_basis

    segments = np.repeat(np.arange(32), 14)
    starts = np.tile(np.arange(14) * 50, 32)
    samples = np.arange(32)[:, None] * 27_000 + np.arange(701)[None, :]  # 6 h at 40 Hz
    basis = _slow_basis(
        (segments, starts, starts + 50), SimpleNamespace(sample_index=samples, dt=0.025)
    )
    assert basis is not None
    assert np.allclose(basis.T @ basis, np.eye(basis.shape[1]), atol=1e-9)
    assert basis.shape[1] < 2 * 360  # the cosines the sparse chunks cannot tell apart: merged
    rng = np.random.default_rng(0)
    root = rng.standard_normal((2 * len(segments), 2 * len(segments)))
    noise = root @ root.T / len(segments)  # the data's information on the scales
    information = noise + 1e-2 * np.eye(len(noise))  # with their prior
    score = rng.multivariate_normal(np.zeros(len(noise)), noise)
    restricted = (basis.T @ score, basis.T @ information @ basis, basis.T @ noise @ basis)
    _, expected, spread = _score_test(*restricted)
    assert 0 < expected <= basis.shape[1]
    assert spread > 0


def _screen_system(rng: np.random.Generator, sizes: list[int], k: int, chained: bool):
    """A slip screen's augmented Hessians ``(total, data)``: parts that each touch the
    ``k`` graph-wide variables and their own block of scales (``sizes``), Gauss–Markov
    priors along each block (``chained``: one prior step joins the first two blocks, as a
    tied chain's do), a prior on the graph-wide variables."""
    s = sum(sizes)
    n = k + s
    data = np.zeros((n + 1, n + 1))
    start = k
    for size in sizes:
        index = np.r_[np.arange(k), np.arange(start, start + size), n]
        rows = rng.standard_normal((3 * size + k, len(index)))
        data[np.ix_(index, index)] += rows.T @ rows
        start += size
    priors = np.zeros_like(data)
    priors[:k, :k] = np.eye(k)
    ends = set(np.cumsum(sizes)[int(chained) : -1] - 1)  # a step only within a block (or chain)
    walk = 0.1 * np.eye(s)
    for j in (j for j in range(s - 1) if j not in ends):
        walk[j : j + 2, j : j + 2] += np.array([[1.0, -1.0], [-1.0, 1.0]])
    priors[k:n, k:n] = 4.0 * walk
    return data + priors, data


@pytest.mark.parametrize("chained", [False, True])
def test_the_slip_screens_structured_test_is_the_dense_one(chained):
    """The score test on the screen's block structure (``slip_score``: Woodbury over the
    graph-wide variables, traces block by block) gives the dense formulas' statistic, null
    mean and σ, and the slow test's restricted system; it fails if a block's coupling to
    the graph-wide variables or the score's covariance off the diagonal blocks is lost."""
    from graphcal.pipeline.solvers.slip_score import ScreenSystem, diagonal_blocks
    from graphcal.pipeline.solvers.slip_screen import _score_test

    rng = np.random.default_rng(3)
    sizes, k = [6, 10, 4, 8], 5
    total, data = _screen_system(rng, sizes, k, chained)
    n = len(total) - 1
    blocks = diagonal_blocks(total[k:n, k:n], data[k:n, k:n])
    assert [b.stop - b.start for b in blocks] == ([16, 4, 8] if chained else sizes)
    information, gradient = total[:n, :n], total[:n, n]
    gain = np.linalg.solve(information[:k, :k], information[:k, k:]).T
    reduced = information[k:, k:] - gain @ information[:k, k:]
    projection = np.hstack([-gain, np.eye(n - k)])
    score = projection @ gradient
    noise = projection @ data[:n, :n] @ projection.T
    system = ScreenSystem(total, data, k)
    assert np.allclose(system.test(), _score_test(score, reduced, noise), rtol=1e-10, atol=0)
    basis = np.linalg.qr(rng.standard_normal((n - k, 3)))[0]
    dense = (basis.T @ score, basis.T @ reduced @ basis, basis.T @ noise @ basis)
    for got, expected in zip(system.restricted(basis), dense, strict=True):
        assert np.allclose(got, expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())
