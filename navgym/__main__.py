import sys

from navgym.cli import main

sys.exit(main())
