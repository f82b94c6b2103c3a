import sys

from agents.training.cli import main

sys.exit(main())
