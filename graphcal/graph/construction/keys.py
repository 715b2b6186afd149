"""GTSAM keys of every graph graphcal builds: one encoding, one place.

A key is ``gtsam.symbol(letter, index)``. Variables that belong to a segment pack the segment
and their position in it into the index, ``segment * SEGMENT_STRIDE + position``, so keys of
different segments never collide.

=========  ==================  =====================================================
letter     variable            index
=========  ==================  =====================================================
``t``      theta (4-vector)    0, or the slice number of a time-varying theta
``p``      segment Pose2       segment, chunk boundary (0 = the segment's start)
``c``      wheel corrections   segment, chunk (one ``2L``-vector per chunk)
``s``      wheel slip scales   segment, chunk (a 2-vector: rear-left, rear-right)
``o``      wheel time offset   0 (a 1-vector [s])
``a``      antenna lever arm   0 (a 2-vector [m]: ahead, left)
``h``      heading bias        segment (a 1-vector [rad])
``e``      fixes' shared error segment, chunk (a 2-vector [m]: east, north)
``x``      keyframe Pose2      keyframe number (localization graphs)
``w``      wheel slip scales   span number (localization graphs; a 2-vector)
``g``      wheel slip scales   GNSS gap number (localization graphs; a 2-vector)
=========  ==================  =====================================================
"""

from __future__ import annotations

import gtsam

#: Positions per segment in a packed index (chunks or steps of one segment).
SEGMENT_STRIDE = 1 << 24
#: Letters of the variables that belong to one segment (a packed index); a segment graph's
#: other variables are graph-wide.
SEGMENT_LETTERS = frozenset("pcseh")
#: Letters of the Pose2 variables (every other variable is a vector).
POSE_LETTERS = frozenset("px")
#: Bits of a key below its letter (GTSAM's ``Symbol``).
INDEX_BITS = 56


def theta(slice_index: int = 0) -> int:
    """Key of theta ``[c_e, c_d, t_r, d]``; ``slice_index`` numbers the slices of an online run."""
    return gtsam.symbol("t", slice_index)


#: The key of the one shared theta of a calibration or smoothing graph.
THETA = theta(0)


def _packed(segment: int, position: int) -> int:
    if not 0 <= position < SEGMENT_STRIDE:
        raise ValueError(f"position {position} outside 0..{SEGMENT_STRIDE - 1}")
    return segment * SEGMENT_STRIDE + position


def segment_of(key: int) -> int:
    """The segment a segment variable's key belongs to (the inverse of the packing)."""
    return int(gtsam.Symbol(key).index()) // SEGMENT_STRIDE


def in_segment(key: int, segment: int) -> int:
    """The key of the same variable (letter and position) in another segment: a segment
    graph's value moved to a graph of a subset of its segments."""
    symbol = gtsam.Symbol(key)
    return gtsam.symbol(chr(symbol.chr()), _packed(segment, int(symbol.index()) % SEGMENT_STRIDE))


def segment_pose(segment: int, boundary: int = 0) -> int:
    """Key of the Pose2 at chunk boundary ``boundary`` of ``segment`` (0: the segment's start)."""
    return gtsam.symbol("p", _packed(segment, boundary))


def segment_corrections(segment: int, chunk: int) -> int:
    """Key of the ``2L``-vector of wheel-rotation corrections of ``chunk`` of ``segment``."""
    return gtsam.symbol("c", _packed(segment, chunk))


def segment_slip(segment: int, chunk: int = 0) -> int:
    """Key of the 2-vector of relative wheel-slip scales ``[s_rl, s_rr]`` of ``chunk`` of
    ``segment``."""
    return gtsam.symbol("s", _packed(segment, chunk))


def segment_fix_offset(segment: int, chunk: int = 0) -> int:
    """Key of the 2-vector world-frame error ``[east, north]`` [m] the fixes of ``chunk`` of
    ``segment`` share (a slowly varying GNSS error)."""
    return gtsam.symbol("e", _packed(segment, chunk))


#: The wheels' time offset against the pose [s] (1-vector).
TIME_OFFSET = gtsam.symbol("o", 0)
#: The GNSS antenna's lever arm ``[ahead, left]`` [m] from the centre of gravity (2-vector).
LEVER_ARM = gtsam.symbol("a", 0)
#: The rear tyres' slip gain [rad per m/s²] of a log without a sideslip (1-vector): the model's
#: point, the rear axle, moves at the sideslip ``−gain · a_y`` to the heading.
REAR_SLIP_GAIN = gtsam.symbol("r", 0)


def segment_heading_bias(segment: int) -> int:
    """Key of the 1-vector bias [rad] of the measured heading over ``segment``."""
    return gtsam.symbol("h", _packed(segment, 0))


def keyframe(index: int) -> int:
    """Key of keyframe ``index``'s Pose2 in a localization graph."""
    return gtsam.symbol("x", index)


def keyframe_slip(span: int) -> int:
    """Key of the 2-vector of relative wheel-slip scales of ``span`` of a localization graph
    (a span is a run of consecutive keyframe intervals)."""
    return gtsam.symbol("w", span)


def gap_slip(gap: int) -> int:
    """Key of the 2-vector of relative wheel-slip scales over GNSS gap ``gap`` of a
    localization graph (one scale for the whole gap)."""
    return gtsam.symbol("g", gap)
