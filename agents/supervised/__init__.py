"""Supervised imitation of the RowScale regime oracle (gate G2 of the v3 ids).

The RowScale task's regime oracle sets each row's noise scale from the row's *true* regime
(nominal / noisy / biased) and the process-noise scale from the motion's (nominal / event). This
package learns to recognize those regimes from the observation alone and acts through the same
table:

* :mod:`~agents.supervised.labels`: the labels (the oracle's classification, read from the truth
  of the step the action is applied at; plus *not received*);
* :mod:`~agents.supervised.features`: per-row and global inputs from observations;
* :mod:`~agents.supervised.collect`: batched labelled rollouts on training seeds;
* :mod:`~agents.supervised.model`: the per-row classifier (shared weights, permutation-equivariant);
* :mod:`~agents.supervised.train`: cross-entropy training with early stopping;
* :mod:`~agents.supervised.policy`: :class:`SupervisedRowScalePolicy` (SB3-style ``predict``);
* :mod:`~agents.supervised.files`: weights (``torch.load(weights_only=True)``) and JSON manifest;
* :mod:`~agents.supervised.study`: the held-out comparison and gate G2;
* :mod:`~agents.supervised.command`: ``python -m agents.supervised``.
"""

from agents.supervised.files import SupervisedLoadError, load_policy, save_policy
from agents.supervised.labels import MOTION_CLASSES, ROW_CLASSES, StepLabels, next_step_labels
from agents.supervised.model import RowRegimeNet
from agents.supervised.policy import SupervisedRowScalePolicy

__all__ = [
    "MOTION_CLASSES",
    "ROW_CLASSES",
    "RowRegimeNet",
    "StepLabels",
    "SupervisedLoadError",
    "SupervisedRowScalePolicy",
    "load_policy",
    "next_step_labels",
    "save_policy",
]
