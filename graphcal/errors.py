"""Errors a user can fix. Their message is one line: what, where, how to fix.

The CLI prints such a message and exits with status 2; anything else is a bug.
"""


class GraphcalError(Exception):
    """Base of every error caused by the user's input or settings."""
