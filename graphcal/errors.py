"""Errors a user can fix. Their message is one line: what, where, how to fix.

The CLI prints such a message and exits with status 2; anything else is a bug.
"""


class GraphcalError(Exception):
    """Base of every error caused by the user's input or settings."""


def first_line(message: str) -> str:
    """The first non-empty line of a message (GTSAM's often start with a newline)."""
    return next((line.strip() for line in message.splitlines() if line.strip()), "")
