"""The randomized campaign over recording shapes (issue 43, item 1): recordings of shapes the
suite never held, from the independent twin, must keep the invariants of
``tests/campaign/invariants.py``.

Quick tier: the data path (import, the wheel-scale and unit checks, segments, tick
detection) on short recordings, shapes drawn with a fixed seed. Slow tier: a few full
calibrations. ``scripts/campaign.py`` runs N shapes and prints the table."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")

from campaign.invariants import calibrate, data_path_broken  # noqa: E402
from campaign.recording import write_recording  # noqa: E402
from campaign.shape import Shape, drawn_from_the_seed_alone, shapes  # noqa: E402
from hypothesis import HealthCheck, Phase, example, given, settings  # noqa: E402

import graphcal  # noqa: E402

#: Short recordings: the quick tier's drives [m].
QUICK_CAR_M = (400.0, 900.0)
QUICK_ROBOT_M = (60.0, 150.0)


def _shape(**axes) -> Shape:
    """A shape: a 0.6 km town car at 10 Hz, 0.3 m white noise, IMU, wheel speeds, one drive
    parked 3 s at each end, unless ``axes`` say otherwise."""
    base = dict(
        vehicle="car", route="town", length_m=600.0, gnss_rate=10.0, noise_sigma=0.3,
        noise_tau_s=0.0, heading=False, imu=True, wheels="speed", ticks=0, drives=1,
        gap_s=0.0, park_s=3.0, time_offset_s=0.0, lever_arm=(1.0, 0.3), seed=1,
    )  # fmt: skip
    return Shape(**{**base, **axes})


def _yard(vehicle: str, **axes) -> Shape:
    """A robot's shape (``vehicle`` in a yard), as :func:`_shape` otherwise."""
    return _shape(vehicle=vehicle, route="yard", **axes)


def _prepared(shape: Shape, directory: Path):
    """``shape``'s recording written to ``directory``, imported and prepared for the joint
    solve with its vehicle's profile (as ``graphcal calibrate`` does); and the profile."""
    from graphcal.pipeline.configuration.configure import configure_settings
    from graphcal.pipeline.methods.prepare import prepare_log

    manifest = write_recording(shape, directory)
    vehicle = graphcal.load_vehicle(directory / "vehicle.toml")
    log, _ = graphcal.open_log(manifest, vehicle)
    settings = configure_settings(vehicle=directory / "vehicle.toml")
    return prepare_log(log, settings, fall_back_to_all=True), vehicle


#: Three 1.5 km drives on a straight road, 5 Hz fixes of 0.26 m, no heading, an antenna
#: 0.38 m to the side: neither the arm nor t_r shows.
STRAIGHT_POSITIONS_ONLY = dict(
    route="straight", length_m=1500.0, gnss_rate=5.0, noise_sigma=0.26, drives=3, gap_s=22.0,
    park_s=4.0, lever_arm=(0.0, 0.38), seed=1087,
)  # fmt: skip


