"""Paired Monte Carlo evaluation of policies on identical seeded episodes.

* :func:`evaluate` (``runner``): every policy on the same episodes (one batched rollout each),
  per-episode metrics (``metrics``), summary and paired differences against the best baseline
  with bootstrap CIs (``bootstrap``).
* :func:`~agents.evaluation.parts.forked_evaluate` (``parts``): the same evaluation split into
  parts of the seeds over forked processes, merged bit for bit.
* :func:`write_outputs` (``report``): CSV, markdown table, plots, manifest.
* :func:`run_eval`, :func:`add_arguments`, :func:`run` (``cli``): the ``navgym eval`` job.
"""

from agents.evaluation.bootstrap import bootstrap_mean_ci, paired_difference
from agents.evaluation.cli import add_arguments, parse_policies, run, run_eval
from agents.evaluation.metrics import METRICS, PAIRED_METRICS, episode_metrics
from agents.evaluation.report import results_table, write_outputs
from agents.evaluation.runner import EvalResults, Rollout, evaluate, make_vector_env, rollout

__all__ = [
    "METRICS",
    "PAIRED_METRICS",
    "EvalResults",
    "Rollout",
    "add_arguments",
    "bootstrap_mean_ci",
    "episode_metrics",
    "evaluate",
    "make_vector_env",
    "paired_difference",
    "parse_policies",
    "results_table",
    "rollout",
    "run",
    "run_eval",
    "write_outputs",
]
