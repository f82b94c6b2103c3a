"""Load a trained agent as a policy with SB3's ``predict`` that takes raw observations.

A saved agent is a folder (:mod:`agents.training.agent_files` lists its files). Agents with memory
load the same way: a ``frame_stack`` agent's model takes the stacked observations (its manifest
space), :class:`~agents.training.agent.TrainedAgent` takes the environment's and stacks them per
episode; a ``ppo_lstm`` agent (sb3-contrib's RecurrentPPO) is rebuilt like PPO, its LSTM sizes
checked against the manifest. Both keep their memory in the ``state`` that
:meth:`TrainedAgent.predict` returns (:mod:`agents.policy_runner` carries it between steps).

A residual agent (``residual`` in its configuration, :mod:`agents.training.residual`) loads with
its baseline rebuilt from the manifest's record (parameters as resolved at training, checked
against ``config.yml``): :meth:`TrainedAgent.predict` takes the raw env observation, computes the
base action (the baseline's memory in the ``state``, reset where ``episode_start``), appends it
when ``observe_base``, normalizes / stacks as in training, and returns
``clip(a_base + scale * a_res, low, high)``.

Loading never runs code from these files by default: the manifest is checked first
(:mod:`agents.training.manifest`; a file that changed after saving raises
:class:`AgentLoadError` naming it), the statistics are read with ``np.load(allow_pickle=False)``
(:mod:`agents.training.normalization`), and the SB3 model is rebuilt from ``config.yml`` and the
manifest (:mod:`agents.training.sb3_archive`): every entry SB3 pickled into the archive's
``data`` is replaced through SB3's ``custom_objects``, and the weights come from the archive's
``.pth`` state dicts (``torch.load(weights_only=True)``). No ``cloudpickle.loads`` or
``pickle.load`` runs.

Files that need unpickling (an agent saved by an older navgym with ``vecnormalize.pkl`` and no
manifest, or any SB3 archive made elsewhere) load only with an explicit ``trust=True``:

.. warning::
   ``trust=True`` unpickles ``model.zip``'s data and ``vecnormalize.pkl``, which can execute
   arbitrary code. Pass it only for files you made yourself or otherwise trust; convert such an
   agent once with :func:`convert_agent` (``python -m agents.training.zoo PATH --convert``)
   to load it without ``trust`` afterwards.

This module also re-exports the names of those modules that were defined here before they were
split out (``from agents.training.loading import space_from_dict`` keeps working).
"""

from __future__ import annotations

import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.training.agent import TrainedAgent
from agents.training.agent_files import (
    CONFIG_FILE,
    MANIFEST_FILE,
    META_FILE,
    MODEL_FILE,
    STATS_FILE,
    TRUST_HINT,
    VECNORMALIZE_FILE,
    AgentLoadError,
    resolve_agent,
    run_info,
    sha256_file,
    stats_path,
    write_json_atomic,
)
from agents.training.config import frame_stack_of, residual_of
from agents.training.manifest import (
    LSTM_KEYS,
    MANIFEST_FORMAT,
    RESIDUAL_RECORD_KEYS,
    check_covered,
    read_manifest,
    verify_manifest,
    write_manifest,
)
from agents.training.normalization import (
    STATS_KEYS,
    VecNormalizeStats,
    expects_normalized_obs,
    normalization_arrays,
    read_normalization,
    restore_vec_normalize,
    save_normalization,
)
from agents.training.residual import ResidualRuntime, ResidualSpec, make_residual_baseline
from agents.training.sb3_archive import (
    algo_class,
    algo_from_archive,
    load_sb3_model,
    lstm_sizes,
    read_archive_data,
    safe_custom_objects,
)
from agents.training.spaces import (
    check_spaces,
    env_spaces,
    space_difference,
    space_from_dict,
    space_summary,
    space_to_dict,
    unstacked_space,
)

