"""Load a trained agent as a policy with SB3's ``predict`` that takes raw observations.

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

Agents with memory load the same way: a ``frame_stack`` agent's model takes the stacked
observations (its manifest space), :class:`TrainedAgent` takes the environment's and stacks them
per episode; a ``ppo_lstm`` agent (sb3-contrib's RecurrentPPO) is rebuilt like PPO, its LSTM
sizes checked against the manifest. Both keep their memory in the ``state`` that
:meth:`TrainedAgent.predict` returns (:mod:`agents.policy_runner` carries it between steps).

A residual agent (``residual`` in its configuration, :mod:`agents.training.residual`) loads with
its baseline rebuilt from the manifest's record (parameters as resolved at training, checked
against ``config.yml``): :meth:`TrainedAgent.predict` takes the raw env observation, computes the
base action (the baseline's memory in the ``state``, reset where ``episode_start``), appends it
when ``observe_base``, normalizes / stacks as in training, and returns
``clip(a_base + scale * a_res, low, high)``.

Loading never runs code from these files by default: the manifest is checked first (a file
that changed after saving raises :class:`AgentLoadError` naming it), the statistics are read
with ``np.load(allow_pickle=False)``, and the SB3 model is rebuilt from ``config.yml`` and the
manifest: every entry SB3 pickled into the archive's ``data`` (policy class, spaces, schedules,
buffers) is replaced through SB3's ``custom_objects``, and the weights come from the archive's
``.pth`` state dicts (``torch.load(weights_only=True)``). No ``cloudpickle.loads`` or
``pickle.load`` runs.

Files that need unpickling (an agent saved by an older navgym with ``vecnormalize.pkl`` and no
manifest, or any SB3 archive made elsewhere) load only with an explicit ``trust=True``:

.. warning::
   ``trust=True`` unpickles ``model.zip``'s data and ``vecnormalize.pkl``, which can execute
   arbitrary code. Pass it only for files you made yourself or otherwise trust; convert such an
   agent once with :func:`convert_agent` (``python -m agents.training.zoo PATH --convert``)
   to load it without ``trust`` afterwards.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import pickle
import re
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.policy_runner import FrameStack, StackedState
from agents.training.config import (
    ALGOS,
    build_hyperparameters,
    frame_stack_of,
    normalize_options,
    split_entry,
)

MODEL_FILE = "model.zip"
#: Normalization statistics as plain arrays (written by :func:`save_normalization`).
STATS_FILE = "vecnormalize.npz"
#: Pickled ``VecNormalize`` of agents saved before the npz format (``trust=True`` only).
VECNORMALIZE_FILE = "vecnormalize.pkl"
MANIFEST_FILE = "manifest.json"
CONFIG_FILE = "config.yml"
META_FILE = "meta.json"
MANIFEST_FORMAT = 1
#: Keys of the statistics file (``count``-like entries are scalars, flags are booleans).
STATS_KEYS = (
    "norm_obs",
    "norm_reward",
    "mean",
    "var",
    "count",
    "ret_mean",
    "ret_var",
    "ret_count",
    "clip_obs",
    "clip_reward",
    "gamma",
    "epsilon",
)
_SERIALIZED = ":serialized:"
_TRUST_HINT = (
    "pass trust=True to load_agent only if you trust the file (unpickling can run arbitrary code), "
    "or convert the agent once with agents.training.loading.convert_agent"
)


class AgentLoadError(ValueError):
    """A saved agent's file is missing, changed since it was saved, or not what it should be."""


def algo_class(algo: str):
    """The SB3 class of ``algo`` (``"ppo" | "sac" | "dqn" | "a2c"``; ``"ppo_lstm"``: RecurrentPPO)."""
    import stable_baselines3 as sb3

    key = str(algo).lower()
    if key == "ppo_lstm":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError as e:
            raise ImportError(
                "algo ppo_lstm needs sb3-contrib (pip install -e '.[agents]' installs it)"
            ) from e
        return RecurrentPPO
    classes = {"ppo": sb3.PPO, "sac": sb3.SAC, "dqn": sb3.DQN, "a2c": sb3.A2C}
    try:
        return classes[key]
    except KeyError:
        raise ValueError(f"algo must be one of {list(ALGOS)}; got {algo!r}") from None


#: Keys of a manifest's ``lstm`` record (the recurrent policy's sizes).
LSTM_KEYS = ("lstm_hidden_size", "n_lstm_layers", "shared_lstm", "enable_critic_lstm")


