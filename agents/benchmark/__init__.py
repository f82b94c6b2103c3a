"""``navgym benchmark``: the standard evaluation protocol and its leaderboard.

* :mod:`agents.benchmark.protocol`: every policy of an id (plain, every tuned baseline, the bar,
  the agents, the references) on the same held-out episodes; the leaderboard rows;
* :mod:`agents.benchmark.agent_specs`: the AGENT arguments (supervised, SB3, ``seed_*`` folders);
* :mod:`agents.benchmark.references`: the clairvoyant filter and the regime oracle;
* :mod:`agents.benchmark.aggregate`: IQM and stratified-bootstrap CIs across training seeds
  (Agarwal et al. 2021);
* :mod:`agents.benchmark.leaderboard`: ``leaderboard.md`` / ``.json`` / ``.csv``, ``manifest.json``;
* :mod:`agents.benchmark.cli`: the command line.
"""

from agents.benchmark.agent_specs import AgentSpec, parse_agent
from agents.benchmark.aggregate import across_seeds, iqm, stratified_bootstrap_ci
from agents.benchmark.protocol import Leaderboard, run_protocol

__all__ = [
    "AgentSpec",
    "Leaderboard",
    "across_seeds",
    "iqm",
    "parse_agent",
    "run_protocol",
    "stratified_bootstrap_ci",
]
