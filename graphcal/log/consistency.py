"""Positions checked against the wheels: unit mistakes, absurd values, spikes, frozen fixes.

The pose and the wheel rotations of a drive log measure the same motion, so each can check
the other (with the vehicle's nominal theta, ``nominal``: the paper's car unless given;
calibration changes distances by far less than the factors checked here):

* **absurd positions** (beyond :data:`MAX_POSITION` from the origin) and **unit mistakes**
  (GNSS distance over the whole log far from the wheels' distance: positions in km, cm or
  degrees, rotations per second instead of per sample) reject the log with one line;
* **isolated spikes** (fixes off the track, the next fix back on it within
  :data:`SPIKE_RETURN_S`, e.g. multipath) are flagged as outlying (``DriveLog.outlying``):
  segments keep them and calibration gives them no weight, so many spikes do not cut the
  log into pieces;
* **jumps** (a position step far longer than the wheels allow that does not return; a
  heading step far from the yaw the wheels imply) and **frozen fixes** (a receiver repeating
  its last fix during an outage while the wheels roll) are masked: :func:`screen` returns
  the log with a per-sample mask and a note per span, and
  no calibration or validation segment spans a masked sample
  (:func:`graphcal.log.segments.split_segments`).

Distances are counted in wheel revolutions of the nominal c_e, so that a robot's 0.27 m
wheels and millimetre motion capture are checked as the paper's car (2 m wheels, GNSS) is,
with the car's values unchanged. Wheels turning backwards (a robot reversing, or spinning on
the spot with one wheel backwards: ``VehicleProfile.reverses``) are motion: a step's
distance is compared with a chord by its length, and distance along the path adds it up.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.log.track import COURSE_MIN_REVS, course
from graphcal.log.turns import fix_noise
from graphcal.model import THETA_NOMINAL

#: Largest plausible distance [m] of a position from the local frame's origin (1000 km).
MAX_POSITION = 1e6
#: Accepted range of GNSS distance / wheel distance over the whole log (the fixes' white
#: noise fitted out of the chords: a robot's 1 Hz fixes of 1.9 m doubled 2 m chords), and the
#: window [s] over which both are compared.
DISTANCE_RATIO_RANGE = (0.5, 2.0)
RATIO_WINDOW_S = 2.0
#: Where the fixes' noise is at least this share of the chords' squared length, the
#: distance ratio is not judged: what is left once the noise is taken out is the difference
#: of two noisy sums (a differential robot's 5 Hz fixes of 2 m, 0.3 m of travel per window:
#: the ratio came out 0 and a valid recording was refused).
NOISE_SHARE_JUDGED = 0.5
#: The comparison's windows must each travel :data:`RATIO_MIN_WINDOW_REVS` wheel revolutions
#: (nominal c_e: 5 m for the paper's car), and all of them together
#: :data:`RATIO_MIN_REVS` (50 m), so that the position noise is small next to them.
RATIO_MIN_WINDOW_REVS = 2.5
RATIO_MIN_REVS = 25.0
#: A position step longer than the wheels' step by more than this many wheel revolutions
#: (nominal c_e: 3 m for the paper's car, 0.4 m for a robot with 0.27 m wheels), or by ten
#: times the log's own step noise if that is larger, is a spike.
SPIKE_EXCESS_REVS = 1.5
#: A heading step that differs from the wheels' yaw by more than this [rad], or by ten times
#: the log's own heading-step noise if that is larger, is a heading spike.
HEADING_EXCESS = 0.25
#: Samples masked on each side of a jump [s] (the fix before and after it).
SPIKE_MARGIN_S = 0.5
#: The range of :func:`wheel_turn_scale` (the coarse search's: a skid-steer vehicle's
#: effective track is 1.5–2.5 times its datasheet's) and the turning steps it needs.
WHEEL_TURN_SCALES = (1.0 / 3.0, 3.0)
MIN_TURN_STEPS = 10
#: Fixes off the track for at most this long [s], the next fix back on it, are an isolated
#: spike: flagged outlying, not masked.
SPIKE_RETURN_S = 1.0
#: A fix repeated for at least this long [s] while the wheels travel ...
FROZEN_MIN_S = 1.0
#: ... at least this many revolutions along the path (nominal c_e: 2 m for the paper's car)
#: is frozen.
FROZEN_MIN_REVS = 1.0
#: Above this share of jumping steps no spike counts as isolated.
MAX_SPIKE_SHARE = 0.05
#: A log with more than this share of its samples masked is rejected.
MAX_MASKED_SHARE = 0.5


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(first, last), ...]`` inclusive index ranges of the True runs of ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def wheel_steps(log, *, nominal: np.ndarray = THETA_NOMINAL) -> np.ndarray:
    """Signed distance [m] of each step ``k -> k+1`` from the wheel rotations (nominal c_e),
    ``(N-1,)``: negative backwards (a robot reversing), about 0 in a spin on the spot."""
    return 0.5 * (log.n_rl[:-1] + log.n_rr[:-1]) * nominal[0]


def position_problem(
    log, masked: np.ndarray | None = None, *, nominal: np.ndarray = THETA_NOMINAL
) -> str | None:
    """One line (what, where, how to fix) if the positions cannot be in metres of a local
    frame or disagree with the wheels over the whole log; else ``None``. ``masked``: the
    samples :func:`inconsistent_samples` found (computed if not given), left out;
    ``nominal``: the vehicle's nominal theta."""
    radius = np.hypot(log.px, log.py)
    if (radius > MAX_POSITION).any():
        k = int(np.argmax(radius > MAX_POSITION))
        return (
            f"line {k + 2}: position ({log.px[k]:.6g}, {log.py[k]:.6g}) m is more than "
            f"{MAX_POSITION / 1e3:.0f} km from the origin; give px, py in metres of a local frame "
            "(e.g. ENU around the drive's start), not latitude/longitude or ECEF"
        )
    # Chords over 2 s windows: long enough that position noise is small next to them, short
    # enough that a chord in a bend is nearly the arc. The wheels' net travel in a window
    # against its chord: backwards (a robot reversing) as far as forwards.
    window = max(1, round(RATIO_WINDOW_S / log.dt))
    ends = np.arange(0, len(log), window)
    travelled = np.concatenate([[0.0], np.cumsum(wheel_steps(log, nominal=nominal))])
    wheels = np.abs(np.diff(travelled[ends]))
    chords = np.hypot(np.diff(log.px[ends]), np.diff(log.py[ends]))
    if masked is None:
        masked, _, outlying = inconsistent_samples(log, nominal=nominal)
        masked = masked | outlying
    # A window's chord ends at its last sample: clean takes both ends (a 20 Hz robot's fix
    # 36 m off at a window's end read a 36 m chord for 1.7 m of wheels).
    flagged = np.concatenate([[0], np.cumsum(masked.astype(int))])
    clean = flagged[ends[1:] + 1] - flagged[ends[:-1]] == 0
    usable = clean & (wheels >= RATIO_MIN_WINDOW_REVS * nominal[0])
    if wheels[usable].sum() < RATIO_MIN_REVS * nominal[0]:
        return None
    # A chord between noisy fixes is longer than the path: E|chord|² = d² + 4σ² per window
    # at most (two ends, two axes; less where an end lies between fixes). Too long only with
    # that taken out, too short as it is.
    squared, rolled = np.sum(chords[usable] ** 2), np.sum(wheels[usable] ** 2)
    fixes = log.position_measured
    noise = 4.0 * usable.sum() * fix_noise({"px": log.px, "py": log.py}, fixes) ** 2
    low, high = DISTANCE_RATIO_RANGE
    ratio = np.sqrt(squared / rolled)
    if ratio > high:
        if noise >= NOISE_SHARE_JUDGED * squared:
            return None  # the chords are mostly the fixes' noise: they tell no scale
        ratio = np.sqrt((squared - noise) / rolled)
    if not low <= ratio <= high:
        return (
            f"the positions travel {ratio:.3g}x the distance the wheel rotations imply "
            f"({chords[usable].sum():.0f} m vs {wheels[usable].sum():.0f} m with c_e = "
            f"{nominal[0]:g} m); "
            "give px, py in metres and n_rl, n_rr in revolutions per sample interval, and "
            "check the vehicle's nominal c_e (--vehicle)"
        )
    return None