def lstm_sizes(model: Any) -> dict[str, Any] | None:
    """The LSTM sizes of a recurrent model (``None`` for a policy without one).

    ``{lstm_hidden_size, n_lstm_layers, shared_lstm, enable_critic_lstm}`` of sb3-contrib's
    ``RecurrentActorCriticPolicy``.
    """
    policy = getattr(model, "policy", model)
    shape = getattr(policy, "lstm_hidden_state_shape", None)
    if shape is None:
        return None
    return {
        "lstm_hidden_size": int(shape[-1]),
        "n_lstm_layers": int(shape[0]),
        "shared_lstm": bool(policy.shared_lstm),
        "enable_critic_lstm": bool(policy.enable_critic_lstm),
    }


def unstacked_space(space: Any, n_stack: int) -> Any:
    """The observation space of one frame of ``VecFrameStack``'s stacked Box ``space``.

    SB3 stacks a flat Box's bounds with ``np.repeat`` (each bound ``n_stack`` times in a row):
    every ``n_stack``-th bound is the frame's.
    """
    from gymnasium import spaces

    if n_stack == 1:
        return space
    if not isinstance(space, spaces.Box) or len(space.shape) != 1 or space.shape[0] % n_stack:
        raise AgentLoadError(f"cannot unstack {n_stack} frames of the observation space {space}")
    return spaces.Box(low=space.low[::n_stack], high=space.high[::n_stack], dtype=space.dtype)


# --- files, hashes, manifest -------------------------------------------------------------------


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


def space_to_dict(space: Any) -> dict[str, Any]:
    """A JSON description of a Gymnasium space (Box, Discrete, MultiDiscrete, MultiBinary)."""
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "dtype": str(space.dtype),
            "low": space.low.tolist(),
            "high": space.high.tolist(),
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start), "dtype": str(space.dtype)}
    if isinstance(space, spaces.MultiDiscrete):
        return {
            "type": "MultiDiscrete",
            "nvec": np.asarray(space.nvec).tolist(),
            "start": np.asarray(space.start).tolist(),
            "dtype": str(space.dtype),
        }
    if isinstance(space, spaces.MultiBinary):
        return {"type": "MultiBinary", "n": np.asarray(space.n).tolist()}
    raise ValueError(f"cannot describe a {type(space).__name__} space in a manifest")


def space_from_dict(d: Mapping[str, Any]) -> Any:
    """The Gymnasium space of a :func:`space_to_dict` description."""
    from gymnasium import spaces

    try:
        kind = d["type"]
        if kind == "Box":
            dtype = np.dtype(d["dtype"])
            low = np.asarray(d["low"], dtype=dtype).reshape(d["shape"])
            high = np.asarray(d["high"], dtype=dtype).reshape(d["shape"])
            return spaces.Box(low=low, high=high, shape=tuple(d["shape"]), dtype=dtype)
        if kind == "Discrete":
            return spaces.Discrete(int(d["n"]), start=int(d.get("start", 0)))
        if kind == "MultiDiscrete":
            return spaces.MultiDiscrete(
                np.asarray(d["nvec"]), dtype=np.dtype(d.get("dtype", "int64")), start=d.get("start")
            )
        if kind == "MultiBinary":
            return spaces.MultiBinary(d["n"])
    except (KeyError, TypeError, ValueError) as e:
        raise AgentLoadError(f"invalid space description {dict(d)!r}: {type(e).__name__}: {e}") from e
    raise AgentLoadError(f"unknown space type {kind!r} in {dict(d)!r}")


def space_difference(expected: Any, actual: Any) -> str | None:
    """``None`` when two spaces are the same (type, shape, dtype, bounds / n), else what differs."""
    a = expected if isinstance(expected, Mapping) else space_to_dict(expected)
    b = actual if isinstance(actual, Mapping) else space_to_dict(actual)
    if a.get("type") != b.get("type"):
        return f"{a.get('type')} vs {b.get('type')}"
    for key in ("shape", "dtype", "n", "start", "nvec"):
        if a.get(key) != b.get(key):
            return f"{key} {a.get(key)} vs {b.get(key)}"
    for key in ("low", "high"):
        if key in a or key in b:
            x, y = np.asarray(a.get(key), dtype=float), np.asarray(b.get(key), dtype=float)
            if x.shape != y.shape or not np.array_equal(x, y):
                if x.shape == y.shape:
                    i = int(np.flatnonzero(x.ravel() != y.ravel())[0])
                    return f"{key} bound [{i}] {x.ravel()[i]:g} vs {y.ravel()[i]:g}"
                return f"{key} bounds {x.tolist()} vs {y.tolist()}"
    return None


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
    the recurrent policy's sizes (:func:`lstm_sizes`); ``residual`` a residual agent's record
    (:meth:`agents.training.residual.ResidualVecEnv.manifest_record`).
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


