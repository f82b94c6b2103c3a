"""The files of a saved agent: their names, where they are, and reading the run's record.

A saved agent is a folder (``train``'s output, a zoo folder, a checkpoint)::

    model.zip         the SB3 archive; its network weights (``policy.pth``) are what is loaded
    vecnormalize.npz  observation / return normalization statistics as plain arrays
                      (mean, var, count, clip_obs, epsilon, ...), when the run normalized
    config.yml        the configuration entry used (env id, algo, hyperparameters)
    meta.json         how it was made (command, seeds, versions)
    manifest.json     SHA-256 of each of these files, the algorithm, env id, timesteps, the
                      observation and action spaces (shape, bounds, dtype / n) of the model,
                      ``frame_stack`` (with the environment's own observation space when > 1)
                      and ``lstm`` (hidden size, layers, shared / critic LSTM; ``null`` for a
                      policy without memory), ``residual`` (``null``, or the baseline, its
                      resolved parameters, scale, observe_base and the env's raw observation
                      space of a residual agent)

An older agent may hold ``vecnormalize.pkl`` (a pickled ``VecNormalize``) instead of the npz
and no manifest; an SB3 checkpoint ``checkpoints/<name>_<n>_steps.zip`` keeps its statistics
beside it and its configuration two folders up. :mod:`agents.training.manifest` writes and
checks the manifest, :mod:`agents.training.normalization` the statistics,
:mod:`agents.training.sb3_archive` the archive, :mod:`agents.training.loading` puts them
together.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path
from typing import Any, NamedTuple

import yaml

__all__ = [
    "CONFIG_FILE",
    "MANIFEST_FILE",
    "META_FILE",
    "MODEL_FILE",
    "STATS_FILE",
    "TRUST_HINT",
    "VECNORMALIZE_FILE",
    "AgentLoadError",
    "AgentPaths",
    "resolve_agent",
    "run_info",
    "sha256_file",
    "stats_path",
    "write_json_atomic",
]

MODEL_FILE = "model.zip"
#: Normalization statistics as plain arrays (:func:`agents.training.normalization.save_normalization`).
STATS_FILE = "vecnormalize.npz"
#: Pickled ``VecNormalize`` of agents saved before the npz format (``trust=True`` only).
VECNORMALIZE_FILE = "vecnormalize.pkl"
MANIFEST_FILE = "manifest.json"
CONFIG_FILE = "config.yml"
META_FILE = "meta.json"
#: What an error says of files that loading would have to unpickle.
TRUST_HINT = (
    "pass trust=True to load_agent only if you trust the file (unpickling can run arbitrary code), "
    "or convert the agent once with agents.training.loading.convert_agent"
)
_LEGACY_CHECKPOINT = r"(.*)_(\d+)_steps\.zip"


class AgentLoadError(ValueError):
    """A saved agent's file is missing, changed since it was saved, or not what it should be."""


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with Path(path).open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_json_atomic(path: str | Path, data: Any) -> None:
    """Write ``data`` as JSON through a temporary file and ``os.replace`` (never half written)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=2, default=str) + "\n")
    os.replace(tmp, path)


class AgentPaths(NamedTuple):
    """Where a saved agent's files are (:func:`resolve_agent`)."""

    model: Path  #: the SB3 archive
    folder: Path  #: the folder holding it (and, but for a legacy checkpoint, its other files)
    legacy: bool  #: an SB3 checkpoint ``checkpoints/<name>_<n>_steps.zip``


def resolve_agent(path: str | Path) -> AgentPaths:
    """The files of an agent folder or of a model archive (:class:`AgentPaths`).

    Raises:
        FileNotFoundError: nothing at ``path``, or a folder without ``model.zip``.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no trained agent at {p}: the path does not exist")
    if p.is_dir():
        model = p / MODEL_FILE
        if not model.is_file():
            raise FileNotFoundError(f"no trained agent at {p}: {model} does not exist")
        return AgentPaths(model, p, False)
    # A legacy SB3 checkpoint checkpoints/model_<n>_steps.zip (statistics beside it, config two up).
    legacy = re.fullmatch(_LEGACY_CHECKPOINT, p.name) is not None and p.parent.name == "checkpoints"
    return AgentPaths(p, p.parent, legacy)


def run_info(folder: Path) -> dict[str, Any]:
    """The run's ``config.yml`` entry of ``folder``, with its ``meta.json`` under ``"meta"``.

    Either file may be absent (``{}`` without both); an unreadable one raises
    :class:`AgentLoadError`.
    """
    info: dict[str, Any] = {}
    cfg = folder / CONFIG_FILE
    if cfg.is_file():
        try:
            data = yaml.safe_load(cfg.read_text())
        except yaml.YAMLError as e:
            raise AgentLoadError(f"{cfg} is not readable YAML: {e}") from e
        if data is not None and not isinstance(data, dict):
            raise AgentLoadError(f"{cfg} is not a configuration mapping")
        info.update(data or {})
    meta = folder / META_FILE
    if meta.is_file():
        try:
            info.setdefault("meta", json.loads(meta.read_text()))
        except json.JSONDecodeError as e:
            raise AgentLoadError(f"{meta} is not readable JSON: {e}") from e
    return info


def stats_path(paths: AgentPaths) -> Path | None:
    """The normalization statistics of an agent (npz, else an older pickle); ``None``: none."""
    model, folder, legacy = paths
    if legacy:
        m = re.fullmatch(_LEGACY_CHECKPOINT, model.name)
        assert m is not None
        for c in (
            folder / f"{m.group(1)}_vecnormalize_{m.group(2)}_steps.pkl",
            folder.parent / VECNORMALIZE_FILE,
        ):
            if c.is_file():
                return c
        return None
    for name in (STATS_FILE, VECNORMALIZE_FILE):
        if (folder / name).is_file():
            return folder / name
    return None
