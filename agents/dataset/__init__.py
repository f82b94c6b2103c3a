"""Datasets of episodes for offline RL: ``navgym dataset`` (:mod:`agents.dataset.command`)."""
