"""``python -m quatform``: the command line of :mod:`quatform.cli` (runs/cli layer)."""

import sys

from .cli import main

sys.exit(main())