def _residual_record(residual: Mapping[str, Any]) -> dict[str, Any]:
    out = {k: residual[k] for k in RESIDUAL_RECORD_KEYS}
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
        or set(residual) != set(RESIDUAL_RECORD_KEYS)
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


# --- normalization statistics ------------------------------------------------------------------


def normalization_arrays(vec_normalize: Any) -> dict[str, np.ndarray]:
    """The statistics of a ``VecNormalize`` (or an unpickled one's ``__dict__``) as plain arrays."""
    fields = vec_normalize if isinstance(vec_normalize, Mapping) else vec_normalize.__dict__
    obs_rms, ret_rms = fields.get("obs_rms"), fields.get("ret_rms")
    if isinstance(obs_rms, Mapping):
        raise ValueError("dict observation statistics are not supported")
    out = {
        "norm_obs": np.asarray(bool(fields["norm_obs"])),
        "norm_reward": np.asarray(bool(fields.get("norm_reward", False))),
        "clip_obs": np.asarray(float(fields.get("clip_obs", 10.0))),
        "clip_reward": np.asarray(float(fields.get("clip_reward", 10.0))),
        "gamma": np.asarray(float(fields.get("gamma", 0.99))),
        "epsilon": np.asarray(float(fields.get("epsilon", 1e-8))),
    }
    if obs_rms is not None:
        out.update(
            mean=np.asarray(obs_rms.mean, dtype=np.float64),
            var=np.asarray(obs_rms.var, dtype=np.float64),
            count=np.asarray(float(obs_rms.count)),
        )
    else:
        out.update(mean=np.zeros(0), var=np.ones(0), count=np.asarray(0.0))
    if ret_rms is not None:
        out.update(
            ret_mean=np.asarray(ret_rms.mean, dtype=np.float64),
            ret_var=np.asarray(ret_rms.var, dtype=np.float64),
            ret_count=np.asarray(float(ret_rms.count)),
        )
    else:
        out.update(ret_mean=np.asarray(0.0), ret_var=np.asarray(1.0), ret_count=np.asarray(0.0))
    return out


def save_normalization(vec_normalize: Any, path: str | Path) -> Path:
    """Write a ``VecNormalize``'s statistics to ``path`` (``.npz``, plain arrays, no pickle)."""
    path = Path(path)
    with path.open("wb") as f:
        np.savez(f, **normalization_arrays(vec_normalize))
    return path


def read_normalization(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a statistics file written by :func:`save_normalization` (never unpickles)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: np.asarray(z[k]) for k in z.files}
    except Exception as e:  # truncated zip, object arrays (ValueError), not an npz
        raise AgentLoadError(
            f"{path} is not a readable normalization statistics file (.npz of plain arrays): "
            f"{type(e).__name__}: {e}"
        ) from e
    missing = [k for k in STATS_KEYS if k not in data]
    if missing:
        raise AgentLoadError(f"{path} lacks normalization statistics {missing}")
    for k in STATS_KEYS:
        if data[k].dtype.kind not in "biuf":
            raise AgentLoadError(f"{path}: {k} is not numeric (dtype {data[k].dtype})")
    if data["mean"].shape != data["var"].shape:
        raise AgentLoadError(f"{path}: mean {data['mean'].shape} and var {data['var'].shape} differ in shape")
    return data


def restore_vec_normalize(venv: Any, path: str | Path, training: bool = True):
    """``VecNormalize(venv)`` with the statistics of ``path`` (a :func:`save_normalization` file)."""
    from stable_baselines3.common.vec_env import VecNormalize

    s = read_normalization(path)
    norm_obs = bool(s["norm_obs"])
    if norm_obs and s["mean"].shape != venv.observation_space.shape:
        raise AgentLoadError(
            f"{path} normalizes observations of shape {s['mean'].shape}; the environment's have "
            f"{venv.observation_space.shape}"
        )
    vn = VecNormalize(
        venv,
        training=training,
        norm_obs=norm_obs,
        norm_reward=bool(s["norm_reward"]),
        clip_obs=float(s["clip_obs"]),
        clip_reward=float(s["clip_reward"]),
        gamma=float(s["gamma"]),
        epsilon=float(s["epsilon"]),
    )
    if norm_obs:
        vn.obs_rms.mean = s["mean"].astype(np.float64).copy()
        vn.obs_rms.var = s["var"].astype(np.float64).copy()
        vn.obs_rms.count = float(s["count"])
    vn.ret_rms.mean = s["ret_mean"].astype(np.float64).copy()
    vn.ret_rms.var = s["ret_var"].astype(np.float64).copy()
    vn.ret_rms.count = float(s["ret_count"])
    return vn


