"""A drive-log CSV's columns checked against each other in the log's turns, as an import
checks its streams (:mod:`graphcal.recording.import_turns`, :mod:`graphcal.recording.import_units`),
in the CSV's terms:

* the wheels (``n_rl``, ``n_rr``), the track (``px``, ``py``) and the heading (``psi``) must
  turn the same way: the one that turns against the other two names swapped wheels, swapped
  positions (a mirrored track) or a heading of the other sign;
* the lateral acceleration ``ay`` must be about speed × yaw rate of the track in its turns:
  1/9.81 of it is an acceleration in g.

A log that hardly turns (fewer than :data:`~graphcal.log.turns.TURN_MIN_COUNT` clear
turns: a highway) is not judged.
"""

from __future__ import annotations

import numpy as np

from graphcal.log.checks import fail
from graphcal.log.drive_log import COLUMNS, DriveLog
from graphcal.log.turns import (
    TURN_MIN_COUNT,
    WHEEL_TURN_SLACK,
    TrackTurns,
    lateral_acceleration_agreement,
    lateral_acceleration_scale,
    looks_like_g,
    track_turns,
    turning,
)


def _columns(log: DriveLog) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The log's format columns by name and the samples not to judge by ``(N,)``: masked
    (jumps, frozen fixes, an import's gaps) or outlying (isolated spikes)."""
    excluded = np.zeros(len(log), dtype=bool)
    for flags in (log.masked, log.outlying):
        if flags is not None:
            excluded |= flags
    return {name: getattr(log, name) for name in COLUMNS}, excluded


def log_turns(log: DriveLog, nominal: np.ndarray) -> TrackTurns:
    """The track's turns of ``log`` (:func:`~graphcal.log.turns.track_turns`, the masked and
    outlying samples left out), which the checks below share."""
    columns, excluded = _columns(log)
    fixed = None if log.measured is None else log.measured[:, 0]
    return track_turns(columns, excluded, nominal, fixed)


def check_wheels_turn(log: DriveLog, turns: TrackTurns) -> None:
    """One line if the wheels (nominal θ) barely turn where the track (or the heading, if
    logged) turns clearly: in
    :data:`STILL_WHEELS_SHARE` of its clear turns (at least
    :data:`~graphcal.log.turns.TURN_MIN_COUNT`) by less than a
    :data:`~graphcal.log.turns.WHEEL_TURN_SLACK`-th of it — one column a copy of the
    other, or two wheels of one side."""
    reference, clear = turns.track, turns.track_turning
    if int(log.heading_measured.sum()) >= 2:  # a heading's turns hold no fix noise
        reference = turns.turns_of(log.psi)
        with np.errstate(invalid="ignore"):
            clear = np.abs(reference) > STILL_WHEELS_TURN
    if clear.sum() < TURN_MIN_COUNT:
        return
    still = np.abs(turns.wheels[clear]) < np.abs(reference[clear]) / WHEEL_TURN_SLACK
    if still.mean() < STILL_WHEELS_SHARE:
        return
    same = float(np.mean(log.n_rl == log.n_rr))
    turning = "track (px, py)" if reference is turns.track else "heading (psi)"
    what = (
        f"the wheels (n_rl, n_rr) barely turn where the {turning} turns: in "
        f"{still.mean():.0%} of its {int(clear.sum())} clear turns by under "
        f"1/{WHEEL_TURN_SLACK:g} of its turn (the two columns equal in {same:.0%} of the rows)"
    )
    fix = (
        "check that they are the rear left and the rear right wheel (not one copied, not one side)"
    )
    raise fail(log.source, None, None, what, fix)


#: Share of the track's clear turns in which still wheels are refused; with a heading, its
#: turns [rad] over a window that count as clear.
STILL_WHEELS_SHARE = 0.75
STILL_WHEELS_TURN = 0.3


def check_turn_directions(log: DriveLog, nominal: np.ndarray) -> None:
    """One line if the wheels (yaw with the nominal theta ``nominal``), the track and the
    heading do not turn the same way (:meth:`~graphcal.log.turns.Turning.opposite`):
    which columns look swapped or of the other sign, and how to fix them."""
    columns, excluded = _columns(log)
    heading = int(log.heading_measured.sum()) >= 2
    fixed = None if log.measured is None else log.measured[:, 0]
    found = turning(columns, ~excluded, nominal, heading, fixed).opposite()
    if found is None:
        return
    signal, share = found
    if signal == "wheels":
        what = (
            "n_rl and n_rr look swapped: the wheels turn opposite to the heading (psi) and "
            f"the track (px, py) in {share:.0%} of the turns"
        )
        raise fail(log.source, None, None, what, "exchange the two columns")
    if signal == "heading":
        what = (
            "the heading turns opposite to the wheels (n_rl, n_rr) and the track (px, py) in "
            f"{share:.0%} of the turns, apparently of the other sign"
        )
        fix = (
            "negate the column (psi is counter-clockwise from the x axis; a compass heading, "
            "clockwise from north, becomes pi/2 minus it)"
        )
        raise fail(log.source, "psi", None, what, fix)
    if heading:
        what = (
            "px and py look swapped: the track turns opposite to the wheels (n_rl, n_rr) and "
            f"the heading (psi) in {share:.0%} of the turns, a mirrored track"
        )
        raise fail(log.source, None, None, what, "exchange the two columns")
    what = (
        "px and py look swapped, or n_rl and n_rr: the track turns opposite to the wheels in "
        f"{share:.0%} of the turns (no heading to tell which)"
    )
    raise fail(log.source, None, None, what, "exchange the columns of one pair")


def check_lateral_acceleration_units(log: DriveLog, turns: TrackTurns) -> None:
    """One line if ``ay`` is apparently in g: about 1/9.81 of speed × yaw rate of the track
    in its clear turns (:func:`~graphcal.log.turns.track_turns`), or of the other sign (to
    the right in left turns: d then comes out of the other sign). A log without a lateral
    acceleration (``ay`` all 0) or hardly turning is not judged."""
    agreement = lateral_acceleration_agreement(log.ay, turns)
    if agreement is not None and agreement < 1.0 - AY_SIGN_SHARE:
        what = (
            f"the lateral acceleration points against speed × yaw rate of the track (px, py) in "
            f"{1.0 - agreement:.0%} of its turns, apparently of the other sign"
        )
        raise fail(log.source, "ay", None, what, "negate the column (ay positive to the left)")
    found = lateral_acceleration_scale(log.ay, turns, log.dt)
    if found is None or not looks_like_g(found[0]):
        return
    ratio, k, logged, expected = found
    start, end = log.t[turns.ends[k]], log.t[turns.ends[k + 1]]
    raise fail(
        log.source,
        "ay",
        None,
        f"the lateral acceleration is {ratio:.3g}x speed × yaw rate of the track (px, py) in "
        f"its turns (e.g. ay = {logged:.3g} where speed × yaw rate is {expected:.3g} m/s² at t = "
        f"{start:.1f}–{end:.1f} s), apparently in g",
        "multiply the column by 9.81 (ay in m/s², positive to the left)",
    )


#: Share of the clear turns in which ``ay`` must point against the track's speed × yaw rate
#: to be refused as of the other sign.
AY_SIGN_SHARE = 0.75


#: Largest ratio of one rear wheel's rotations to the other's where the track runs straight
#: (c_d moves it by c_d / c_e: 0.1 % for the paper's car): beyond it, one wheel's scale is off.
STRAIGHT_WHEEL_RATIO = 1.1
#: Largest turn [rad] of the track in a window still taken as straight.
STRAIGHT_TRACK_TURN = 0.05


def _straight_windows(turns: TrackTurns, forwards: np.ndarray) -> np.ndarray:
    """The windows of ``turns`` in which the track runs straight (a turn under
    :data:`STRAIGHT_TRACK_TURN`) and the wheels go ``forwards``."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(turns.track) & (np.abs(turns.track) < STRAIGHT_TRACK_TURN) & forwards


def wheel_off_scale(
    columns: dict[str, np.ndarray], turns: TrackTurns, nominal
) -> tuple[str, dict[str, float], int] | None:
    """The rear wheel (``"n_rl"`` or ``"n_rr"``) whose scale is off where one turns more than
    :data:`STRAIGHT_WHEEL_RATIO` times the other on the track's straight windows (the median
    over the windows of :func:`~graphcal.log.turns.track_turns` of the grid's drive-log
    ``columns``): the one whose distance (nominal c_e) departs further from the track's;
    with each wheel's distance over the track's and the windows' count. ``None`` if neither."""
    left = np.add.reduceat(columns["n_rl"], turns.ends[:-1])
    right = np.add.reduceat(columns["n_rr"], turns.ends[:-1])
    straight = _straight_windows(turns, (left > 0) & (right > 0))
    if straight.sum() < TURN_MIN_COUNT:
        return None
    ratio = float(np.median(left[straight] / right[straight]))
    if max(ratio, 1.0 / ratio) <= STRAIGHT_WHEEL_RATIO:
        return None
    chords = turns.chords[straight]
    scales = {
        name: float(np.median(rotations[straight] * nominal[0] / chords))
        for name, rotations in (("n_rl", left), ("n_rr", right))
    }
    off = max(scales, key=lambda name: abs(np.log(scales[name])))
    return off, scales, int(straight.sum())


