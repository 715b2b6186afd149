"""The time unit of a stream judged against the recording's other streams: the span they cover.

A median sample interval alone cannot tell a 1 Hz receiver stamped in seconds from a 1 kHz
IMU stamped in milliseconds (both read 1 s apart). The streams of one recording cover about
the same stretch of time, though; a stream whose span, read in its declared unit, is a power
of 1000 off the others' while another unit makes it agree is stamped in that unit.
"""

from __future__ import annotations

import numpy as np

from graphcal.recording.manifest.columns import PLAUSIBLE_STREAM_RATE_HZ, _interval_text
from graphcal.recording.section import Section
from graphcal.recording.streams import StreamError
from graphcal.recording.vocabulary import TIME_UNITS

#: Streams of one recording cover spans within this factor of each other (one starts late,
#: one drops out), far inside the factor 1000 between two time units.
SPAN_AGREEMENT = 10.0


def check_time_spans(timed: list[tuple[Section, str, np.ndarray]]) -> None:
    """Refuse, in one line, a stream ``(section, source, times [s])`` whose span disagrees
    with every other stream's by more than :data:`SPAN_AGREEMENT` when another time unit
    makes it agree with all of them at a plausible rate: the ``time_unit`` to set."""
    spans = np.array([float(t[-1] - t[0]) if len(t) > 1 else 0.0 for _, _, t in timed])
    if len(timed) < 2 or np.any(spans <= 0):
        return
    for i, (section, source, t) in enumerate(timed):
        others = np.delete(spans, i)
        ratio = others / spans[i]
        if np.any((ratio > 1 / SPAN_AGREEMENT) & (ratio < SPAN_AGREEMENT)):
            continue  # agrees with some other stream
        unit = section.choice("time_unit", TIME_UNITS, "s")
        interval = float(np.median(np.diff(t)))  # [s] as declared
        for name, scale in TIME_UNITS.items():
            factor = scale / TIME_UNITS[unit]
            agrees = np.all(np.abs(np.log(ratio / factor)) < np.log(SPAN_AGREEMENT))
            rate = 1.0 / (interval * factor)
            if name == unit or not agrees:
                continue
            if not PLAUSIBLE_STREAM_RATE_HZ[0] <= rate <= PLAUSIBLE_STREAM_RATE_HZ[1]:
                continue
            declared = section.declaration("time_unit", "s")
            raise StreamError(
                f"the times of {source} look like {name} (they span "
                f"{_interval_text(spans[i])} read as {unit}, {declared}"
                f", the other streams {_interval_text(float(np.median(others)))}; a "
                f"{1 / interval:.3g} Hz sensor, in {name} a {rate:.3g} Hz one): set time_unit = "
                f'"{name}" in [{section.name}]'
            )
