"""The progress callback every long step takes: one line of text at a time.

``progress=print`` shows them, ``None`` keeps a step quiet; the CLI prefixes the elapsed time.
"""

from collections.abc import Callable

#: Receives one line of progress text (no newline).
Progress = Callable[[str], None]
