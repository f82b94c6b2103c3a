"""A saved agent's ``manifest.json``: the SHA-256 of its files and what the model takes and gives.

:func:`write_manifest` records, besides each file's hash, the algorithm, env id and timesteps,
the model's observation and action spaces (:mod:`agents.training.spaces`), ``frame_stack``
(with the environment's own observation space when > 1), ``lstm`` (the recurrent policy's sizes,
``null`` without memory) and ``residual`` (``null``, or a residual agent's baseline record).
:func:`read_manifest` checks its structure, :func:`verify_manifest` every listed file against its
hash: a file that changed after saving raises :class:`AgentLoadError` naming it.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from agents.training.agent_files import (
    CONFIG_FILE,
    MANIFEST_FILE,
    STATS_FILE,
    AgentLoadError,
    sha256_file,
    write_json_atomic,
)
from agents.training.config import frame_stack_of
from agents.training.spaces import space_to_dict, unstacked_space

__all__ = [
    "LSTM_KEYS",
    "MANIFEST_FORMAT",
    "RESIDUAL_RECORD_KEYS",
    "check_covered",
    "read_manifest",
    "verify_manifest",
    "write_manifest",
]

MANIFEST_FORMAT = 1

#: Keys of a manifest's ``lstm`` record (the recurrent policy's sizes).
LSTM_KEYS = ("lstm_hidden_size", "n_lstm_layers", "shared_lstm", "enable_critic_lstm")


def write_manifest(
    folder: str | Path,
    files: Iterable[str],
    *,
    algo: str,
    env_id: str | None,
    num_timesteps: int,
    observation_space: Any,
    action_space: Any,
    frame_stack: int = 1,
    env_observation_space: Any = None,
    lstm: Mapping[str, Any] | None = None,
    residual: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``folder/manifest.json``: SHA-256 of ``files`` (names in ``folder``) and the spaces.

    ``observation_space`` is the model's (stacked when ``frame_stack`` > 1);
    ``env_observation_space`` the environment's (default: unstacked from the model's); ``lstm``
    the recurrent policy's sizes (:func:`agents.training.sb3_archive.lstm_sizes`); ``residual``
    a residual agent's record (:meth:`agents.training.residual.ResidualVecEnv.manifest_record`).
    """
    folder = Path(folder)
    names = sorted(set(files))
    for name in names:
        _check_name(name)
    frame_stack = frame_stack_of(frame_stack)
    manifest = {
        "format": MANIFEST_FORMAT,
        "algo": algo,
        "env_id": env_id,
        "num_timesteps": int(num_timesteps),
        "observation_space": space_to_dict(observation_space),
        "action_space": space_to_dict(action_space),
        "frame_stack": frame_stack,
        "lstm": None if lstm is None else {k: lstm[k] for k in LSTM_KEYS},
        "residual": None if residual is None else _residual_record(residual),
        "files": {name: sha256_file(folder / name) for name in names},
    }
    if frame_stack > 1:
        if env_observation_space is None:
            env_observation_space = unstacked_space(observation_space, frame_stack)
        manifest["env_observation_space"] = space_to_dict(env_observation_space)
    path = folder / MANIFEST_FILE
    write_json_atomic(path, manifest)
    return path


#: Keys of a manifest's ``residual`` record.
RESIDUAL_RECORD_KEYS = (
    "baseline",
    "params",
    "scale",
    "observe_base",
    "task",
    "params_source",
    "env_observation_space",
)
#: Optional keys of a manifest's ``residual`` record (a supervised base's folder).
RESIDUAL_OPTIONAL_KEYS = ("agent",)


def _residual_record(residual: Mapping[str, Any]) -> dict[str, Any]:
    out = {k: residual[k] for k in RESIDUAL_RECORD_KEYS}
    out.update({k: residual[k] for k in RESIDUAL_OPTIONAL_KEYS if residual.get(k)})
    space = out["env_observation_space"]
    out["env_observation_space"] = dict(space) if isinstance(space, Mapping) else space_to_dict(space)
    return out