__all__ = [
    # defined here
    "convert_agent",
    "load_agent",
    # re-exported from the modules split out of this one
    "CONFIG_FILE",
    "LSTM_KEYS",
    "MANIFEST_FILE",
    "MANIFEST_FORMAT",
    "META_FILE",
    "MODEL_FILE",
    "RESIDUAL_RECORD_KEYS",
    "STATS_FILE",
    "STATS_KEYS",
    "VECNORMALIZE_FILE",
    "AgentLoadError",
    "TrainedAgent",
    "VecNormalizeStats",
    "algo_class",
    "check_spaces",
    "env_spaces",
    "load_sb3_model",
    "lstm_sizes",
    "normalization_arrays",
    "read_archive_data",
    "read_manifest",
    "read_normalization",
    "restore_vec_normalize",
    "safe_custom_objects",
    "save_normalization",
    "sha256_file",
    "space_difference",
    "space_from_dict",
    "space_summary",
    "space_to_dict",
    "unstacked_space",
    "verify_manifest",
    "write_json_atomic",
    "write_manifest",
]


def load_agent(
    path: str | Path,
    algo: str | None = None,
    device: str = "cpu",
    *,
    env: Any = None,
    trust: bool = False,
) -> TrainedAgent:
    """Load a trained agent from its folder (``model.zip``, ``vecnormalize.npz``, ...) or a zip.

    The returned :class:`TrainedAgent` has SB3's ``predict(obs, state, episode_start,
    deterministic)`` and normalizes raw observations internally when the run used
    ``VecNormalize``, so evaluators pass the environment's observations unchanged.

    The folder's ``manifest.json`` is checked first: every file it lists must have its recorded
    SHA-256. Nothing is unpickled unless ``trust=True`` (see the module docstring).

    Args:
        path: an agent folder (``train``'s output, a zoo folder, a checkpoint
            ``checkpoints/step_<n>``) or the model archive in one.
        algo: the SB3 algorithm; default from the run's ``config.yml`` or the archive.
        device: torch device.
        env: an environment (Gymnasium env or vector env, SB3 VecEnv, or an env id) the agent
            will act in: its observation and action spaces must be the saved ones.
        trust: allow unpickling (``vecnormalize.pkl``, the archive's pickled entries) for an
            agent without a manifest or made elsewhere. Unpickling can run arbitrary code: only
            for files you trust.

    Raises:
        FileNotFoundError: nothing at ``path`` (the message names the path and what is missing).
        AgentLoadError: a file is missing (the normalization statistics a ``normalize``
            configuration needs, a file of the manifest), changed since saving, corrupt, would
            need unpickling without ``trust``, or the spaces differ from ``env``'s.
    """
    paths = resolve_agent(path)
    model_path, folder, legacy = paths
    manifest = None if legacy else read_manifest(folder)
    if manifest is not None:
        verify_manifest(folder, manifest)
        check_covered(folder, model_path, manifest)
    elif not trust:
        raise AgentLoadError(
            f"{folder} has no {MANIFEST_FILE} (SHA-256 of the agent's files and its spaces): it was "
            f"saved by an older navgym or elsewhere, and loading it would unpickle its files; {TRUST_HINT}"
        )
    info = run_info(folder.parent if legacy else folder)
    if manifest is not None:
        for key in ("env_id", "algo"):
            if info.get(key) is not None and manifest.get(key) not in (None, info[key]):
                raise AgentLoadError(
                    f"{folder / CONFIG_FILE} says {key} {info[key]!r}, {folder / MANIFEST_FILE} "
                    f"{manifest[key]!r}"
                )
    frame_stack = _frame_stack(folder, info, manifest)
    algo = algo or info.get("algo") or (manifest or {}).get("algo") or algo_from_archive(model_path)
    if algo is None:
        raise AgentLoadError(f"cannot tell the algorithm of {model_path}; pass algo=")
    cls = algo_class(algo)
    algo_from_archive(model_path)  # checks the archive before SB3 sees it (clear message)

    norm_path = stats_path(paths)
    if norm_path is None and expects_normalized_obs(info):
        cfg = (folder.parent if legacy else folder) / CONFIG_FILE
        raise AgentLoadError(
            f"{folder / STATS_FILE} is missing (nor is there an older {VECNORMALIZE_FILE}), but {cfg} "
            "says the run normalized observations "
            f"(normalize: {info.get('normalize')!r}): without the statistics the agent would act on "
            "raw observations"
        )
    normalizer = VecNormalizeStats.load(norm_path, trust=trust) if norm_path is not None else None
    model = load_sb3_model(cls, model_path, info, manifest, trust=trust, device=device)
    obs_space = (
        space_from_dict(manifest["env_observation_space"])
        if manifest is not None and frame_stack > 1
        else unstacked_space(model.observation_space, frame_stack)
    )
    if normalizer is not None and normalizer.mean.shape != obs_space.shape:
        raise AgentLoadError(
            f"{norm_path} normalizes observations of shape {normalizer.mean.shape}, the model takes "
            f"{obs_space.shape}" + (f" (one of its {frame_stack} stacked frames)" if frame_stack > 1 else "")
        )
    if obs_space.shape[0] * frame_stack != model.observation_space.shape[0]:
        raise AgentLoadError(
            f"{folder}: {frame_stack} frames of {obs_space.shape} do not make the model's observations "
            f"{model.observation_space.shape}"
        )
    if manifest is not None:
        check_spaces(
            manifest["observation_space"], manifest["action_space"], model, f"{folder / MANIFEST_FILE}"
        )
        if manifest.get("lstm", None) != lstm_sizes(model):
            raise AgentLoadError(
                f"{folder / MANIFEST_FILE} records the LSTM {manifest.get('lstm')}, the model has "
                f"{lstm_sizes(model)}"
            )
    residual = _residual(folder, info, manifest, obs_space, model.action_space)
    if env is not None:
        if residual is not None:
            check_spaces(residual.observation_space, residual.action_space, env, f"the agent {folder}")
        else:
            check_spaces(obs_space, model.action_space, env, f"the agent {folder}")
    info.setdefault("algo", algo)
    return TrainedAgent(model, normalizer, model_path, info, manifest, frame_stack, obs_space, residual)