def check_wheel_ratio(log: DriveLog, turns: TrackTurns, nominal: np.ndarray) -> None:
    """One line if one rear wheel's scale is off (:func:`wheel_off_scale`): its unit, tick
    count or circumference. Judged before the turns' directions, which such wheels turn one
    way only and would call swapped."""
    found = wheel_off_scale(_columns(log)[0], turns, nominal)
    if found is None:
        return
    off, scales, count = found
    other = "n_rr" if off == "n_rl" else "n_rl"
    what = (
        f"where the track (px, py) runs straight, {off} travels {scales[off]:.2f}x its "
        f"distance and {other} {scales[other]:.2f}x (nominal c_e; median of {count} straight "
        f"stretches): {off}'s scale is off"
    )
    fix = f"check {off}'s unit, ticks per revolution or circumference (rev per sample)"
    raise fail(log.source, off, None, what, fix)


#: A track stretched along one direction by more than this factor against the other (the
#: wheels' distance along straight windows as the ruler), beyond
#: :data:`TRACK_STRETCH_SIGMAS` of the fit's own standard error, is refused: positions whose
#: axes were scaled differently (longitude in degrees times 111 km, without cos(latitude)).
TRACK_STRETCH = 1.05
TRACK_STRETCH_SIGMAS = 3.0
#: Windows whose directions (modulo 180°) align this closely (the length of their mean
#: doubled-angle vector) cannot tell one axis from the other.
STRETCH_MAX_ALIGNMENT = 0.8
#: Share of the windows' spread in (chord / travel)² the directions must explain: wheels on
#: a clock 18 s off the track's fit a "stretch" of 1.47 ± 0.13 that explains 14 % of it
#: (axes scaled 1.3x apart: 93 %, a clean log: 0.01 %).
STRETCH_MIN_EXPLAINED = 0.5