class VecNormalizeStats:
    """Observation normalization of a saved ``VecNormalize``, applied to raw observations."""

    def __init__(
        self, mean: np.ndarray, var: np.ndarray, epsilon: float, clip_obs: float, count: float = 0.0
    ) -> None:
        self.mean = np.asarray(mean, dtype=np.float64)
        self.var = np.asarray(var, dtype=np.float64)
        self.epsilon = float(epsilon)
        self.clip_obs = float(clip_obs)
        self.count = float(count)

    @classmethod
    def load(cls, path: str | Path, trust: bool = False) -> VecNormalizeStats | None:
        """Statistics of ``path``; ``None`` when the run did not normalize observations.

        ``path`` is a ``.npz`` of plain arrays (never unpickled) or, with ``trust=True`` only, a
        pickled ``VecNormalize`` of an older agent.
        """
        path = Path(path)
        if path.suffix != ".npz":
            return cls._load_pickle(path, trust)
        s = read_normalization(path)
        if not bool(s["norm_obs"]):
            return None
        return cls(s["mean"], s["var"], float(s["epsilon"]), float(s["clip_obs"]), float(s["count"]))

    @classmethod
    def _load_pickle(cls, path: Path, trust: bool) -> VecNormalizeStats | None:
        if not trust:
            raise AgentLoadError(
                f"{path} is a pickled VecNormalize: loading it would unpickle it, which can run "
                f"arbitrary code; {_TRUST_HINT}"
            )
        try:
            with path.open("rb") as f:
                vn = pickle.load(f)  # trust=True: the caller vouches for the file
        except Exception as e:  # any unpickling failure means a corrupt file
            raise AgentLoadError(
                f"{path} is not a readable VecNormalize pickle: {type(e).__name__}: {e}"
            ) from e
        # An unpickled VecNormalize has no venv: read its fields from __dict__ (its __getattr__
        # would recurse looking for the wrapped env).
        fields = getattr(vn, "__dict__", {})
        if "norm_obs" not in fields:
            raise AgentLoadError(f"{path} does not hold VecNormalize statistics (got {type(vn).__name__})")
        if not fields["norm_obs"]:
            return None
        rms = fields.get("obs_rms")
        if rms is None or not hasattr(rms, "mean"):
            raise AgentLoadError(f"{path} normalizes observations but holds no statistics")
        return cls(rms.mean, rms.var, fields.get("epsilon", 1e-8), fields.get("clip_obs", 10.0), rms.count)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)


# --- the SB3 model without unpickling ----------------------------------------------------------


def read_archive_data(model: str | Path) -> dict[str, Any]:
    """The JSON ``data`` of an SB3 archive, pickled entries left encoded (never unpickled)."""
    try:
        with zipfile.ZipFile(model) as z:
            data = json.loads(z.read("data"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError, OSError) as e:
        raise AgentLoadError(
            f"{model} is not a stable-baselines3 model archive (zip with 'data'): {type(e).__name__}: {e}"
        ) from e
    if not isinstance(data, dict):
        raise AgentLoadError(f"{model}: the archive's 'data' is not a JSON object")
    return data


def _algo_from_zip(model: Path) -> str | None:
    """The algorithm of an SB3 archive from the module of its policy class (no unpickling)."""
    data = read_archive_data(model)
    module = str((data.get("policy_class") or {}).get("__module__", ""))
    for algo in ("sac", "dqn", "td3"):
        if f".{algo}." in module:
            return algo if algo in ALGOS else None
    if module.startswith("sb3_contrib.") and ".recurrent." in module:
        return "ppo_lstm"
    return "ppo" if "common.policies" in module else None


#: Pickled entries of SB3's ``data`` that ``_setup_model`` / ``learn`` rebuild or that prediction
#: and resumed training do without: replaced by ``None``.
_REBUILT = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
    "lr_schedule",
    "exploration_schedule",
    "rollout_buffer_class",
    "replay_buffer_class",
)
#: Pickled entries replaced by the configuration's value (or the algorithm's default).
_FROM_CONFIG = ("learning_rate", "clip_range", "clip_range_vf", "train_freq")


def _readable(value: Any) -> Any:
    """A value as SB3 writes it beside a pickled object (JSON as is, else ``str``)."""
    try:
        json.dumps(value)
        return value
    except (TypeError, ValueError):
        return str(value)


