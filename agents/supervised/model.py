"""The per-row regime classifier: one MLP with shared weights per row, and a motion head.

For each row ``i`` the row network ``f`` maps ``[x_i, g]`` (that row's inputs and the global
inputs, both standardized with the training set's mean and spread) to the logits of the row
classes (:data:`agents.supervised.labels.ROW_CLASSES`) and to an embedding ``e_i``; the motion
head maps ``[g, mean_i e_i]`` to the logits of the motion classes. The rows share ``f`` and
enter the motion head through a mean, so permuting the rows permutes the row logits and leaves
the motion logits unchanged (the model is permutation-equivariant across rows, as a Deep Sets
model, Zaheer et al. 2017).
"""

from __future__ import annotations

import torch
from torch import nn

from agents.supervised.labels import MOTION_CLASSES, ROW_CLASSES

__all__ = ["RowRegimeNet"]


class RowRegimeNet(nn.Module):
    """Row classes ``(B, m, 4)`` and motion classes ``(B, 2)`` logits from ``rows``, ``glob``.

    Args:
        n_row: inputs per row ``F_r``.
        n_global: global inputs ``F_g``.
        hidden: width of the hidden layers (two per network).
    """

    def __init__(self, n_row: int, n_global: int, hidden: int = 64) -> None:
        super().__init__()
        self.n_row, self.n_global, self.hidden = int(n_row), int(n_global), int(hidden)
        self.register_buffer("row_mean", torch.zeros(n_row))
        self.register_buffer("row_std", torch.ones(n_row))
        self.register_buffer("glob_mean", torch.zeros(n_global))
        self.register_buffer("glob_std", torch.ones(n_global))
        self.row_body = nn.Sequential(
            nn.Linear(n_row + n_global, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU()
        )
        self.row_head = nn.Linear(hidden, len(ROW_CLASSES))
        self.motion_head = nn.Sequential(
            nn.Linear(n_global + hidden, hidden), nn.ReLU(), nn.Linear(hidden, len(MOTION_CLASSES))
        )

    def set_normalization(self, rows: torch.Tensor, glob: torch.Tensor) -> None:
        """Standardize inputs with the mean and spread of ``rows (N, m, F_r)``, ``glob (N, F_g)``."""
        r = rows.reshape(-1, self.n_row).double()
        g = glob.double()
        self.row_mean.copy_(r.mean(0).float())
        self.row_std.copy_(r.std(0).clamp_min(1e-6).float())
        self.glob_mean.copy_(g.mean(0).float())
        self.glob_std.copy_(g.std(0).clamp_min(1e-6).float())

    def forward(self, rows: torch.Tensor, glob: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(row logits (B, m, 4), motion logits (B, 2))``."""
        x = (rows - self.row_mean) / self.row_std
        g = (glob - self.glob_mean) / self.glob_std
        gi = g[:, None, :].expand(-1, x.shape[1], -1)
        e = self.row_body(torch.cat([x, gi], dim=-1))
        motion = self.motion_head(torch.cat([g, e.mean(dim=1)], dim=-1))
        return self.row_head(e), motion
