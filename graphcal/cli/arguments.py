"""argparse types of the ``graphcal`` command's options: one clear line each."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np


def at_least(minimum: float, unit: str) -> Callable[[str], float]:
    """An argparse type: a finite number >= ``minimum``."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not (np.isfinite(value) and value >= minimum):
            raise argparse.ArgumentTypeError(f"must be at least {minimum:g} {unit}, got {text!r}")
        return value

    return parse


def in_range(low: float, high: float, unit: str) -> Callable[[str], float]:
    """An argparse type: a finite number in ``[low, high]``."""

    def parse(text: str) -> float:
        value = at_least(low, unit)(text)
        if value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high:g} {unit}, got {text!r}")
        return value

    return parse


def whole(minimum: int) -> Callable[[str], int]:
    """An argparse type: a whole number >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {text!r}")
        return value

    return parse


def non_negative(text: str) -> float:
    """An argparse type: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (np.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def value_option(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    flag: str,
    kind: Callable[[str], Any],
    metavar: str,
    text: str,
) -> None:
    """Add an option that takes one value of type ``kind`` and is ``None`` unless given."""
    parser.add_argument(flag, type=kind, default=None, metavar=metavar, help=text)