#: Shapes the campaign found breaking an invariant on main (each named by its failure), and
#: shapes of issue 43's table kept as regression tests.
EXAMPLES = [
    pytest.param(
        _yard(
            "differential",
            length_m=250.0,
            noise_sigma=1.03,
            park_s=3.0,
            time_offset_s=-0.038,
            lever_arm=(0.01, 0.0),
            seed=4466,
        ),
        id="noisy-fixes-read-as-a-mirrored-track",  # seed 29's shape 155: 10 Hz fixes of
        # 1 m on a slow robot turned at random over 1 s chords: "a mirrored track", refused
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=126.0,
            gnss_rate=20.0,
            noise_sigma=1.75,
            heading=True,
            imu=False,
            park_s=3.0,
            time_offset_s=0.029,
            lever_arm=(0.15, 0.0),
            seed=1382,
        ),
        id="loops-within-a-noisy-tracks-chord",  # seed 30's shape 8: 1.8 m fixes, a 90 m
        # chord in a yard bending back on itself: "a mirrored track", refused
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=100.0,
            gnss_rate=5.0,
            noise_sigma=1.43,
            noise_tau_s=5.0,
            imu=False,
            wheels="ticks",
            ticks=2792,
            park_s=4.0,
            lever_arm=(0.0, 0.0),
            seed=2792,
        ),
        id="chords-too-alike-to-fit-the-noise-out",  # seed 30's shape 83: 1.4 m fixes,
        # chord² 1.5 m² on 0.36 m² of wheel travel, all alike: "the wheels travel 0.49x"
    ),
    pytest.param(
        _shape(drives=3, gap_s=30.0, park_s=5.0, gnss_rate=5.0, heading=False),
        id="three-drives-one-clock",
    ),
    pytest.param(  # a highway cruise's speeds scattered about 1/3 rev per interval: "6 ticks"
        _shape(
            route="straight",
            length_m=1000.0,
            gnss_rate=1.0,
            noise_sigma=1.0,
            park_s=5.0,
            lever_arm=(0.0, -0.49),
            seed=7609,
        ),
        id="ticks-on-a-cruise-of-speeds",
    ),
    pytest.param(
        _shape(wheels="ticks", ticks=96, gnss_rate=1.0, heading=False, length_m=800.0),
        id="1hz-fixes",
    ),
    pytest.param(
        _shape(gnss_rate=0.5, noise_sigma=0.2, seed=0),
        id="0.5hz-fixes",
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=620.0,
            gnss_rate=1.0,
            noise_sigma=0.43,
            noise_tau_s=42.0,
            wheels="ticks",
            ticks=2340,
            drives=3,
            gap_s=28.0,
            park_s=7.0,
            time_offset_s=0.05,
            lever_arm=(0.0, 0.38),
            seed=65536,
            imu=True,
        ),
        id="ticks-2340-cruise",
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=890.0,
            gnss_rate=2.0,
            noise_sigma=2.0,
            heading=True,
            drives=3,
            gap_s=38.0,
            park_s=0.0,
            time_offset_s=0.047,
            lever_arm=(0.43, 0.0),
            seed=2676,
        ),
        id="heading-noisy-fixes",
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=150.0,
            gnss_rate=2.5,
            noise_sigma=2.0,
            noise_tau_s=45.0,
            wheels="angular_speed",
            park_s=5.0,
            time_offset_s=0.05,
            lever_arm=(0.0, 0.0),
            seed=1430,
        ),
        id="robot-ay-noisy-fixes",
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=810.0,
            gnss_rate=5.0,
            noise_sigma=1.8,
            wheels="ticks",
            ticks=418,
            drives=2,
            gap_s=30.0,
            park_s=6.0,
            lever_arm=(0.0, -0.03),
            seed=418,
        ),
        id="yaw-rate-noisy-fixes",
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=60.0,
            gnss_rate=5.0,
            noise_sigma=1.2,
            heading=True,
            imu=False,
            wheels="angular_speed",
            park_s=3.0,
            lever_arm=(0.0, 0.0),
            seed=24897,
        ),
        id="wheel-scale-skid-steer",
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=400.0,
            gnss_rate=20.0,
            noise_sigma=0.2,
            noise_tau_s=16.0,
            heading=True,
            drives=2,
            gap_s=42.0,
            park_s=1.0,
            lever_arm=(0.0, 0.0),
            seed=654,
        ),
        id="gap-longer-than-drives",
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=120.0,
            gnss_rate=20.0,
            noise_sigma=1.3,
            noise_tau_s=16.0,
            imu=False,
            wheels="ticks",
            ticks=16,
            drives=3,
            gap_s=20.0,
            park_s=0.0,
            lever_arm=(0.0, 0.0),
            seed=16,
        ),
        id="ticks-16-robot",
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=81.0,
            gnss_rate=2.5,
            noise_sigma=1.1,
            noise_tau_s=35.0,
            imu=False,
            wheels="ticks",
            ticks=128,
            park_s=1.0,
            time_offset_s=0.046,
            lever_arm=(0.0, 0.0),
            seed=128,
        ),
        id="ticks-128-skid-steer",
    ),
    pytest.param(  # seed 14's shape 7: refused, "the heading differs from the direction of
        # travel by -27° on average", the median of courses between fixes 1.9 m noisy, 1 m apart
        _yard(
            "skid-steer",
            length_m=123.0,
            gnss_rate=1.0,
            noise_sigma=1.95,
            heading=True,
            imu=False,
            park_s=6.0,
            lever_arm=(-0.15, 0.0),
            seed=290,
        ),
        id="heading-against-a-noisy-course",
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=236.0,
            gnss_rate=50.0,
            noise_sigma=1.7,
            heading=False,
            wheels="ticks",
            ticks=3302,
            drives=3,
            gap_s=45.0,
            time_offset_s=0.012,
            lever_arm=(0.0, 0.0),
            seed=343,
        ),
        id="course-of-noisy-fixes-read-as-degrees",  # seed 25's shape 7: the track's own
        # course (no heading logged) turned 22x the wheels' and was refused as "degrees"
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=162.0,
            gnss_rate=5.0,
            noise_sigma=1.98,
            heading=False,
            wheels="angular_speed",
            drives=3,
            gap_s=50.0,
            park_s=4.0,
            lever_arm=(0.01, 0.0),
            seed=436,
        ),
        id="distance-ratio-of-chords-all-noise",  # seed 25's shape 13: 2 m fixes, 0.3 m of
        # travel per 2 s window; the chords' length less their noise came out 0: refused
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=248.0,
            gnss_rate=1.0,
            noise_sigma=0.2,
            noise_tau_s=5.0,
            heading=False,
            imu=False,
            wheels="ticks",
            ticks=16,
            park_s=2.0,
            lever_arm=(0.0, 0.0),
            seed=16,
        ),
        id="sixteen-ticks-one-per-interval",  # seed 24's shape 15: every positive rotation
        # one tick, the intervals around it none: no resolution found
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=240.0,
            gnss_rate=0.5,
            noise_sigma=0.66,
            noise_tau_s=37.0,
            heading=True,
            wheels="angular_speed",
            park_s=5.0,
            time_offset_s=0.02,
            lever_arm=(-0.19, 0.0),
            seed=1560,
            outliers=0.002,
            outage_s=59.0,
        ),
        id="sparse-fixes-one-outlier",  # seed 34's shape 13: a fix 37 m off at 0.5 Hz, the
        # track interpolated towards it: a 37 m chord for 3 m of wheels, refused as a unit
        # mistake ("the positions travel 2.68x the distance the wheel rotations imply")
    ),
    pytest.param(
        _shape(
            length_m=1047.0,
            gnss_rate=20.0,
            noise_sigma=1.97,
            noise_tau_s=23.0,
            heading=True,
            wheels="ticks",
            ticks=852,
            park_s=7.0,
            time_offset_s=0.0,
            lever_arm=(-1.47, 0.0),
            seed=1631,
            slip=0.0006,
            mounting=(0.0, 1.0, 182.0),
            mounting_estimated=True,
        ),
        id="mounted-imu-estimated-parked-ends",  # seed 34's shape 6: the campaign's cars
        # went from parked to 5 m/s in a millisecond; the IMU felt it otherwise than the
        # wheels' bins: the mounting "only to ±0.8°", refused (the cars now start from rest)
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=193.0,
            gnss_rate=20.0,
            noise_sigma=0.5,
            heading=True,
            imu=False,
            park_s=5.0,
            time_offset_s=0.0,
            lever_arm=(0.3, 0.0),
            seed=57222,
            outliers=0.002,
            outage_s=32.0,
            slip=0.0015,
        ),
        id="outlier-at-a-windows-end",  # seed 34's shape 107: a fix 36 m off at the last
        # sample of a 2 s window, whose clean test stopped one sample short: refused as a
        # unit mistake
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=115.0,
            noise_sigma=1.89,
            imu=False,
            wheels="angular_speed",
            park_s=1.0,
            time_offset_s=0.045,
            lever_arm=(-0.2, 0.0),
            seed=15642,
            outage_s=60.0,
        ),
        id="chord-noise-fitted-below-zero",  # seed 34's shape 108: 10 Hz fixes of 1.9 m,
        # 31 pairs of blocks 0.75 m apart: their noise fitted below 0, the chords taken as
        # noiseless, "the wheels travel 0.553x the distance of the GNSS track", refused
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=134.0,
            gnss_rate=1.0,
            noise_sigma=1.88,
            heading=True,
            wheels="ticks",
            ticks=75,
            park_s=1.0,
            time_offset_s=0.0,
            lever_arm=(0.15, 0.0),
            seed=2475,
            outliers=0.002,
        ),
        id="chord-slope-judged-on-its-scale",  # seed 35's shape 173: 1 Hz fixes of 1.9 m,
        # the chords' slope 6.0 ± 2.1 (2.1σ from the range), judged as log(ratio) with the
        # σ at the estimate (4σ): "the wheels travel 0.407x", refused
    ),
    pytest.param(
        _shape(
            length_m=1268.0,
            gnss_rate=20.0,
            noise_sigma=0.97,
            heading=True,
            wheels="ticks",
            ticks=657,
            park_s=4.0,
            time_offset_s=0.024,
            lever_arm=(0.0, -0.23),
            seed=19,
            outage_s=50.0,
            slip=0.0016,
            mounting=(-1.0, -8.0, 97.0),
            mounting_estimated=True,
            sideslip=True,
        ),
        id="mounting-estimated-across-an-outage",  # seed 36's shape 57: the wheels scaled to
        # metres by GNSS chords, one across the 50 s outage the straight line between its
        # ends: 0.8 of their travel, the IMU's accelerations 1.25 times the wheels', the
        # mounting "only to ±1.2°", refused (seed 35's shape 159 the same)
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=199.0,
            gnss_rate=50.0,
            noise_sigma=1.83,
            noise_tau_s=8.0,
            heading=True,
            imu=False,
            wheels="ticks",
            ticks=1379,
            drives=3,
            gap_s=25.0,
            park_s=4.0,
            time_offset_s=-0.015,
            lever_arm=(-0.22, 0.0),
            seed=487,
            outliers=0.01,
            slip=0.0028,
        ),
        id="a-noisy-course-wrapping-by-a-turn",  # seed 44's shape 101: a robot's course
        # over 3–5 m chords of fixes sharing 1.8 m wrapped by ±5–6.7 rad where the wheels
        # turned 0.03–0.55 rad: a right heading in degrees refused as "0.0157x the track"
    ),
]