def _check_name(name: str) -> None:
    if not isinstance(name, str) or name in ("", ".", "..") or Path(name).name != name or "\\" in name:
        raise AgentLoadError(f"manifest file names must be plain names in the agent folder; got {name!r}")


def read_manifest(folder: str | Path) -> dict[str, Any] | None:
    """``folder/manifest.json`` (``None`` when there is none; ``AgentLoadError`` when invalid)."""
    path = Path(folder) / MANIFEST_FILE
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise AgentLoadError(f"{path} is not readable JSON: {type(e).__name__}: {e}") from e
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise AgentLoadError(f"{path} is not an agent manifest (no 'files' mapping)")
    if manifest.get("format") != MANIFEST_FORMAT:
        raise AgentLoadError(
            f"{path} has format {manifest.get('format')!r}; this navgym reads {MANIFEST_FORMAT}"
        )
    for key in ("observation_space", "action_space"):
        if not isinstance(manifest.get(key), dict):
            raise AgentLoadError(f"{path} does not record the agent's {key}")
    try:
        n = frame_stack_of(manifest.get("frame_stack", 1))
    except ValueError as e:
        raise AgentLoadError(f"{path}: {e}") from e
    if n > 1 and not isinstance(manifest.get("env_observation_space"), dict):
        raise AgentLoadError(f"{path} stacks {n} frames but does not record the env_observation_space")
    lstm = manifest.get("lstm")
    if lstm is not None and (not isinstance(lstm, dict) or set(lstm) != set(LSTM_KEYS)):
        raise AgentLoadError(f"{path}: 'lstm' must be null or a mapping of {list(LSTM_KEYS)}; got {lstm!r}")
    residual = manifest.get("residual")
    if residual is not None and (
        not isinstance(residual, dict)
        or not set(RESIDUAL_RECORD_KEYS) <= set(residual) <= {*RESIDUAL_RECORD_KEYS, *RESIDUAL_OPTIONAL_KEYS}
        or not isinstance(residual.get("env_observation_space"), dict)
        or not isinstance(residual.get("params"), dict)
    ):
        raise AgentLoadError(
            f"{path}: 'residual' must be null or a mapping of {list(RESIDUAL_RECORD_KEYS)}; got {residual!r}"
        )
    for name in manifest["files"]:
        _check_name(name)
    return manifest


def verify_manifest(folder: str | Path, manifest: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Check every file of ``folder``'s manifest against its SHA-256; return the manifest.

    Raises:
        AgentLoadError: no manifest, a listed file missing, or a file whose hash differs (the
            message names the file).
    """
    folder = Path(folder)
    manifest = dict(manifest) if manifest is not None else read_manifest(folder)
    if manifest is None:
        raise AgentLoadError(f"{folder / MANIFEST_FILE} is missing")
    for name, digest in manifest["files"].items():
        path = folder / name
        if not path.is_file():
            raise AgentLoadError(f"{path} is listed in {folder / MANIFEST_FILE} but missing")
        actual = sha256_file(path)
        if actual != digest:
            raise AgentLoadError(
                f"{path} does not match its SHA-256 in {folder / MANIFEST_FILE} (expected {digest[:16]}..., "
                f"got {actual[:16]}...): the file changed after the agent was saved"
            )
    return manifest


def check_covered(folder: Path, model_path: Path, manifest: Mapping[str, Any]) -> None:
    """The files loading reads must be listed in the manifest (an unlisted one is unchecked)."""
    listed = manifest["files"]
    for path in (model_path, folder / CONFIG_FILE, folder / STATS_FILE):
        if path.is_file() and path.name not in listed:
            raise AgentLoadError(
                f"{path} is not listed in {folder / MANIFEST_FILE}: it was added after saving"
            )