def track_stretch(
    dx: np.ndarray, dy: np.ndarray, travelled: np.ndarray
) -> tuple[float, float, float] | None:
    """How far a track is stretched along one direction against the other: from straight
    windows' displacements ``dx``, ``dy`` [m] over the wheels' travel [m] along them, the
    fit (chord / travel)² = A cos²φ + B sin²φ + 2 C cos φ sin φ (the metric the positions'
    axes give distance; a wrong c_e scales it evenly): the square root of its eigenvalues'
    ratio, its standard error and the stretched direction [rad]; ``None`` when the
    directions do not tell (fewer than :data:`~graphcal.log.turns.TURN_MIN_COUNT` windows,
    or all one way) or explain less than :data:`STRETCH_MIN_EXPLAINED` of the spread."""
    if len(dx) < TURN_MIN_COUNT:
        return None
    phi = np.arctan2(dy, dx)
    if abs(np.mean(np.exp(2j * phi))) > STRETCH_MAX_ALIGNMENT:  # (nearly) all one way
        return None
    c, s = np.cos(phi), np.sin(phi)
    design = np.column_stack([c * c, s * s, 2.0 * c * s])
    observed = (dx * dx + dy * dy) / (travelled * travelled)
    coefficients, *_ = np.linalg.lstsq(design, observed, rcond=None)
    residual = observed - design @ coefficients
    dof = len(observed) - 3
    normal = design.T @ design
    if dof < 1 or np.linalg.cond(normal) > 1e6:
        return None
    spread = observed - np.mean(observed)
    if 1.0 - float(residual @ residual) / float(spread @ spread) < STRETCH_MIN_EXPLAINED:
        return None  # the direction explains little: wheels off the track in time, not axes
    covariance = float(residual @ residual) / dof * np.linalg.inv(normal)

    def stretch(k: np.ndarray) -> tuple[float, float]:
        values, vectors = np.linalg.eigh(np.array([[k[0], k[2]], [k[2], k[1]]]))
        if values[0] <= 0.0:
            return np.nan, 0.0
        return float(np.sqrt(values[1] / values[0])), float(np.arctan2(*vectors[::-1, 1]))

    value, direction = stretch(coefficients)
    if not np.isfinite(value):
        return None
    gradient = np.array([(stretch(coefficients + h)[0] - value) / 1e-7 for h in 1e-7 * np.eye(3)])
    return value, float(np.sqrt(max(gradient @ covariance @ gradient, 0.0))), direction


def check_track_stretch(log: DriveLog, turns: TrackTurns, nominal: np.ndarray) -> None:
    """One line if the track is stretched along one direction against the other
    (:func:`track_stretch` over the track's straight windows of
    :func:`~graphcal.log.turns.track_turns`, by more than :data:`TRACK_STRETCH` certainly):
    a calibration would take it for c_e and t_r."""
    starts, ends = turns.ends[:-1], turns.ends[1:]
    wheels = np.add.reduceat(0.5 * (log.n_rl + log.n_rr), starts) * nominal[0]
    straight = _straight_windows(turns, wheels > 0)
    dx = (log.px[ends] - log.px[starts])[straight]
    dy = (log.py[ends] - log.py[starts])[straight]
    found = track_stretch(dx, dy, wheels[straight])
    if found is None:
        return
    stretch, sigma, direction = found
    if stretch - TRACK_STRETCH_SIGMAS * sigma <= TRACK_STRETCH:
        return
    along = np.degrees(direction) % 180.0
    what = (
        f"the track (px, py) is {stretch:.3g}x as long against the wheels' distance along "
        f"{along:.0f}° from the x axis as across it (straight stretches): the axes are scaled "
        "differently"
    )
    fix = (
        "check the conversion to metres (from longitude in degrees, east metres are "
        "111,320 m × cos(latitude) per degree)"
    )
    raise fail(log.source, None, None, what, fix)
