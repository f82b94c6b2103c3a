"""Saving and loading a supervised RowScale policy: ``weights.pt`` and ``manifest.json``.

The folder holds the model's ``state_dict`` saved by ``torch.save`` (read back with
``torch.load(..., weights_only=True)``: tensors only, no pickled code) and a JSON manifest: the
format, the env id and keyword arguments, the observation's feature layout (``{name: width}``)
and the model's input names, the network's sizes, the oracle's table and the classes, the
training record (seeds, behaviour, command, accuracy, wall time) and the SHA-256 of the weights.

:func:`load_policy` checks the weights against the hash and the env's observation layout against
the manifest's; a mismatch raises :class:`SupervisedLoadError` naming the file or the features.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch

from agents.supervised.features import RowFeatures
from agents.supervised.labels import MOTION_CLASSES, ROW_CLASSES
from agents.supervised.model import RowRegimeNet
from agents.supervised.policy import SupervisedRowScalePolicy, tuned_iae
from agents.training.agent_files import sha256_file, write_json_atomic
from navgym.envs.base import navigation_env

__all__ = [
    "FORMAT",
    "KIND",
    "MANIFEST",
    "WEIGHTS",
    "SupervisedLoadError",
    "load_policy",
    "read_manifest",
    "save_policy",
]

FORMAT = 1
KIND = "supervised_rowscale"
WEIGHTS = "weights.pt"
MANIFEST = "manifest.json"


class SupervisedLoadError(ValueError):
    """A saved supervised policy is missing a file, changed since saving, or serves another env."""


def save_policy(
    folder: str | Path,
    policy: SupervisedRowScalePolicy,
    env_id: str,
    env_kwargs: Mapping[str, Any] | None = None,
    record: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``policy``'s weights and manifest into ``folder`` (created); returns the manifest's path.

    ``record``: the training record (seeds, behaviour, command, accuracy, seconds, ...).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = policy.model
    torch.save(model.state_dict(), folder / WEIGHTS)
    manifest = {
        "format": FORMAT,
        "kind": KIND,
        "env_id": env_id,
        "env_kwargs": dict(env_kwargs or {}),
        "observation_layout": dict(policy.features.layout),
        "inputs": policy.features.input_names,
        "model": {"n_row": model.n_row, "n_global": model.n_global, "hidden": model.hidden},
        "m_max": policy.features.m,
        "table": policy.table.tolist(),
        "mode": policy.mode,
        "iae": policy.iae,
        "iae_q": policy.iae_q,
        "row_classes": list(ROW_CLASSES),
        "motion_classes": list(MOTION_CLASSES),
        "training": dict(record or {}),
        "files": {WEIGHTS: sha256_file(folder / WEIGHTS)},
    }
    path = folder / MANIFEST
    write_json_atomic(path, manifest)
    return path


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a saved policy, its weights checked against their hash."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        raise SupervisedLoadError(f"{path} is missing: not a saved supervised policy")
    manifest = json.loads(path.read_text())
    if manifest.get("kind") != KIND or manifest.get("format") != FORMAT:
        raise SupervisedLoadError(
            f"{path} is not a {KIND} manifest of format {FORMAT} "
            f"(kind {manifest.get('kind')!r}, format {manifest.get('format')!r})"
        )
    for name, digest in manifest["files"].items():
        f = folder / name
        if not f.is_file():
            raise SupervisedLoadError(f"{f} is missing")
        if sha256_file(f) != digest:
            raise SupervisedLoadError(f"{f} changed since it was saved (SHA-256 differs from {path})")
    return manifest


def load_policy(
    folder: str | Path,
    env: Any,
    mode: str | None = None,
    table: Any = None,
    iae_q: str | None = None,
) -> SupervisedRowScalePolicy:
    """The saved policy of ``folder`` on ``env`` (its table, mode, iae_q unless given).

    row_iae's parameters of mode ``"iae_mix"``: the manifest's ``iae``, else (a manifest saved
    without) :func:`~agents.supervised.policy.tuned_iae` of the manifest's env id.

    Raises:
        SupervisedLoadError: a missing or changed file, or an env whose observation layout differs
            from the manifest's (the features named).
    """
    folder = Path(folder)
    manifest = read_manifest(folder)
    nav = navigation_env(env)
    feats = RowFeatures.of(nav.observation_features, int(nav.task.m_max))
    bad = feats.mismatch({str(k): int(v) for k, v in manifest["observation_layout"].items()})
    if bad or feats.input_names != manifest["inputs"]:
        raise SupervisedLoadError(
            f"{folder / MANIFEST} was trained on another observation: features {bad or 'in another order'} "
            f"differ between the manifest and this env"
        )
    m = manifest["model"]
    model = RowRegimeNet(int(m["n_row"]), int(m["n_global"]), int(m["hidden"]))
    state = torch.load(folder / WEIGHTS, map_location="cpu", weights_only=True)
    model.load_state_dict(state)
    mode = mode or manifest["mode"]
    iae = manifest.get("iae")
    if iae is None and mode == "iae_mix":
        iae = tuned_iae(manifest["env_id"])
    return SupervisedRowScalePolicy(
        env,
        model,
        manifest["table"] if table is None else table,
        mode,
        iae,
        iae_q or manifest.get("iae_q", "table"),
    )
