"""``python -m graphcal.cli``: the ``graphcal`` command."""

import sys

from graphcal.cli import entry

sys.exit(entry())