def _residual(
    folder: Path,
    info: Mapping[str, Any],
    manifest: Mapping[str, Any] | None,
    frame_space: Any,
    action_space: Any,
) -> ResidualRuntime | None:
    """The baseline of a residual agent, rebuilt from its manifest (``None``: not a residual agent).

    ``config.yml``'s ``residual`` (resolved at training) and the manifest's must agree; the
    baseline is built for the env id and ``env_kwargs`` of the run (its observation layout).
    """
    try:
        from_config = residual_of(info.get("residual"))
    except ValueError as e:
        raise AgentLoadError(f"{folder / CONFIG_FILE}: {e}") from e
    record = None if manifest is None else manifest.get("residual")
    if from_config is None and record is None:
        return None
    if manifest is None:
        raise AgentLoadError(f"{folder}: a residual agent needs its {MANIFEST_FILE} (the resolved baseline)")
    if from_config is None or record is None:
        raise AgentLoadError(
            f"{folder / CONFIG_FILE} {'has no' if from_config is None else 'has a'} residual, "
            f"{folder / MANIFEST_FILE} {'has none' if record is None else 'has one'}"
        )
    mine = {k: record[k] for k in ("baseline", "params", "scale", "observe_base")}
    if record.get("agent"):
        mine["agent"] = record["agent"]
    if from_config != {**mine, "params": {k: float(v) for k, v in mine["params"].items()}}:
        raise AgentLoadError(
            f"{folder / CONFIG_FILE} says residual {from_config}, {folder / MANIFEST_FILE} {mine}"
        )
    env_id = manifest.get("env_id") or info.get("env_id")
    if not env_id:
        raise AgentLoadError(f"{folder}: a residual agent must record its env id (the baseline's layout)")
    env_obs = space_from_dict(record["env_observation_space"])
    spec = ResidualSpec(
        baseline=str(record["baseline"]),
        task=str(record["task"]),
        params=dict(record["params"]),
        scale=float(record["scale"]),
        observe_base=bool(record["observe_base"]),
        params_source=str(record["params_source"]),
        agent=str(record.get("agent") or ""),
    )
    try:
        import navgym  # noqa: F401 - registers the environments
        from navgym.envs.registration import superseded_ids_quiet

        with superseded_ids_quiet():
            probe = gym.make_vec(
                env_id,
                num_envs=1,
                vectorization_mode="vector_entry_point",
                **dict(info.get("env_kwargs") or {}),
            )
        try:
            baseline = make_residual_baseline(spec, probe)
        finally:
            probe.close()
    except (ValueError, TypeError, KeyError) as e:
        raise AgentLoadError(f"{folder}: cannot rebuild the residual's baseline {spec.baseline}: {e}") from e
    runtime = ResidualRuntime(spec, baseline, env_obs)
    if not isinstance(action_space, spaces.Box) or action_space.shape != runtime.action_space.shape:
        raise AgentLoadError(
            f"{folder}: the model's action space {action_space} is not a residual of the env's "
            f"{runtime.action_space}"
        )
    if int(np.prod(frame_space.shape)) != runtime.model_obs_dim:
        raise AgentLoadError(
            f"{folder}: the model's observations {frame_space.shape} are not the env's {env_obs.shape}"
            + (f" plus the base action ({runtime.act_dim})" if spec.observe_base else "")
        )
    if int(baseline.obs_dim) != int(env_obs.shape[0]):
        raise AgentLoadError(
            f"{folder}: the baseline {spec.baseline} reads observations of width {baseline.obs_dim}, the "
            f"agent was trained on {env_obs.shape[0]} (env_kwargs changed the layout?)"
        )
    return runtime