@pytest.mark.parametrize("shape", EXAMPLES)
def test_found_shapes_keep_the_data_path_invariants(shape: Shape, tmp_path: Path) -> None:
    assert data_path_broken(shape, write_recording(shape, tmp_path)) == []


def test_a_skid_steer_robots_spins_are_not_heading_jumps(tmp_path: Path) -> None:
    """Seed 14's shape 7 with its profile: the datasheet track is half the effective one, so
    at the nominal the wheels turn twice as far as the heading; its spins on the spot were
    masked as heading jumps ("64° more than the wheels turn", 6 s), and with them kept, the
    1.9 m fixes' 2 m chords read as "the positions travel 2.03x the distance" of the wheels."""
    shape = next(p.values[0] for p in EXAMPLES if p.id == "heading-against-a-noisy-course")
    manifest = write_recording(shape, tmp_path)
    vehicle = graphcal.load_vehicle(tmp_path / "vehicle.toml")
    log, _ = graphcal.open_log(manifest, vehicle)
    assert not any("heading jumps" in note for note in log.mask_notes), log.mask_notes


def test_a_course_of_positions_only_does_not_turn_towards_outlying_fixes(tmp_path: Path) -> None:
    """Seed 35's shape 158 (a town car, 5 Hz fixes with 1 % of them 10–50 m off, no heading):
    the course of the track, each segment's start heading, ran through the outliers and
    turned by up to 2 rad for a second around each; a segment started there, its first solve
    ran 300 m off, and the run ended "the information is singular", exit 2. Against the
    wheels' yaw (nominal theta) the course may drift, but not jump."""
    shape = _shape(gnss_rate=5.0, noise_sigma=0.2, noise_tau_s=7.0, outliers=0.01, seed=2511)
    manifest = write_recording(shape, tmp_path)
    vehicle = graphcal.load_vehicle(tmp_path / "vehicle.toml")
    log, _ = graphcal.open_log(manifest, vehicle)
    assert log.outlying is not None and log.outlying.sum() > 0
    c_e, _, t_r, _ = vehicle.theta_nominal
    wheel_yaw = np.cumsum(c_e * (log.n_rr - log.n_rl) / t_r)
    second = round(1.0 / float(np.median(np.diff(log.t))))
    change = np.abs((log.psi - wheel_yaw)[second:] - (log.psi - wheel_yaw)[:-second])
    kept = ~log.masked[second:] & ~log.masked[:-second] if log.masked is not None else True
    assert np.max(change[kept]) < 0.2  # rad over a second


