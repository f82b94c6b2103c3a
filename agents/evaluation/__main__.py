"""``python -m agents.evaluation --env ID --policies ... --episodes N --out DIR``."""

import sys

from agents.evaluation.cli import main

if __name__ == "__main__":
    sys.exit(main())