def _frame_stack(folder: Path, info: Mapping[str, Any], manifest: Mapping[str, Any] | None) -> int:
    """Frames stacked by the agent: its ``config.yml`` and its manifest must agree."""
    try:
        from_config = frame_stack_of(info.get("frame_stack"))
    except ValueError as e:
        raise AgentLoadError(f"{folder / CONFIG_FILE}: {e}") from e
    if manifest is None:
        return from_config
    from_manifest = frame_stack_of(manifest.get("frame_stack", 1))
    if from_manifest != from_config:
        raise AgentLoadError(
            f"{folder / CONFIG_FILE} says frame_stack {from_config}, {folder / MANIFEST_FILE} {from_manifest}"
        )
    return from_manifest


# --- converting an older agent -----------------------------------------------------------------


def convert_agent(path: str | Path, remove_pickle: bool = True) -> Path:
    """Write ``vecnormalize.npz`` and ``manifest.json`` for an agent saved before them.

    This unpickles the agent's ``vecnormalize.pkl`` and archive data once (``trust=True``): run
    it only on agents you trust (e.g. this repository's own). ``model.zip`` is kept as it is
    (its weights are what loading reads); ``vecnormalize.pkl`` is removed unless
    ``remove_pickle`` is false. Returns the manifest's path.
    """
    folder = Path(path)
    model_path, folder, legacy = resolve_agent(folder)
    if legacy or model_path.name != MODEL_FILE:
        raise ValueError(f"convert_agent takes an agent folder holding {MODEL_FILE}; got {path}")
    info = run_info(folder)
    algo = info.get("algo") or algo_from_archive(model_path)
    if algo is None:
        raise AgentLoadError(f"cannot tell the algorithm of {model_path}")
    pkl = folder / VECNORMALIZE_FILE
    if pkl.is_file():
        with pkl.open("rb") as f:
            vn = pickle.load(f)  # trusted by the caller (docstring)
        save_normalization(vn.__dict__, folder / STATS_FILE)
    model = load_sb3_model(algo_class(algo), model_path, info, None, trust=True)
    files = [n for n in (MODEL_FILE, STATS_FILE, CONFIG_FILE, META_FILE) if (folder / n).is_file()]
    manifest = write_manifest(
        folder,
        files,
        algo=algo,
        env_id=info.get("env_id"),
        num_timesteps=model.num_timesteps,
        observation_space=model.observation_space,
        action_space=model.action_space,
        frame_stack=frame_stack_of(info.get("frame_stack")),
        lstm=lstm_sizes(model),
    )
    if remove_pickle:
        pkl.unlink(missing_ok=True)
    return manifest
