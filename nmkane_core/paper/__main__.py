"""``python -m nmkane_core.paper``: see :mod:`nmkane_core.paper.cli`."""

import sys

from .cli import main

sys.exit(main())
