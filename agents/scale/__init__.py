"""Beyond one machine: navgym's training sweeps, evaluation and baseline tuning on Ray.

The modules import Ray lazily (only when a function that needs it runs), so this package and
the commands that use it load without the ``scale`` extra; a command that needs Ray then says
how to get it (``pip install -e ".[scale]"``) and exits with status 2 (:mod:`.ray_runtime`).

* :mod:`.specs` — ``--seeds 0..9`` and ``--grid KEY=V1,V2`` parsing, the trials of a sweep;
* :mod:`.summary` — per-config mean and 95 % t-interval over seeds of the trials' metrics;
* :mod:`.sweep` — ``navgym sweep``: one SB3 training (:func:`agents.training.train`) and one
  held-out evaluation (:func:`agents.evaluation.evaluate`) per Ray Tune trial, resumable
  (``tune.Tuner.restore``);
* :mod:`.distributed_eval` — ``navgym eval --workers N --ray``: the held-out episodes split over Ray
  tasks, merged into the result single-process evaluation gives, bit for bit;
* :mod:`.ray_tuning` — ``navgym tune --ray``: the baselines' grid search as Ray Tune trials
  (Optuna search with ``--samples`` where the grid is large).
"""