def test_a_straight_roads_warm_start_holds_what_its_segments_run_away_with(
    tmp_path: Path,
) -> None:
    """Seed 37's shape 11 (a 2.1 km straight road, 2.5 Hz fixes, a heading): each 150 m
    segment on its own ran t_r out of range (0.12 m), the warm start gave up, the tied log
    was integrated with the nominal c_d, drifted 390 m from its fixes, and the run ended
    "covariance: indeterminate", exit 2. Held at its prior, the rest of theta is a start."""
    from graphcal.graph.construction import keys
    from graphcal.graph.optimization.solve_options import SolveOptions
    from graphcal.log.segments import gather_segments, split_segments
    from graphcal.pipeline.solvers.joint_settings import JointSettings
    from graphcal.pipeline.solvers.warm_start import warm_start

    shape = _shape(
        route="straight", length_m=2090.0, gnss_rate=2.5, noise_sigma=0.84, heading=True,
        wheels="ticks", ticks=784, park_s=1.0, lever_arm=(0.65, 0.0), seed=784,
    )  # fmt: skip
    manifest = write_recording(shape, tmp_path)
    vehicle = graphcal.load_vehicle(tmp_path / "vehicle.toml")
    log, _ = graphcal.open_log(manifest, vehicle)
    data = gather_segments(log, split_segments(log, 150.0))
    start = warm_start(data, JointSettings().graph_spec(), SolveOptions(50, 1e-7))
    assert start is not None
    theta = start[keys.THETA]
    assert abs(theta[0] - 1.99) < 0.01 and abs(theta[1] - 0.0008) < 0.0003  # the twin's
    assert theta[2] == pytest.approx(vehicle.theta_nominal[2])


@pytest.mark.slow
def test_a_warm_start_of_a_solve_holding_a_parameter_does_not_hold_it_again(
    tmp_path: Path,
) -> None:
    """Seed 43's shape 194 without heading, recording seed 12 (a robot's 250 m in three
    drives, 50 Hz fixes sharing 0.74 m over 35 s): t_r ran out of range and the solve held
    at its prior started from a warm start whose segments pulled the held t_r a few of its
    held σ off; held again (σ 10⁻⁸ of its prior's), GTSAM took its prior as a constraint:
    "cannot update information with constrained noise model", a traceback."""
    from graphcal.graph.construction import keys
    from graphcal.graph.optimization.solve_options import SolveOptions
    from graphcal.pipeline.solvers.warm_start import warm_start

    shape = _yard(
        "differential", length_m=250.0, gnss_rate=50.0, noise_sigma=0.74, noise_tau_s=35.0,
        imu=False, drives=3, gap_s=25.0, park_s=0.0, lever_arm=(0.26, 0.0), seed=12,
        outage_s=29.0,
    )  # fmt: skip
    prepared, vehicle = _prepared(shape, tmp_path)
    joint = prepared.settings.joint.holding(("t_r",))
    start = warm_start(
        prepared.data, joint.graph_spec(), SolveOptions(50, 1e-7), joint.held_names()
    )
    assert start is not None
    assert start[keys.THETA][2] == pytest.approx(vehicle.theta_nominal[2], abs=1e-3)


@pytest.mark.parametrize(
    ("axes", "left_out", "held"),
    [(STRAIGHT_POSITIONS_ONLY, True, True), ({}, False, False)],
    ids=["straight", "town"],
)
def test_what_a_drive_of_positions_only_cannot_show_is_decided_before_solving(
    axes: dict, left_out: bool, held: bool, tmp_path: Path
) -> None:
    """A straight road's fixes without heading show neither the antenna's lever arm nor t_r:
    both are decided before any solve (the arm judged from the wheels' turn, not the course
    of the noisy fixes, which made it look showable: ±0.14 m at best; t_r held where the
    drive barely turns). The quick tier's 0.6 km town drive keeps both."""
    prepared, _ = _prepared(_shape(**axes), tmp_path)
    assert ("lever_arm" in prepared.left_out) == left_out, prepared.left_out
    assert ("t_r" in prepared.held) == held, prepared.held


