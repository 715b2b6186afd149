"""Errors a user can fix. Their message is one line: what, where, how to fix.

The CLI prints such a message and exits with status 2; anything else is a bug.
"""

import math


class GraphcalError(Exception):
    """Base of every error caused by the user's input or settings."""


class CalibrationFailed(GraphcalError, RuntimeError):
    """A solve that did not produce a usable estimate (diverged, singular or implausible)."""


def first_line(message: str) -> str:
    """The first non-empty line of a message (GTSAM's often start with a newline)."""
    return next((line.strip() for line in message.splitlines() if line.strip()), "")


def exception_reason(exc: BaseException) -> str:
    """An exception in one line: its message's first line, or its type's name if it has none."""
    return first_line(str(exc)) or type(exc).__name__


def is_number(value: object) -> bool:
    """A real number as TOML or JSON gives it (``int`` or ``float``, not ``bool``)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_settings(
    section: str,
    positive_vectors: dict | None = None,
    finite_vectors: dict | None = None,
    positive: dict | None = None,
    non_negative: dict | None = None,
    at_least_one: dict | None = None,
) -> None:
    """Range checks of a settings object; raises ``ValueError`` naming ``section.key``."""

    def numbers(value: object) -> list[float]:
        try:
            return [float(v) for v in value]  # type: ignore[union-attr]
        except (TypeError, ValueError):
            return [math.nan]

    for key, value in (positive_vectors or {}).items():
        if not all(math.isfinite(v) and v > 0 for v in numbers(value)):
            shown = [float(f"{v:.6g}") for v in numbers(value)]
            raise ValueError(f"{section}.{key} must be positive finite numbers, got {shown}")
    for key, value in (finite_vectors or {}).items():
        if not all(math.isfinite(v) for v in numbers(value)):
            shown = [float(f"{v:.6g}") for v in numbers(value)]
            raise ValueError(f"{section}.{key} must be finite numbers, got {shown}")
    for key, value in (positive or {}).items():
        if not (is_number(value) and math.isfinite(value) and value > 0):
            raise ValueError(f"{section}.{key} must be a positive number, got {value!r}")
    for key, value in (non_negative or {}).items():
        if not (is_number(value) and math.isfinite(value) and value >= 0):
            raise ValueError(f"{section}.{key} must be a number >= 0, got {value!r}")
    for key, value in (at_least_one or {}).items():
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
            raise ValueError(f"{section}.{key} must be a whole number >= 1, got {value!r}")
