"""``python -m agents.supervised`` (:mod:`agents.supervised.command`)."""

from agents.supervised.command import main

if __name__ == "__main__":
    main()