@pytest.fixture
def seed_alone() -> Iterator[None]:
    """Hypothesis draws from its seed alone (not from graphcal's literals: a fixed draw
    whatever the code changed)."""
    with drawn_from_the_seed_alone():
        yield


@settings(
    derandomize=True,
    max_examples=20,
    deadline=None,
    database=None,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: the quick tier's time is bounded
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(shape=shapes(car_length_m=QUICK_CAR_M, robot_length_m=QUICK_ROBOT_M))
@example(shape=_shape(vehicle="skid-steer", route="yard", length_m=120.0, gnss_rate=2.5,
                      noise_sigma=1.0, noise_tau_s=30.0, lever_arm=(-0.15, 0.0),
                      wheels="angular_speed"))  # fmt: skip
def test_drawn_shapes_keep_the_data_path_invariants(
    shape: Shape, tmp_path: Path, seed_alone: None
) -> None:
    """Import gives a log or one line naming a real cause (never a traceback); no segment
    holds a masked sample or a run boundary; the tick resolution is the one drawn, none on
    continuous wheel signals."""
    directory = tmp_path / f"shape{abs(hash(shape))}"
    broken = data_path_broken(shape, write_recording(shape, directory))
    assert broken == [], shape.label()


#: A few full calibrations (fixed shapes and seeds): a town car, three drives on one clock
#: (issue 43's first row); shapes the campaign found failing: a skid-steer robot with
#: correlated fixes, a town car with 1.5 m fixes, a straight road with correlated 1.8 m fixes.
SLOW = [
    pytest.param(_shape(length_m=1000.0, gnss_rate=5.0, heading=True, seed=3), id="car-town"),
    pytest.param(
        _shape(drives=3, gap_s=30.0, park_s=5.0, gnss_rate=5.0, length_m=500.0, seed=4),
        id="car-three-drives",
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=156.0,
            gnss_rate=50.0,
            noise_sigma=1.53,
            noise_tau_s=12.0,
            heading=True,
            imu=False,
            park_s=1.0,
            lever_arm=(-0.22, 0.0),
            seed=197,
        ),
        id="skid-steer-correlated-fixes",
    ),
    pytest.param(
        _shape(
            length_m=1824.0,
            gnss_rate=2.5,
            noise_sigma=1.54,
            noise_tau_s=5.0,
            heading=True,
            imu=False,
            wheels="ticks",
            ticks=244,
            park_s=5.0,
            time_offset_s=-0.05,
            lever_arm=(0.0, -0.29),
            seed=244,
        ),
        id="car-noisy-fixes",
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=213.0,
            gnss_rate=50.0,
            noise_sigma=0.33,
            noise_tau_s=24.0,
            heading=True,
            imu=False,
            drives=2,
            gap_s=33.0,
            park_s=5.0,
            time_offset_s=0.001,
            lever_arm=(0.0, 0.0),
            seed=120,
        ),
        id="differential-noisy-wheel-speeds",  # seed 11's shape 2: t_r +3.8σ at the profile's
        # wheel noise (its speeds 26 % noisier per step), the spare noise found as "slip"
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=150.0,
            gnss_rate=0.5,
            noise_sigma=1.92,
            noise_tau_s=11.0,
            heading=True,
            wheels="ticks",
            ticks=287,
            drives=2,
            gap_s=30.0,
            park_s=0.0,
            lever_arm=(0.0, 0.0),
            seed=43832,
        ),
        id="differential-sparse-far-noisier-fixes",  # seed 12's shape 6: fixes of 1.9 m
        # weighted as the profile's 0.05 m, the wheels shifted by 350 ms on that solve and
        # t_r out of range, exit 2 after 110 s; now the noise first, then the shifts
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=2143.0,
            gnss_rate=2.5,
            noise_sigma=1.11,
            heading=False,
            imu=False,
            park_s=0.0,
            lever_arm=(1.5, -0.5),
            seed=65536,
        ),
        id="car-straight-white-fixes-found-twice",  # seed 13's shape 2: 1.10 m fixes left
        # weighted as the 0.887 m an over-fitted solve showed (within the old 25 %), χ²/dof
        # 1.58, "not trusted"
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=1677.0,
            gnss_rate=2.5,
            noise_sigma=1.82,
            noise_tau_s=53.0,
            heading=True,
            imu=False,
            park_s=0.0,
            lever_arm=(0.0, -0.5),
            seed=35368,
        ),
        id="straight-correlated-fixes-confidently-wrong",  # was a strict xfail: d −6.3σ
        # "calibrated" (t_r not observable), its a_y taken from the heading the graph also
        # tracks, on a road that barely turns; now held at its nominal as from the wheels
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=175.0,
            gnss_rate=5.0,
            heading=True,
            wheels="angular_speed",
            drives=3,
            gap_s=33.0,
            park_s=0.0,
            time_offset_s=0.03,
            lever_arm=(0.0, 0.0),
            seed=452,
        ),
        id="skid-steer-spins-fused-heading",  # seed 13's shape 4: the datasheet track (half
        # the effective one) turned the graph's reference path through > π too much in the
        # spins; a rebuilt graph's heading residuals 2π off, χ²/dof 5942, exit 2 after 102 s
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=117.0,
            gnss_rate=0.5,
            noise_sigma=0.36,
            heading=True,
            park_s=0.0,
            time_offset_s=-0.012,
            lever_arm=(-0.17, 0.0),
            seed=114,
        ),
        id="differential-few-fixes-noisier",  # seed 15's shape 2: 78 fixes, fewer than the
        # 100 a noise estimate needed; 0.36 m fixes kept weighted as 0.05 m, χ²/dof 26, exit 3
    ),
    pytest.param(
        _shape(
            route="town",
            length_m=2500.0,
            gnss_rate=20.0,
            noise_sigma=0.5,
            noise_tau_s=48.0,
            imu=False,
            wheels="ticks",
            ticks=218,
            park_s=1.0,
            lever_arm=(0.29, 0.33),
            seed=705,
        ),
        id="town-correlated-fixes-false-slip",  # seed 19's shape 12: slip "found" (z 4.1)
        # where the fixes share 0.5 m over 48 s; the defect model with it predicted 0.997 m,
        # theta alone 0.393 m: theta alone chosen, blind to a 0.33 m arm, c_e -4.9σ
    ),
    pytest.param(
        _shape(**STRAIGHT_POSITIONS_ONLY),
        id="straight-positions-only-lateral-arm",  # seed 19's shape 9 (3 km drives, 275
        # ticks): the arm judged showable from the fixes' course, kept; the warm start ran
        # t_r to 0.0017 m, the solve from the nominal 50 iterations into the same runaway;
        # then the arm not observable, left out, its share of the residuals not re-judged:
        # χ²/dof 1.67 "not to be trusted", exit 3 after 112 s
    ),
    pytest.param(
        _shape(
            length_m=2493.0,
            noise_sigma=1.99,
            imu=False,
            drives=2,
            gap_s=20.0,
            park_s=2.0,
            time_offset_s=-0.032,
            lever_arm=(0.03, 0.3),
            seed=24625,
        ),
        id="town-fixes-ten-times-noisier",  # seed 22's shape 9: 10 Hz fixes of 2 m weighted
        # as the profile's 0.2 m; the first solve crept 41 iterations at χ²/dof 95, and the
        # runs from there ended t_r +3.4σ, d -6.0σ "calibrated" (18 s)
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=1138.0,
            gnss_rate=0.5,
            noise_sigma=0.34,
            noise_tau_s=19.0,
            heading=True,
            park_s=2.0,
            time_offset_s=0.023,
            lever_arm=(1.35, -0.05),
            seed=13,
        ),
        id="few-fixes-sharing-their-error",  # seed 26's shape 17: 25 fixes in 54 s, too few
        # to measure their noise, weighted as the profile's white 0.2 m: c_e +3.9σ "calibrated"
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=1657.0,
            gnss_rate=0.5,
            noise_sigma=0.51,
            heading=True,
            imu=False,
            park_s=0.0,
            time_offset_s=0.05,
            lever_arm=(0.0, 0.0),
            seed=231,
        ),
        id="few-fixes-far-noisier",  # seed 27's shape 15: 29 fixes of 0.5 m weighted as the
        # profile's 0.2 m: χ²/dof 4.1, "not to be trusted", exit 3
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=150.0,
            gnss_rate=50.0,
            noise_sigma=1.7,
            noise_tau_s=10.0,
            heading=True,
            wheels="ticks",
            ticks=72,
            park_s=8.0,
            lever_arm=(-0.3, 0.0),
            seed=379,
        ),
        id="fixes-wandering-far-above-rtk",  # seed 22's shape 4: 50 Hz fixes wandering by
        # 1.7 m, weighted as the profile's RTK 0.05 m: the first solves crept (121 s)
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=106.0,
            gnss_rate=10.0,
            noise_sigma=1.69,
            heading=False,
            imu=False,
            wheels="ticks",
            ticks=500,
            park_s=5.0,
            time_offset_s=-0.03,
            lever_arm=(0.3, 0.0),
            seed=5,
        ),
        id="white-fixes-far-above-rtk",  # seed 29's shape 9: 1.7 m white fixes weighted as
        # RTK 0.05 m; read as 4.5 m shared from a first solve stopped creeping: exit 2
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=206.0,
            gnss_rate=2.5,
            noise_sigma=1.9,
            noise_tau_s=8.0,
            heading=True,
            wheels="angular_speed",
            park_s=4.0,
            time_offset_s=0.032,
            lever_arm=(-0.3, 0.0),
            seed=1577,
        ),
        id="weak-track-far-from-its-nominal",  # seed 30's shape 124: t_r weakly determined
        # at 1.11 ± 0.035 m against the geometric 0.55 m; the validation check put the
        # calibrated c_d beside the nominal t_r, "validates worse": exit 3
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=109.0,
            gnss_rate=1.0,
            noise_sigma=0.85,
            heading=True,
            park_s=6.0,
            lever_arm=(-0.28, 0.0),
            seed=339,
        ),
        id="heading-shows-the-track-sparse-fixes-do-not",  # seed 32's shape 198: the solve
        # stayed at t_r 0.52 m (truth 1.08), its heading 7° off: exit 3
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=2881.0,
            gnss_rate=0.5,
            noise_sigma=0.93,
            imu=False,
            wheels="ticks",
            ticks=16,
            park_s=0.0,
            time_offset_s=-0.009,
            lever_arm=(-0.48, 0.15),
            seed=155,
        ),
        id="sparse-fixes-across-the-track-absorbed",  # seed 32's shape 160: 0.93 m fixes
        # read as 0.50 m (0.68 m along the track, 0.08 m across it: the wheels' corrections
        # turned the trajectory onto them), χ²/dof 1.77, "not to be trusted", exit 3
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=1794.0,
            noise_sigma=0.81,
            heading=True,
            drives=2,
            gap_s=47.0,
            park_s=4.0,
            time_offset_s=-0.047,
            lever_arm=(0.0, 0.0),
            seed=37088,
            outliers=0.01,
            outage_s=24.0,
            slip=0.0007,
            sideslip=True,
        ),
        id="slow-slip-over-the-log",  # seed 36's shape 117: 0.07 % slip over minutes, its
        # chunks' test at z -2.9 (276 scales for what a few slow terms carry): c_e +8.4σ
        # "calibrated" (σ 0.09 mm from the drive tied end to end); the slow test z 5.8
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=2924.0,
            noise_sigma=1.68,
            heading=True,
            imu=False,
            wheels="angular_speed",
            park_s=0.0,
            lever_arm=(0.0, -0.5),
            seed=3559,
            outage_s=22.0,
            slip=0.0013,
            sideslip=True,
        ),
        id="slow-slip-no-test-can-see",  # seed 39's shape 90: 0.13 % slip over a 2.9 km
        # straight road, both slip tests at z < 1: c_e +3.4σ "calibrated" (σ 0.235 mm, the
        # data's own); with the slow slip no test can show in its σ (0.399 mm), +2.0σ
    ),
    pytest.param(
        _yard(
            "skid-steer",
            length_m=200.0,
            gnss_rate=50.0,
            noise_sigma=1.17,
            noise_tau_s=59.0,
            heading=True,
            imu=False,
            wheels="ticks",
            ticks=16,
            drives=3,
            gap_s=60.0,
            park_s=6.0,
            time_offset_s=-0.047,
            lever_arm=(0.1, 0.0),
            seed=1248,
        ),
        id="fixes-sharing-their-error-over-a-minute",  # seed 38's shape 30 without its
        # slip: 1.17 m over 59 s read with the 30 s fix_error_time as 0.83 m: c_e +4.3σ and
        # t_r +4.0σ "calibrated" (over 10 recording seeds mean e/σ +2.3, +1.9); with 60 s
        # 1.2 m, and neither determined by three 65 m drives
    ),
    pytest.param(
        _shape(
            length_m=1852.0,
            noise_sigma=0.47,
            imu=False,
            wheels="angular_speed",
            time_offset_s=0.018,
            lever_arm=(-1.0, 0.27),
            seed=41030,
            outliers=0.002,
            outage_s=59.0,
            slip=0.0028,
        ),
        id="lateral-acceleration-from-a-creeping-solve",  # seed 43's shape 192: a_y from
        # the wheels derived again with a first solve's theta that had crept under far too
        # tight fix weights (c_e -1.7 m, t_r 0.56 m): 252 m/s² in turns, d pinned at its
        # nominal with σ 0.006 mm·s²/m, -199σ "calibrated"
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=100.0,
            noise_sigma=1.01,
            noise_tau_s=6.0,
            imu=False,
            wheels="ticks",
            ticks=28,
            drives=3,
            gap_s=53.0,
            park_s=6.0,
            lever_arm=(0.0, 0.0),
            seed=28,
        ),
        id="damping-that-rejects-every-other-step",  # seed 45's shape 61: the last solve
        # alternated λ 1e-8 (rejected) and 1e-7 (accepted) for 50 iterations, χ²/dof 0.5595
        # at its limit, exit 3; with the gain ratio's damping 15 iterations to 0.55
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=250.0,
            gnss_rate=50.0,
            noise_sigma=0.74,
            noise_tau_s=35.0,
            heading=True,
            imu=False,
            drives=3,
            gap_s=25.0,
            park_s=0.0,
            lever_arm=(0.26, 0.0),
            seed=4178,
            outage_s=29.0,
        ),
        id="fixes-sharing-their-error-within-a-chunk",  # seed 43's shape 194: what the
        # error did within half a chunk weighted as white at each of the 25 fixes there:
        # t_r -3.4σ "calibrated" (mean (e/σ)² 2.86 over 16 recording seeds; 0.85 counted
        # once per half chunk)
    ),
    pytest.param(
        _yard(
            "differential",
            length_m=210.0,
            gnss_rate=5.0,
            noise_sigma=1.03,
            noise_tau_s=43.0,
            heading=False,
            imu=False,
            park_s=4.0,
            time_offset_s=-0.038,
            lever_arm=(0.05, 0.0),
            seed=7916,
            outliers=0.01,
            outage_s=37.0,
        ),
        id="runaway-judged-under-white-weights",  # seed 53's shape 68: t_r ran out in a
        # solve under 1.69 m white weights, its held solve read 1.2 m shared over 60 s, and
        # t_r was judged determined by that white-weighted solve: exit 2 "check the units"
    ),
    pytest.param(
        _shape(
            route="straight",
            length_m=1394.0,
            gnss_rate=2.5,
            noise_sigma=0.44,
            noise_tau_s=17.0,
            heading=True,
            imu=False,
            wheels="ticks",
            ticks=3617,
            park_s=7.0,
            time_offset_s=0.044,
            lever_arm=(0.0, 0.38),
            seed=543,
            outliers=0.01,
        ),
        id="shared-error-read-after-a-crept-first-solve",  # seed 63's shape 5: the first
        # solve crept under 0.2 m weights, the fixes were weighted 0.565 m white from its
        # unfinished fit and never judged again: c_e "calibrated" 12.5σ off
    ),
]


