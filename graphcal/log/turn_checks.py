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


def check_lateral_acceleration_units(log: DriveLog, nominal: np.ndarray) -> None:
    """One line if ``ay`` is apparently in g: about 1/9.81 of speed × yaw rate of the track
    in its clear turns (:func:`~graphcal.log.turns.track_turns`). A log
    without a lateral acceleration (``ay`` all 0) or hardly turning is not judged."""
    columns, excluded = _columns(log)
    fixed = None if log.measured is None else log.measured[:, 0]
    turns = track_turns(columns, excluded, nominal, fixed)
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


#: Largest ratio of one rear wheel's rotations to the other's where the track runs straight
#: (c_d moves it by c_d / c_e: 0.1 % for the paper's car): beyond it, one wheel's scale is off.
STRAIGHT_WHEEL_RATIO = 1.1
#: Largest turn [rad] of the track in a window still taken as straight.
STRAIGHT_TRACK_TURN = 0.05


def check_wheel_ratio(log: DriveLog, nominal: np.ndarray) -> None:
    """One line if one rear wheel turns more than :data:`STRAIGHT_WHEEL_RATIO` times the
    other where the track runs straight (the median over the track's straight windows of
    :func:`~graphcal.log.turns.track_turns`): a wheel's unit, tick count or circumference is
    off. Judged before the turns' directions, which such wheels turn one way only and would
    call swapped."""
    columns, excluded = _columns(log)
    fixed = None if log.measured is None else log.measured[:, 0]
    turns = track_turns(columns, excluded, nominal, fixed)
    starts = turns.ends[:-1]
    left = np.add.reduceat(log.n_rl, starts)
    right = np.add.reduceat(log.n_rr, starts)
    with np.errstate(invalid="ignore"):
        straight = (
            np.isfinite(turns.track)
            & (np.abs(turns.track) < STRAIGHT_TRACK_TURN)
            & (left > 0)
            & (right > 0)
        )
    if straight.sum() < TURN_MIN_COUNT:
        return
    ratio = float(np.median(left[straight] / right[straight]))
    if max(ratio, 1.0 / ratio) <= STRAIGHT_WHEEL_RATIO:
        return
    # the wheel whose distance (nominal c_e) departs further from the track's is off
    chords = turns.chords[straight]
    scales = {
        name: float(np.median(rotations[straight] * nominal[0] / chords))
        for name, rotations in (("n_rl", left), ("n_rr", right))
    }
    off = max(scales, key=lambda name: abs(np.log(scales[name])))
    other = "n_rr" if off == "n_rl" else "n_rl"
    what = (
        f"where the track (px, py) runs straight, {off} travels {scales[off]:.2f}x its "
        f"distance and {other} {scales[other]:.2f}x (nominal c_e; median of "
        f"{int(straight.sum())} straight stretches): {off}'s scale is off"
    )
    fix = f"check {off}'s unit, ticks per revolution or circumference (rev per sample)"
    raise fail(log.source, off, None, what, fix)