def _config_entry(info: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    entry = {k: v for k, v in info.items() if k not in ("env_id", "algo", "seed", "env_seed", "meta")}
    try:
        return split_entry(entry)
    except ValueError as e:
        raise AgentLoadError(f"invalid configuration: {e}") from e


def safe_custom_objects(
    cls: Any, model_path: Path, info: Mapping[str, Any], manifest: Mapping[str, Any]
) -> dict[str, Any]:
    """SB3 ``custom_objects`` replacing every pickled entry of the archive's ``data``.

    The policy class and keyword arguments come from ``config.yml`` (checked against what the
    archive says of them in plain text), the spaces from the manifest, schedules from the
    configuration; buffers and last observations are rebuilt by SB3. An entry it does not know
    raises :class:`AgentLoadError` (it would have to be unpickled).
    """
    data = read_archive_data(model_path)
    run, hyper = _config_entry(info)
    try:
        built = build_hyperparameters(hyper)
    except ValueError as e:
        raise AgentLoadError(f"invalid hyperparameters in the configuration: {e}") from e
    defaults = {
        k: p.default
        for k, p in inspect.signature(cls.__init__).parameters.items()
        if p.default is not inspect.Parameter.empty
    }
    out: dict[str, Any] = {}
    for key, item in data.items():
        if not (isinstance(item, dict) and _SERIALIZED in item):
            continue
        shown = {k: v for k, v in item.items() if not k.startswith(":")}
        if key == "policy_class":
            out[key] = _policy_class(cls, run.get("policy", _default_policy(cls)), shown, model_path)
        elif key in ("observation_space", "action_space"):
            out[key] = _manifest_space(manifest, key, shown, model_path)
        elif key == "policy_kwargs":
            out[key] = _policy_kwargs(built.get("policy_kwargs") or {}, shown, model_path)
        elif key in _REBUILT:
            out[key] = None
        elif key in _FROM_CONFIG:
            out[key] = built.get(key, defaults.get(key))
        else:
            raise AgentLoadError(
                f"{model_path}: the archive's data entry {key!r} is a pickle that only unpickling "
                f"could restore; {_TRUST_HINT}"
            )
    return out


def _default_policy(cls: Any) -> str:
    return "MlpLstmPolicy" if cls.__name__ == "RecurrentPPO" else "MlpPolicy"


def _policy_class(cls: Any, name: Any, shown: Mapping[str, Any], model_path: Path) -> Any:
    aliases = getattr(cls, "policy_aliases", {})
    if name not in aliases:
        raise AgentLoadError(
            f"{model_path}: policy {name!r} of the configuration is not one of {cls.__name__}'s "
            f"{sorted(aliases)}; {_TRUST_HINT}"
        )
    policy = aliases[name]
    module = shown.get("__module__")
    if module is not None and module != policy.__module__:
        raise AgentLoadError(
            f"{model_path}: the archive's policy class is from {module}, the configuration's {name} "
            f"from {policy.__module__}"
        )
    return policy


def _manifest_space(manifest: Mapping[str, Any], key: str, shown: Mapping[str, Any], model_path: Path) -> Any:
    d = manifest[key]
    space = space_from_dict(d)
    checks = {"_shape": list(space.shape or ()), "dtype": str(space.dtype)}
    if d["type"] == "Discrete":
        checks["n"] = str(d["n"])
    for field, want in checks.items():
        if field in shown and str(shown[field]) != str(want) and shown[field] != want:
            raise AgentLoadError(
                f"{model_path}: the archive's {key} has {field} {shown[field]}, the manifest says {want}"
            )
    return space


def _policy_kwargs(kwargs: Mapping[str, Any], shown: Mapping[str, Any], model_path: Path) -> dict[str, Any]:
    mine = {k: _readable(v) for k, v in kwargs.items() if k != "device"}
    theirs = {k: v for k, v in shown.items() if k != "device"}
    if mine != theirs:
        raise AgentLoadError(
            f"{model_path}: policy_kwargs of the configuration {mine} differ from the archive's {theirs}"
        )
    return dict(kwargs)


def load_sb3_model(
    cls: Any,
    model_path: str | Path,
    info: Mapping[str, Any],
    manifest: Mapping[str, Any] | None,
    *,
    trust: bool = False,
    env: Any = None,
    device: str = "cpu",
    **kwargs: Any,
):
    """``cls.load`` of an SB3 archive; without ``trust``, through :func:`safe_custom_objects`."""
    model_path = Path(model_path)
    custom = None
    if not trust:
        if manifest is None:
            raise AgentLoadError(
                f"{model_path} has no {MANIFEST_FILE} beside it (its spaces and file hashes); "
                f"loading it would unpickle the archive's data; {_TRUST_HINT}"
            )
        custom = safe_custom_objects(cls, model_path, info, manifest)
    try:
        return cls.load(model_path, env=env, device=device, custom_objects=custom, **kwargs)
    except AgentLoadError:
        raise
    except Exception as e:  # SB3 raises many kinds on a corrupt or mismatched archive
        raise AgentLoadError(
            f"cannot load {model_path} as a {cls.__name__} model: {type(e).__name__}: {e}"
        ) from e


# --- loading an agent --------------------------------------------------------------------------


def _resolve(path: str | Path) -> tuple[Path, Path, bool]:
    """``(model zip, agent folder, legacy SB3 checkpoint)`` for an agent folder or a zip."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no trained agent at {p}: the path does not exist")
    if p.is_dir():
        model = p / MODEL_FILE
        if not model.is_file():
            raise FileNotFoundError(f"no trained agent at {p}: {model} does not exist")
        return model, p, False
    # A legacy SB3 checkpoint checkpoints/model_<n>_steps.zip (statistics beside it, config two up).
    legacy = re.fullmatch(r"(.*)_(\d+)_steps\.zip", p.name) is not None and p.parent.name == "checkpoints"
    return p, p.parent, legacy


def _run_info(folder: Path) -> dict[str, Any]:
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


def _stats_path(model: Path, folder: Path, legacy: bool) -> Path | None:
    if legacy:
        m = re.fullmatch(r"(.*)_(\d+)_steps\.zip", model.name)
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


def _expects_normalized_obs(info: Mapping[str, Any]) -> bool:
    try:
        opts = normalize_options(info.get("normalize"))
    except ValueError as e:
        raise AgentLoadError(f"invalid 'normalize' in the configuration: {e}") from e
    return bool(opts and opts.get("norm_obs", True))


def env_spaces(env: Any) -> tuple[Any, Any]:
    """``(observation space, action space)`` of one sub-environment of ``env``.

    ``env`` is a Gymnasium env, a Gymnasium vector env (its ``single_*`` spaces), an SB3
    ``VecEnv`` or a registered env id (made once to read its spaces).
    """
    if isinstance(env, str):
        import gymnasium as gym

        import navgym  # noqa: F401 - registers the environments
        from navgym.envs.registration import superseded_ids_quiet

        with superseded_ids_quiet():
            made = gym.make(env)
        try:
            return made.observation_space, made.action_space
        finally:
            made.close()
    obs = getattr(env, "single_observation_space", None) or env.observation_space
    act = getattr(env, "single_action_space", None) or env.action_space
    return obs, act


def space_summary(space: Any) -> str:
    """A one-line description of a space (``Box(25,) float32``, ``Discrete(2)``)."""
    d = space if isinstance(space, Mapping) else space_to_dict(space)
    if d.get("type") == "Box":
        return f"Box{tuple(d['shape'])} {d['dtype']}"
    if d.get("type") == "Discrete":
        return f"Discrete({d['n']})"
    if d.get("type") == "MultiDiscrete":
        return f"MultiDiscrete({d['nvec']})"
    return f"{d.get('type')}({d.get('n')})"


def check_spaces(agent_obs: Any, agent_act: Any, env: Any, what: str) -> None:
    """``AgentLoadError`` when ``env``'s spaces are not the agent's (the message says which)."""
    obs, act = env_spaces(env)
    for name, mine, theirs in (("observation", agent_obs, obs), ("action", agent_act, act)):
        diff = space_difference(mine, theirs)
        if diff is not None:
            raise AgentLoadError(
                f"{what} was saved for the {name} space {space_summary(mine)}, the environment has "
                f"{space_summary(theirs)} ({diff})"
            )


class TrainedAgent:
    """A trained SB3 model whose :meth:`predict` takes raw environment observations.

    Attributes:
        model: the stable-baselines3 model (its ``policy`` acts on normalized, and when
            ``frame_stack`` > 1 stacked, observations).
        normalizer: the saved observation normalization, or ``None``.
        algo, env_id, env_kwargs: from the run's ``config.yml`` when present.
        frame_stack: observations stacked per step (1: none).
        lstm: the recurrent policy's sizes (:func:`lstm_sizes`), ``None`` without memory.
        residual: a residual agent's baseline (:class:`agents.training.residual.ResidualRuntime`),
            ``None`` for a plain agent.
        observation_space: the environment's (raw, one frame), which :meth:`predict` takes.
        action_space: the environment's (the combined action's for a residual agent).
        path: the model archive.
        manifest: the checked ``manifest.json`` (``None`` for an agent loaded with ``trust``
            that has none).
    """

    def __init__(
        self,
        model: Any,
        normalizer: VecNormalizeStats | None,
        path: Path,
        info: dict[str, Any],
        manifest: dict[str, Any] | None = None,
        frame_stack: int = 1,
        observation_space: Any = None,
        residual: Any = None,
    ) -> None:
        self.model = model
        self.normalizer = normalizer
        self.path = path
        self.info = info
        self.manifest = manifest
        self.algo = info.get("algo")
        self.env_id = info.get("env_id")
        self.env_kwargs = dict(info.get("env_kwargs") or {})
        self.frame_stack = frame_stack_of(frame_stack)
        self.lstm = lstm_sizes(model)
        if observation_space is None:
            observation_space = unstacked_space(model.observation_space, self.frame_stack)
        #: One frame of what the model stacks (the env's observation, plus the base action of a
        #: residual agent with ``observe_base``).
        self.frame_space = observation_space
        self.residual = residual
        self.observation_space = residual.observation_space if residual is not None else observation_space
        self.action_space = residual.action_space if residual is not None else model.action_space
        self._stack = (
            FrameStack(self.frame_stack, observation_space.shape[0]) if self.frame_stack > 1 else None
        )

    @property
    def has_memory(self) -> bool:
        """Whether :meth:`predict`'s ``state`` carries memory (frames, LSTM states, a baseline's)."""
        return self._stack is not None or self.lstm is not None or self.residual is not None

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for raw observation(s) ``(n_obs,)`` or ``(B, n_obs)``; SB3's signature.

        An agent with memory keeps it in the returned ``state``: pass it back with the next
        step's observations, and ``episode_start`` True for the rows whose episode starts (their
        memory is reset; ``state=None`` starts every row afresh). A frame-stacked agent's state
        is a :class:`~agents.policy_runner.StackedState` (frames and the model's state), a
        RecurrentPPO's its LSTM states. A residual agent's is a
        :class:`~agents.training.residual.ResidualState` (the baseline's memory and the agent's
        own state) and its action ``clip(a_base + scale * a_res, low, high)``.
        :class:`agents.policy_runner.PredictRunner` does this.
        """
        obs = np.asarray(observation, dtype=np.float32)
        if obs.shape[-1:] != self.observation_space.shape:
            raise ValueError(
                f"observation must have shape {self.observation_space.shape} or (B, "
                f"{self.observation_space.shape[0]}); got {obs.shape}"
            )
        if self.residual is not None:
            return self._predict_residual(obs, state, episode_start, deterministic)
        return self._predict_model(obs, state, episode_start, deterministic)

    def _predict_residual(
        self, obs: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        from agents.training.residual import ResidualState

        single = obs.ndim == 1
        batch = obs.reshape(1, -1) if single else obs
        B = batch.shape[0]
        prev = state if isinstance(state, ResidualState) else None
        if prev is None:  # every row starts afresh (as the model's state None does)
            starts = np.ones(B, dtype=bool)
        elif episode_start is None:
            starts = np.zeros(B, dtype=bool)
        else:
            starts = np.asarray(episode_start, dtype=bool).reshape(B)
        base, base_state = self.residual.base(batch, None if prev is None else prev.base, starts)
        a_res, agent_state = self._predict_model(
            self.residual.model_obs(batch, base),
            None if prev is None else prev.agent,
            starts,
            deterministic,
        )
        actions = self.residual.combine(base, a_res)
        return (actions[0] if single else actions), ResidualState(base_state, agent_state)

    def _predict_model(
        self, obs: np.ndarray, state: Any, episode_start: np.ndarray | None, deterministic: bool
    ) -> tuple[np.ndarray, Any]:
        """The model's action for observations of :attr:`frame_space` (normalized, stacked here)."""
        if self.normalizer is not None:
            obs = self.normalizer(obs)
        if self._stack is None:
            return self.model.predict(
                obs, state=state, episode_start=episode_start, deterministic=deterministic
            )
        single = obs.ndim == 1
        batch = obs.reshape(1, -1) if single else obs
        prev = state if isinstance(state, StackedState) else None
        starts = None if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(-1)
        frames = self._stack.push(None if prev is None else prev.frames, batch, starts)
        actions, model_state = self.model.predict(
            frames,
            state=None if prev is None else prev.model,
            episode_start=episode_start,
            deterministic=deterministic,
        )
        return (actions[0] if single else actions), StackedState(frames, model_state)

    def __repr__(self) -> str:
        norm = "normalized obs" if self.normalizer is not None else "raw obs"
        memory = f", {self.frame_stack} frames" if self.frame_stack > 1 else ""
        memory += f", LSTM {self.lstm['lstm_hidden_size']}" if self.lstm else ""
        if self.residual is not None:
            memory += f", residual on {self.residual.spec.baseline} x {self.residual.spec.scale:g}"
        return f"TrainedAgent({self.algo}, {self.env_id}, {norm}{memory}, {self.path})"


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
    model_path, folder, legacy = _resolve(path)
    manifest = None if legacy else read_manifest(folder)
    if manifest is not None:
        verify_manifest(folder, manifest)
        _check_covered(folder, model_path, manifest)
    elif not trust:
        raise AgentLoadError(
            f"{folder} has no {MANIFEST_FILE} (SHA-256 of the agent's files and its spaces): it was "
            f"saved by an older navgym or elsewhere, and loading it would unpickle its files; {_TRUST_HINT}"
        )
    info = _run_info(folder.parent if legacy else folder)
    if manifest is not None:
        for key in ("env_id", "algo"):
            if info.get(key) is not None and manifest.get(key) not in (None, info[key]):
                raise AgentLoadError(
                    f"{folder / CONFIG_FILE} says {key} {info[key]!r}, {folder / MANIFEST_FILE} "
                    f"{manifest[key]!r}"
                )
    frame_stack = _frame_stack(folder, info, manifest)
    algo = algo or info.get("algo") or (manifest or {}).get("algo") or _algo_from_zip(model_path)
    if algo is None:
        raise AgentLoadError(f"cannot tell the algorithm of {model_path}; pass algo=")
    cls = algo_class(algo)
    _algo_from_zip(model_path)  # checks the archive before SB3 sees it (clear message)

    norm_path = _stats_path(model_path, folder, legacy)
    if norm_path is None and _expects_normalized_obs(info):
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
):
    """The baseline of a residual agent, rebuilt from its manifest (``None``: not a residual agent).

    ``config.yml``'s ``residual`` (resolved at training) and the manifest's must agree; the
    baseline is built for the env id and ``env_kwargs`` of the run (its observation layout).
    """
    from agents.training.config import residual_of

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
    if from_config != {**mine, "params": {k: float(v) for k, v in mine["params"].items()}}:
        raise AgentLoadError(
            f"{folder / CONFIG_FILE} says residual {from_config}, {folder / MANIFEST_FILE} {mine}"
        )
    env_id = manifest.get("env_id") or info.get("env_id")
    if not env_id:
        raise AgentLoadError(f"{folder}: a residual agent must record its env id (the baseline's layout)")
    from gymnasium import spaces

    from agents.training.residual import ResidualRuntime, ResidualSpec, make_residual_baseline

    env_obs = space_from_dict(record["env_observation_space"])
    spec = ResidualSpec(
        baseline=str(record["baseline"]),
        task=str(record["task"]),
        params=dict(record["params"]),
        scale=float(record["scale"]),
        observe_base=bool(record["observe_base"]),
        params_source=str(record["params_source"]),
    )
    try:
        import gymnasium as gym

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