#: Slow-tier shapes whose recording cannot determine c_e (0.5 Hz fixes of 1.9 m on 300 m of
#: a robot's driving): it must say so, not be calibrated.
C_E_UNDETERMINED = {
    "differential-sparse-far-noisier-fixes",
    # 156 m whose 50 Hz fixes share 1.5 m of error over 12 s: about 17 independent looks at
    # the scale over 200 s, c_e's σ 16.5 mm from the data (calibrated needs 4 mm); it once
    # ran the time offset to +4.3 s and c_e to 2.7 m (exit 2), now within 0.6σ, weak
    "skid-steer-correlated-fixes",
    # 150 m whose 50 Hz fixes share 1.7 m of error over 10 s: c_e's σ 15 mm from the data
    # (calibrated needs 2.5 mm)
    "fixes-wandering-far-above-rtk",
    # 106 m of 1.7 m white fixes without heading or IMU: c_e's σ 5.7 mm (calibrated needs 2.5)
    "white-fixes-far-above-rtk",
    # 206 m of fixes sharing 1.9 m over 8 s: c_e's σ 23 mm (calibrated needs 4 mm)
    "weak-track-far-from-its-nominal",
    # three 65 m drives whose 50 Hz fixes share 1.2 m over 59 s
    "fixes-sharing-their-error-over-a-minute",
    # three drives, 100 m in all, of 10 Hz fixes sharing 1 m over 6 s: c_e's σ 15 mm
    "damping-that-rejects-every-other-step",
    # 250 m in three drives whose 50 Hz fixes share 0.74 m over 35 s
    "fixes-sharing-their-error-within-a-chunk",
    # 210 m of 5 Hz fixes sharing 1 m over 43 s, no heading: c_e weakly determined
    "runaway-judged-under-white-weights",
}


