"""A per-row shared actor-critic policy for per-row knobs (the RowScale ids, v3).

A RowScale action holds one noise multiplier per measurement row and a process-noise scale. An
MLP over the whole observation must learn the same rule once per row (satellite 3 and satellite
9 are the same kind of thing) and ties each row's knob to the row's position in the vector.
:class:`RowSharedPolicy` applies **one network to every row** instead, as a Deep Sets model
(Zaheer et al. 2017, "Deep Sets", NeurIPS) and as the per-satellite networks of learned GNSS
weighting (Li et al. 2023, Satellite Navigation 4:12):

* the row network ``f`` maps ``[x_i, g]`` (row ``i``'s features and the global features) to an
  embedding ``h_i = f(x_i, g)``, weights shared across rows;
* the global head maps ``[g, mean_i h_i]`` to an embedding ``h_g``;
* the action head gives row ``i``'s action mean ``w_r . h_i + b_r`` (shared) and the
  process-noise scale's ``w_g . h_g + b_g``: ``(B, m + 1)``;
* the critic is an MLP over the whole observation (its value needs no symmetry).

Permuting the rows permutes the row actions and leaves the process-noise action unchanged. The
columns of each row and the global columns come from the env's observation features
(:func:`row_layout`): per-row features are those of width ``m`` (``innovation``, ``row_cn0``,
``log_row_scale``, ...; ``previous_action``'s first ``m``), and a residual agent's appended base
action (:mod:`agents.training.residual`) gives each row its own base action. Everything else is
global. The layout is a policy keyword argument, so a saved agent records it (``config.yml``).

Built on SB3's :class:`~stable_baselines3.common.policies.ActorCriticPolicy` (its Gaussian
action distribution, orthogonal initialization with gain 0.01 on the action head, optimizer):
only the latent networks and the action head are replaced.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.policies import ActorCriticPolicy
from torch import nn

from agents.supervised.features import ROW_FEATURES

__all__ = ["POLICIES", "RowActionHead", "RowSharedExtractor", "RowSharedPolicy", "row_layout"]

#: Observation features of width ``m_max`` read per row (the rest are global): those of the
#: supervised agent's rows, and the applied multipliers (the supervised agent leaves them out to
#: avoid exposure bias; an on-policy learner reads its own past actions).
PER_ROW = (*ROW_FEATURES, "log_row_scale")


def row_layout(features: Any, m: int, observe_base: bool = False) -> dict[str, list]:
    """``{"row_columns": (m, F_r) lists, "global_columns": list}`` of an observation.

    Args:
        features: the env's :class:`~navgym.envs.features.FeatureSet` (``observation_features``).
        m: the rows (``task.m_max``).
        observe_base: a residual agent's observation: the base action ``(m + 1)`` appended after
            the env's columns (row ``i``'s entry to row ``i``, the last one global).

    Raises:
        ValueError: no per-row feature of width ``m`` (not a per-row task).
    """
    row_cols: list[list[int]] = [[] for _ in range(m)]
    glob: list[int] = []
    for name in features.names:
        s = features.index(name)
        width = s.stop - s.start
        if (name in PER_ROW and width == m) or (name == "previous_action" and width == m + 1):
            for i in range(m):
                row_cols[i].append(s.start + i)
            glob.extend(range(s.start + m, s.stop))
        else:
            glob.extend(range(s.start, s.stop))
    if not row_cols[0]:
        raise ValueError(
            f"the observation has no per-row feature of width m={m} (names: {list(features.names)})"
        )
    if observe_base:
        d = int(features.dim)
        for i in range(m):
            row_cols[i].append(d + i)
        glob.append(d + m)
    return {"row_columns": row_cols, "global_columns": glob}


def _mlp(n_in: int, hidden: int, activation: type[nn.Module]) -> nn.Sequential:
    return nn.Sequential(nn.Linear(n_in, hidden), activation(), nn.Linear(hidden, hidden), activation())


class RowSharedExtractor(nn.Module):
    """Latent networks: per-row embeddings and a global one for the actor, an MLP for the critic.

    ``forward_actor`` returns ``(B, (m + 1) H)``: ``h_1 .. h_m`` then ``h_g`` (module docstring).
    """

    row_idx: torch.Tensor  # (m, F_r) buffer
    glob_idx: torch.Tensor  # (G,) buffer

    def __init__(
        self,
        feature_dim: int,
        row_columns: Sequence[Sequence[int]],
        global_columns: Sequence[int],
        hidden: int = 64,
        activation: type[nn.Module] = nn.Tanh,
    ) -> None:
        super().__init__()
        rows = np.asarray(row_columns, dtype=np.int64)
        glob = np.asarray(global_columns, dtype=np.int64)
        if rows.ndim != 2 or rows.shape[0] < 1 or rows.shape[1] < 1:
            raise ValueError(f"row_columns must be m >= 1 lists of equal length >= 1; got shape {rows.shape}")
        cols = np.concatenate([rows.ravel(), glob])
        if cols.min() < 0 or cols.max() >= feature_dim:
            raise ValueError(f"row_columns and global_columns must index [0, {feature_dim - 1}]")
        self.register_buffer("row_idx", torch.as_tensor(rows))
        self.register_buffer("glob_idx", torch.as_tensor(glob))
        self.m, self.hidden = int(rows.shape[0]), int(hidden)
        n_row, n_glob = int(rows.shape[1]), int(glob.size)
        self.row_net = _mlp(n_row + n_glob, hidden, activation)
        self.global_net = _mlp(n_glob + hidden, hidden, activation)
        self.value_net = _mlp(feature_dim, hidden, activation)
        self.latent_dim_pi = hidden * (self.m + 1)
        self.latent_dim_vf = hidden

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features: torch.Tensor) -> torch.Tensor:
        rows = features[:, self.row_idx]  # (B, m, F_r)
        g = features[:, self.glob_idx]  # (B, G)
        h = self.row_net(torch.cat([rows, g[:, None, :].expand(-1, self.m, -1)], dim=-1))  # (B, m, H)
        hg = self.global_net(torch.cat([g, h.mean(dim=1)], dim=-1))
        return torch.cat([h.flatten(1), hg], dim=-1)

    def forward_critic(self, features: torch.Tensor) -> torch.Tensor:
        return self.value_net(features)


class RowActionHead(nn.Module):
    """Action means ``(B, m + 1)`` from the latent ``(B, (m + 1) H)``: one shared row head, one global."""

    def __init__(self, m: int, hidden: int) -> None:
        super().__init__()
        self.m, self.hidden = int(m), int(hidden)
        self.row = nn.Linear(hidden, 1)
        self.glob = nn.Linear(hidden, 1)

    def forward(self, latent: torch.Tensor) -> torch.Tensor:
        h = latent[:, : self.m * self.hidden].reshape(-1, self.m, self.hidden)
        return torch.cat([self.row(h).squeeze(-1), self.glob(latent[:, self.m * self.hidden :])], dim=-1)


class RowSharedPolicy(ActorCriticPolicy):
    """SB3 actor-critic with the per-row shared actor (module docstring); Box actions of ``m + 1``.

    Args:
        row_columns: ``(m, F_r)`` observation columns of each row (:func:`row_layout`).
        global_columns: the global columns.
        hidden: width of every hidden layer (two per network).
        (the rest as :class:`~stable_baselines3.common.policies.ActorCriticPolicy`; ``net_arch``
        is not used.)
    """

    def __init__(
        self,
        observation_space: Any,
        action_space: Any,
        lr_schedule: Any,
        row_columns: Sequence[Sequence[int]] = (),
        global_columns: Sequence[int] = (),
        hidden: int = 64,
        **kwargs: Any,
    ) -> None:
        self.row_columns = [list(map(int, r)) for r in row_columns]
        self.global_columns = list(map(int, global_columns))
        self.hidden = int(hidden)
        m = len(self.row_columns)
        if m < 1 or tuple(action_space.shape) != (m + 1,):
            raise ValueError(
                f"RowSharedPolicy needs row_columns of the m rows and an action of m + 1 entries; got "
                f"{m} rows and the action space {action_space}"
            )
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_mlp_extractor(self) -> None:
        # SB3 types the attribute as its MlpExtractor; any module with its four members serves.
        self.mlp_extractor = RowSharedExtractor(  # type: ignore[assignment]
            self.features_dim, self.row_columns, self.global_columns, self.hidden, self.activation_fn
        )

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)
        self.action_net = RowActionHead(len(self.row_columns), self.hidden)
        if self.ortho_init:
            self.action_net.apply(partial(self.init_weights, gain=0.01))
        self.optimizer = self.optimizer_class(  # as SB3's _build; its Optimizer type lacks ``lr``
            self.parameters(),
            lr=lr_schedule(1),
            **self.optimizer_kwargs,  # type: ignore[call-arg]
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(row_columns=self.row_columns, global_columns=self.global_columns, hidden=self.hidden)
        return data


#: navgym's policies by the name an entry's ``policy`` gives (beside SB3's aliases).
POLICIES: dict[str, type[ActorCriticPolicy]] = {"RowSharedPolicy": RowSharedPolicy}