def _check_covered(folder: Path, model_path: Path, manifest: Mapping[str, Any]) -> None:
    """The files loading reads must be listed in the manifest (an unlisted one is unchecked)."""
    listed = manifest["files"]
    for path in (model_path, folder / CONFIG_FILE, folder / STATS_FILE):
        if path.is_file() and path.name not in listed:
            raise AgentLoadError(
                f"{path} is not listed in {folder / MANIFEST_FILE}: it was added after saving"
            )


# --- converting an older agent -----------------------------------------------------------------


def convert_agent(path: str | Path, remove_pickle: bool = True) -> Path:
    """Write ``vecnormalize.npz`` and ``manifest.json`` for an agent saved before them.

    This unpickles the agent's ``vecnormalize.pkl`` and archive data once (``trust=True``): run
    it only on agents you trust (e.g. this repository's own). ``model.zip`` is kept as it is
    (its weights are what loading reads); ``vecnormalize.pkl`` is removed unless
    ``remove_pickle`` is false. Returns the manifest's path.
    """
    folder = Path(path)
    model_path, folder, legacy = _resolve(folder)
    if legacy or model_path.name != MODEL_FILE:
        raise ValueError(f"convert_agent takes an agent folder holding {MODEL_FILE}; got {path}")
    info = _run_info(folder)
    algo = info.get("algo") or _algo_from_zip(model_path)
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