@pytest.mark.slow
@pytest.mark.parametrize("shape", SLOW)
def test_calibrations_keep_the_invariants(shape: Shape, tmp_path: Path, request) -> None:
    """Exit 0 (or one line naming a real cause); calibrated parameters within 3σ of the
    truth; a parameter left out says why; c_e calibrated where the recording shows it."""
    result = calibrate(shape, write_recording(shape, tmp_path))
    assert result.broken == [], (shape.label(), result.verdicts, result.ratio, result.line)
    assert result.exit_code == 0
    undetermined = request.node.callspec.id in C_E_UNDETERMINED
    assert result.verdicts["c_e"].startswith("calibrated") != undetermined, result.verdicts


def test_the_summary_sets_values_beyond_3_sigma_beside_what_honest_errors_give():
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "scripts" / "campaign.py"
    spec = importlib.util.spec_from_file_location("campaign_script", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    # 0.27 % of normal errors lie beyond 3σ: 1.3 of 468 values.
    line = script.beyond_line([0.5] * 466 + [3.6, -2.9])
    assert "1 of 468 calibrated values" in line and "put 1.3 there" in line
    assert "chance 0.72" in line  # 1 − (1 − p)^468
    assert "chance 1" in script.beyond_line([0.0] * 10)


def test_a_warm_start_holds_what_the_short_segments_pull_far_from_the_prior(
    tmp_path: Path,
) -> None:
    """Seed 41's shape 188 (a robot's 120 m, 5 Hz fixes of 0.5 m, positions only): its six
    19 m segments on their own put t_r at 0.08 m (prior 0.2 ± 0.025 m); the whole-log solve
    from there crept 50 iterations into a minimum at χ²/dof 4.8, "not to be trusted". From
    the nominal theta: χ²/dof 1.06, every parameter within 1σ of the truth."""
    from graphcal.graph.construction import keys
    from graphcal.graph.optimization.solve_options import SolveOptions
    from graphcal.pipeline.solvers.warm_start import warm_start

    shape = _yard(
        "differential", length_m=120.0, gnss_rate=5.0, noise_sigma=0.52, heading=False,
        imu=True, wheels="speed", park_s=8.0, lever_arm=(0.09, 0.0), seed=48496,
        outliers=0.002,
    )  # fmt: skip
    prepared, vehicle = _prepared(shape, tmp_path)
    spec = prepared.settings.joint.graph_spec()
    assert spec.tied(prepared.data).any()  # a short tied log: theta from its segments untied
    start = warm_start(prepared.data, spec, SolveOptions(50, 1e-7))
    assert start is not None
    theta = start[keys.THETA]
    assert theta[2] == pytest.approx(vehicle.theta_nominal[2], abs=1e-6)  # held, not 0.08 m
    assert abs(theta[0] - 0.503) < 0.005  # the rest from the segments: c_e within 1 %