def inconsistent_samples(
    log, *, nominal: np.ndarray = THETA_NOMINAL
) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Samples whose position disagrees with the wheels, ``(N,)`` bool, one note per span,
    and the isolated spikes' samples ``(N,)`` bool (outlying fixes, not masked).

    The wheel rotations become distance and yaw with ``nominal``, the vehicle's nominal theta.

    Spikes: a distinct fix farther from the previous one than the wheels travelled between
    them (net: backwards counts as forwards) by :data:`SPIKE_EXCESS_REVS` wheel revolutions
    (or ten times the log's own noise). If a later fix within :data:`SPIKE_RETURN_S` is back
    on the track (as far from the last good fix as the wheels travelled, within the same
    tolerance), the fixes between are outlying; otherwise the jump is masked with
    :data:`SPIKE_MARGIN_S` on each side. Frozen fixes: the same position for at least
    :data:`FROZEN_MIN_S` (or five of the receiver's fix intervals, for a receiver slower than
    the log whose fixes are held) while the wheels travel :data:`FROZEN_MIN_REVS` revolutions
    along the path (a spin on the spot travels none).
    """
    n = len(log)
    mask = np.zeros(n, dtype=bool)
    outlying = np.zeros(n, dtype=bool)
    notes: list[str] = []
    if n < 3:
        return mask, notes, outlying
    wheels = wheel_steps(log, nominal=nominal)
    margin = max(1, round(SPIKE_MARGIN_S / log.dt))
    # The rows holding a fix (every row of a uniform log), and which of them repeat the fix
    # before (a receiver at a lower rate than the log, sample-and-hold, or a frozen one).
    rows = np.flatnonzero(log.position_measured)
    same = np.concatenate([[False], np.hypot(np.diff(log.px[rows]), np.diff(log.py[rows])) == 0])
    fixes = rows[~same]
    frozen = _frozen_fixes(log, wheels, rows, same, fixes, notes, nominal)
    spikes, outlying = _position_spikes(log, wheels, fixes, frozen, margin, notes, nominal)
    turns = _heading_jumps(log, margin, frozen | spikes, notes, nominal)
    mask = frozen | spikes | turns | _frozen_wheels(log, notes, nominal)
    return mask, notes, outlying & ~mask


def _frozen_fixes(
    log,
    wheels: np.ndarray,
    rows: np.ndarray,
    same: np.ndarray,
    fixes: np.ndarray,
    notes: list[str],
    nominal: np.ndarray,
) -> np.ndarray:
    """Samples of a fix held (repeated at the rows ``same``) for at least
    :data:`FROZEN_MIN_S` (or five fix intervals) while the wheels travel
    :data:`FROZEN_MIN_REVS` revolutions along the path, ``(N,)``; one note per span."""
    along = np.concatenate([[0.0], np.cumsum(np.abs(wheels))])  # along the path
    fix_interval = float(np.median(np.diff(log.t[fixes]))) if len(fixes) > 1 else log.dt
    # Only a hold much longer than the log's usual one is a frozen fix.
    frozen_min_s = max(FROZEN_MIN_S, 5.0 * fix_interval)
    frozen = np.zeros(len(log), dtype=bool)
    for a, b in runs(same):
        first, last = rows[a - 1], rows[b]  # the fix that is repeated, its last repeat
        if log.t[last] - log.t[first] >= frozen_min_s and (
            along[last] - along[first] >= FROZEN_MIN_REVS * nominal[0]
        ):
            frozen[first : last + 1] = True
            notes.append(
                f"position frozen at t = {log.t[first]:.1f}–{log.t[last]:.1f} s while the "
                f"wheels travelled {_metres(along[last] - along[first], nominal[0])} m: a held fix"
            )
    return frozen


def _frozen_wheels(log, notes: list[str], nominal: np.ndarray) -> np.ndarray:
    """Samples where both wheels repeat one rotation for :data:`FROZEN_WHEELS_MIN_S` and,
    over windows of :data:`FROZEN_WHEELS_WINDOW_S` within that (the chord and the wheels'
    distance, nominal c_e, beyond ten times the fixes' noise), the track moves more than
    :data:`FROZEN_WHEELS_MISMATCH` off the wheels, from the first such window to the last: a
    stale message (tick counts repeat in a steady cruise, where the track keeps their pace),
    ``(N,)``; one note per span."""
    frozen, same = np.zeros(len(log), dtype=bool), log.n_rl[1:] != 0
    for n in (log.n_rl, log.n_rr):  # within an import's resampling jitter
        same &= np.abs(np.diff(n)) <= FROZEN_WHEELS_RTOL * np.abs(n[1:])
    width = max(1, round(FROZEN_WHEELS_WINDOW_S / log.dt))
    least = 10.0 * fix_noise({"px": log.px, "py": log.py})
    for a, b in runs(same):  # rows a..b+1 hold one rotation
        if log.t[b + 1] - log.t[a] < FROZEN_WHEELS_MIN_S:
            continue
        ends = np.arange(a, b + 2, width)
        chords = np.hypot(np.diff(log.px[ends]), np.diff(log.py[ends]))
        wheels = np.abs(0.5 * (log.n_rl[a] + log.n_rr[a]) * nominal[0] * np.diff(ends))
        judged = (chords > least) & (wheels > least)  # reversing counts; a spin travels none
        off = judged & (np.abs(chords / np.maximum(wheels, least) - 1.0) > FROZEN_WHEELS_MISMATCH)
        if not off.any():
            continue
        first, last = np.flatnonzero(off)[[0, -1]]
        rows = slice(ends[first], ends[last + 1] + 1)  # from the first window off to the last
        frozen[rows] = True
        worst = float(np.max(np.abs(chords[off] / wheels[off] - 1.0)))
        notes.append(
            f"wheels frozen at t = {log.t[rows.start]:.1f}–{log.t[rows.stop - 1]:.1f} s (n_rl, "
            f"n_rr repeat one value where the track moves up to {worst:.0%} off their "
            "distance): a stale signal"
        )
    return frozen


#: Stale wheels (:func:`_frozen_wheels`): a repeat's length [s], windows [s], mismatch.
FROZEN_WHEELS_MIN_S = 5.0
FROZEN_WHEELS_WINDOW_S = 2.0
FROZEN_WHEELS_MISMATCH = 0.2
FROZEN_WHEELS_RTOL = 1e-4  # a repeat (a frozen 100 Hz speed resampled varies by 1e-5)


def _position_spikes(
    log,
    wheels: np.ndarray,
    fixes: np.ndarray,
    frozen: np.ndarray,
    margin: int,
    notes: list[str],
    nominal: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Samples around a jump of the distinct ``fixes`` that does not return (masked) and the
    fixes of an isolated spike (outlying), each ``(N,)``; one note per masked span that no
    frozen fix explains."""
    n = len(log)
    travelled = np.concatenate([[0.0], np.cumsum(wheels)])  # net: back where it started
    steps = np.hypot(np.diff(log.px), np.diff(log.py))
    # Each distinct fix against the previous one, over the wheels' travel between them.
    jump = np.hypot(np.diff(log.px[fixes]), np.diff(log.py[fixes]))
    rolled = np.abs(np.diff(travelled[fixes]))
    excess = jump - rolled
    noise = 1.4826 * np.median(np.abs(excess - np.median(excess))) if len(excess) else 0.0
    tolerance = max(SPIKE_EXCESS_REVS * nominal[0], 10.0 * noise)
    spikes = np.zeros(n, dtype=bool)
    outlying = np.zeros(n, dtype=bool)
    jumps = np.flatnonzero(excess > tolerance)
    returned = _returns(log, fixes, travelled, jumps, tolerance)
    handled = np.zeros(len(excess), dtype=bool)  # steps explained by an isolated spike
    for i in jumps:
        if handled[i]:
            continue
        j = returned.get(int(i))
        if j is not None:  # fixes i+1 .. j are off the track, fix j+1 is back on it
            outlying[fixes[i + 1] : fixes[j + 1]] = True
            handled[i : j + 1] = True
            continue
        a, b = fixes[i], fixes[i + 1]
        spikes[max(0, a - margin + 1) : min(n, b + margin)] = True
    for a, b in runs(spikes):
        if frozen[max(0, a - 1) : b + 2].any():
            continue  # the jump where a held fix resumes belongs to that span's note
        notes.append(
            f"position jumps at t = {log.t[a]:.1f}–{log.t[b]:.1f} s (a step up to "
            f"{steps[a : max(a + 1, b)].max():.1f} m where the wheels moved "
            f"{np.abs(wheels[a : max(a + 1, b)]).max():.2f} m): spike"
        )
    return spikes, outlying


def _heading_jumps(
    log, margin: int, explained: np.ndarray, notes: list[str], nominal: np.ndarray
) -> np.ndarray:
    """Samples around a heading step far from the yaw the wheels imply (nominal theta, scaled
    to the heading's turns: :func:`wheel_turn_scale`), from each measured heading to the next
    (per step in a uniform log), ``(N,)``; one note per span not ``explained`` by a frozen
    fix or a position jump."""
    n = len(log)
    wheel_yaw = (log.n_rr[:-1] - log.n_rl[:-1]) * nominal[0] / nominal[2]
    headings = np.flatnonzero(log.heading_measured)
    if len(headings) == n:
        measured_turn, wheel_turn = np.diff(log.psi), wheel_yaw
    else:
        turned = np.concatenate([[0.0], np.cumsum(wheel_yaw)])[headings]
        measured_turn, wheel_turn = np.diff(log.psi[headings]), np.diff(turned)
    scale = wheel_turn_scale(measured_turn, wheel_turn)
    # A heading is an angle: the turn it measures is known up to whole turns (across a gap
    # of a robot's fixes the log read a 1° turn as 359°).
    yaw_excess = np.abs(np.angle(np.exp(1j * (measured_turn - scale * wheel_turn))))
    step_excess = yaw_excess  # per step, for the notes
    if len(headings) < n:
        step_excess = np.zeros(n - 1)
        step_excess[headings[1:] - 1] = yaw_excess
    turns = np.zeros(n, dtype=bool)
    if len(yaw_excess):
        yaw_noise = 1.4826 * np.median(np.abs(yaw_excess - np.median(yaw_excess)))
        for k in np.flatnonzero(yaw_excess > max(HEADING_EXCESS, 10.0 * yaw_noise)):
            if len(headings) < n:  # the samples between the two headings
                k0, k1 = headings[k], headings[k + 1]
                turns[max(0, k0 - margin + 1) : min(n, k1 + margin)] = True
            else:
                turns[max(0, k - margin + 1) : min(n, k + margin + 1)] = True
    for a, b in runs(turns & ~explained):
        notes.append(
            f"heading jumps at t = {log.t[a]:.1f}–{log.t[b]:.1f} s (by up to "
            f"{np.degrees(step_excess[a : max(a + 1, b)].max()):.0f}° more than the wheels turn)"
        )
    return turns


def wheel_turn_scale(measured_turn: np.ndarray, wheel_turn: np.ndarray) -> float:
    """How many times the heading turns as much as the wheels at the nominal theta: the
    median of their ratio over the steps where the wheels turn most (the upper quarter),
    within :data:`WHEEL_TURN_SCALES`; 1 for fewer than :data:`MIN_TURN_STEPS` of them or a
    ratio that is not positive (a heading turning against the wheels is another check's).
    A skid-steer robot's datasheet track is half its effective one: at the nominal its
    wheels turn twice as far as its heading, and its spins on the spot read as heading
    jumps (a 1 Hz heading: "64° more than the wheels turn", 6 s masked)."""
    size = np.abs(wheel_turn)
    if len(size) == 0:
        return 1.0
    turning = size >= max(float(np.percentile(size, 75)), np.finfo(float).tiny)
    if turning.sum() < MIN_TURN_STEPS:
        return 1.0
    ratio = float(np.median(measured_turn[turning] / wheel_turn[turning]))
    if not ratio > 0.0:
        return 1.0
    return float(np.clip(ratio, *WHEEL_TURN_SCALES))


def _returns(
    log, fixes: np.ndarray, travelled: np.ndarray, jumps: np.ndarray, tolerance: float
) -> dict[int, int]:
    """Per jump step ``i`` (fix i → i+1) that an isolated spike explains: the step ``j`` whose
    end fix ``j+1`` is back on the track (as far from fix ``i`` as the wheels travelled,
    within ``tolerance``), at most :data:`SPIKE_RETURN_S` after fix ``i+1``. A log where
    more than :data:`MAX_SPIKE_SHARE` of the steps jump has no isolated spikes (its
    positions are wrong throughout: masked, and refused as mostly masked)."""
    found = {}
    if len(jumps) > MAX_SPIKE_SHARE * len(fixes):
        return found
    for i in jumps:
        start = fixes[i]
        for j in range(i + 1, len(fixes) - 1):
            end = fixes[j + 1]
            if log.t[fixes[j]] - log.t[fixes[i + 1]] > SPIKE_RETURN_S:
                break
            gap = np.hypot(log.px[end] - log.px[start], log.py[end] - log.py[start])
            if abs(gap - abs(travelled[end] - travelled[start])) <= tolerance:
                found[int(i)] = j
                break
    return found


def screen(log, *, nominal: np.ndarray = THETA_NOMINAL):
    """``log`` with its inconsistent samples masked and its isolated spikes flagged outlying
    (:func:`inconsistent_samples`), after
    :func:`position_problem` found nothing to refuse it for (else ``ValueError`` with that
    line). The samples are screened once for both, with the vehicle's nominal theta
    ``nominal``. Samples already masked in ``log`` (gaps an import marked) stay masked, their
    notes first."""
    mask, notes, outlying = inconsistent_samples(log, nominal=nominal)
    if log.masked is not None:
        mask = mask | log.masked
        notes = [*log.mask_notes, *notes]
    problem = position_problem(log, _back_to_the_fix_before(log, mask | outlying), nominal=nominal)
    if problem is not None:
        raise ValueError(problem)
    changes = {}
    if mask.any():
        changes.update(masked=mask, mask_notes=tuple(notes))
    if outlying.any():
        changes["outlying"] = outlying
        if not log.heading_measured.any():  # the course ran through the spikes
            changes["psi"] = _course_without(log, _back_to_the_fix_before(log, outlying), nominal)
    return dataclasses.replace(log, **changes) if changes else log


def _course_without(log, flagged: np.ndarray, nominal: np.ndarray) -> np.ndarray:
    """The heading [rad] of a log without a measured one — the course of its track minus the
    sideslip — taken again on the track between the fixes not ``flagged (N,)``: a chord
    reaching an outlying fix 10–50 m off turned a town car's course by up to 2 rad for a
    second around each, a segment started there, and its first solve ran 300 m off."""
    kept = log.position_measured & ~flagged
    if kept.sum() < 2:
        return log.psi
    x = np.interp(log.t, log.t[kept], log.px[kept])
    y = np.interp(log.t, log.t[kept], log.py[kept])
    dt = float(np.median(np.diff(log.t)))
    beta = 0.0 if log.beta is None else log.beta
    return course(x, y, dt, min_distance=COURSE_MIN_REVS * nominal[0]) - beta


def _back_to_the_fix_before(log, flagged: np.ndarray) -> np.ndarray:
    """``flagged (N,)`` with each run reaching back to the row after the last fix before it:
    between sparse fixes the track is interpolated, so it runs towards a spike from the fix
    before (a skid-steer robot's 0.5 Hz fixes, one 37 m off: the 2 s window before it read a
    37 m chord for 3 m of wheels, and the distance check refused the recording)."""
    fixes = np.flatnonzero(log.position_measured)
    out = flagged.copy()
    if len(fixes) == len(log) or not flagged.any():
        return out
    starts = np.array([a for a, _ in runs(flagged)])
    at = np.searchsorted(fixes, starts)
    first = np.where(at > 0, fixes[np.maximum(at - 1, 0)], -1) + 1  # ≤ its run's start
    cover = np.zeros(len(out) + 1, dtype=np.int64)
    np.add.at(cover, first, 1)
    np.add.at(cover, starts, -1)
    return out | (np.cumsum(cover[:-1]) > 0)


def _metres(distance: float, circumference: float) -> str:
    """A distance [m] for a note: whole metres for a vehicle with wheels of a metre or more
    around (a car), else centimetres (a robot's 0.35 m would read as 0)."""
    return f"{distance:.0f}" if circumference >= 1.0 else f"{distance:.2f}"
