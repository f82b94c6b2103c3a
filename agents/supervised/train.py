"""Training of :class:`~agents.supervised.model.RowRegimeNet`: cross-entropy, early stopping.

The loss is the mean cross-entropy of the row classes over all rows plus that of the motion
classes, each class weighted by ``(N / (K N_c)) ** class_power`` (``0``: unweighted, ``1``:
balanced; the regimes that matter, biased rows and motion events, are the rare ones). Adam
(Kingma & Ba 2015) on mini-batches of steps; after each epoch the loss on the held-out steps
(episodes of other training seeds) is computed, and the weights of the best epoch are kept;
training stops after ``patience`` epochs without improvement (early stopping).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from agents.supervised.collect import Dataset
from agents.supervised.labels import MOTION_CLASSES, ROW_CLASSES
from agents.supervised.model import RowRegimeNet

__all__ = ["TrainConfig", "accuracy_report", "class_weights", "predict_classes", "train_model"]


@dataclass(frozen=True)
class TrainConfig:
    """Hyper-parameters of :func:`train_model`."""

    hidden: int = 64
    epochs: int = 40
    batch: int = 1024
    lr: float = 2e-3
    patience: int = 5
    class_power: float = 0.5
    seed: int = 0


@dataclass
class TrainResult:
    """The trained model and its record."""

    model: RowRegimeNet
    epochs: int
    best_epoch: int
    val_loss: float
    accuracy: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0


def class_weights(y: np.ndarray, k: int, power: float) -> torch.Tensor:
    """``(N / (k N_c)) ** power`` per class ``c`` of the labels ``y`` (absent classes: 1)."""
    n = np.bincount(y.ravel(), minlength=k).astype(np.float64)
    w = np.where(n > 0, (n.sum() / (k * np.maximum(n, 1.0))) ** power, 1.0)
    return torch.tensor(w, dtype=torch.float32)


def _tensors(ds: Dataset) -> tuple[torch.Tensor, ...]:
    return tuple(torch.from_numpy(np.ascontiguousarray(x)) for x in ds[:4])


def predict_classes(model: RowRegimeNet, ds: Dataset, batch: int = 65536) -> tuple[np.ndarray, np.ndarray]:
    """The most probable row ``(N, m)`` and motion ``(N,)`` classes of ``ds``'s inputs."""
    rows, glob = torch.from_numpy(ds.rows), torch.from_numpy(ds.glob)
    out_r, out_m = [], []
    model.eval()
    with torch.no_grad():
        for i in range(0, rows.shape[0], batch):
            lr, lm = model(rows[i : i + batch], glob[i : i + batch])
            out_r.append(lr.argmax(-1).numpy())
            out_m.append(lm.argmax(-1).numpy())
    return np.concatenate(out_r), np.concatenate(out_m)


def accuracy_report(model: RowRegimeNet, ds: Dataset) -> dict[str, Any]:
    """Accuracy and per-class recall (``"nominal": fraction of nominal steps called nominal``, ...)."""
    pr, pm = predict_classes(model, ds)

    def per_class(y: np.ndarray, p: np.ndarray, names: tuple[str, ...]) -> dict[str, Any]:
        out: dict[str, Any] = {"accuracy": float(np.mean(p == y)), "recall": {}, "count": {}}
        for c, n in enumerate(names):
            sel = y == c
            out["recall"][n] = float(np.mean(p[sel] == c)) if sel.any() else float("nan")
            out["count"][n] = int(sel.sum())
        k = len(names)
        out["confusion"] = np.bincount(y.ravel() * k + p.ravel(), minlength=k * k).reshape(k, k).tolist()
        return out

    return {
        "rows": per_class(ds.row_y, pr, ROW_CLASSES),
        "motion": per_class(ds.motion_y, pm, MOTION_CLASSES),
    }


def train_model(
    train: Dataset,
    val: Dataset,
    config: TrainConfig | None = None,
    log: Any = print,
    init: RowRegimeNet | None = None,
) -> TrainResult:
    """Fit a :class:`RowRegimeNet` on ``train``, early-stopped on ``val`` (module docstring).

    ``init``: start from a copy of this model (weights and input normalization; a DAgger round
    goes on from the previous round's model) instead of a fresh one.
    """
    t0 = time.perf_counter()
    config = config or TrainConfig()
    torch.manual_seed(config.seed)
    rows, glob, ry, my = _tensors(train)
    vrows, vglob, vry, vmy = _tensors(val)
    if init is None:
        model = RowRegimeNet(rows.shape[2], glob.shape[1], config.hidden)
        model.set_normalization(rows, glob)
    else:
        model = copy.deepcopy(init)
    ce_row = nn.CrossEntropyLoss(weight=class_weights(train.row_y, len(ROW_CLASSES), config.class_power))
    ce_motion = nn.CrossEntropyLoss(
        weight=class_weights(train.motion_y, len(MOTION_CLASSES), config.class_power)
    )

    def loss_of(r: torch.Tensor, g: torch.Tensor, yr: torch.Tensor, ym: torch.Tensor) -> torch.Tensor:
        lr, lm = model(r, g)
        return ce_row(lr.reshape(-1, lr.shape[-1]), yr.reshape(-1)) + ce_motion(lm, ym)

    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    gen = torch.Generator().manual_seed(config.seed)
    best, best_state, best_epoch, epoch = np.inf, copy.deepcopy(model.state_dict()), 0, 0
    for epoch in range(1, config.epochs + 1):
        model.train()
        perm = torch.randperm(rows.shape[0], generator=gen)
        for i in range(0, rows.shape[0], config.batch):
            b = perm[i : i + config.batch]
            opt.zero_grad()
            loss = loss_of(rows[b], glob[b], ry[b], my[b])
            loss.backward()
            opt.step()
        model.eval()
        with torch.no_grad():
            v = float(
                sum(
                    loss_of(
                        vrows[i : i + 65536], vglob[i : i + 65536], vry[i : i + 65536], vmy[i : i + 65536]
                    )
                    * min(65536, vrows.shape[0] - i)
                    for i in range(0, vrows.shape[0], 65536)
                )
                / max(vrows.shape[0], 1)
            )
        log(f"epoch {epoch:3d}  train loss {loss.item():.4f}  held-out loss {v:.4f}")
        if v < best - 1e-5:
            best, best_state, best_epoch = v, copy.deepcopy(model.state_dict()), epoch
        elif epoch - best_epoch >= config.patience:
            break
    model.load_state_dict(best_state)
    model.eval()
    return TrainResult(model, epoch, best_epoch, best, accuracy_report(model, val), time.perf_counter() - t0)
