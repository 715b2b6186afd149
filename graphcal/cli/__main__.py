"""``python -m graphcal.cli``: the ``graphcal`` command."""

import sys

from graphcal.cli import main

sys.exit(main())
