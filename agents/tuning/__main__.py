"""``python -m agents.tuning``: :func:`agents.tuning.cli.main`."""

import sys

from agents.tuning.cli import main

sys.exit(main())
