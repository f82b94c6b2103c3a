"""The SB3 model of a saved agent, rebuilt without unpickling.

SB3 pickles into its archive's ``data`` the policy class, the spaces, schedules and buffers; its
``cls.load`` would unpickle them. :func:`load_sb3_model` replaces every such entry through SB3's
``custom_objects`` (:func:`safe_custom_objects`: the policy class and keyword arguments from
``config.yml``, checked against what the archive says of them in plain text, the spaces from the
manifest, schedules from the configuration; buffers rebuilt by SB3), and the weights come from
the archive's ``.pth`` state dicts (``torch.load(weights_only=True)``). Only ``trust=True`` lets
SB3 unpickle the archive as it is (an archive made elsewhere, or without a manifest).
"""

from __future__ import annotations

import inspect
import json
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.training.agent_files import MANIFEST_FILE, TRUST_HINT, AgentLoadError
from agents.training.config import ALGOS, build_hyperparameters, split_entry
from agents.training.spaces import space_from_dict

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

__all__ = [
    "algo_class",
    "algo_from_archive",
    "load_sb3_model",
    "lstm_sizes",
    "read_archive_data",
    "safe_custom_objects",
]

#: The marker of an entry SB3 pickled into the archive's ``data``.
_SERIALIZED = ":serialized:"


def algo_class(algo: str) -> type[BaseAlgorithm]:
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
    classes: dict[str, type[BaseAlgorithm]] = {"ppo": sb3.PPO, "sac": sb3.SAC, "dqn": sb3.DQN, "a2c": sb3.A2C}
    try:
        return classes[key]
    except KeyError:
        raise ValueError(f"algo must be one of {list(ALGOS)}; got {algo!r}") from None


def lstm_sizes(model: Any) -> dict[str, Any] | None:
    """The LSTM sizes of a recurrent model or policy (``None`` for a policy without one).

    ``{lstm_hidden_size, n_lstm_layers, shared_lstm, enable_critic_lstm}`` of sb3-contrib's
    ``RecurrentActorCriticPolicy`` (the keys of :data:`agents.training.manifest.LSTM_KEYS`).
    """
    from stable_baselines3.common.base_class import BaseAlgorithm

    try:
        from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
    except ImportError:  # without sb3-contrib no model has a recurrent policy
        return None
    policy = model.policy if isinstance(model, BaseAlgorithm) else model
    if not isinstance(policy, RecurrentActorCriticPolicy):
        return None
    shape = policy.lstm_hidden_state_shape
    return {
        "lstm_hidden_size": int(shape[-1]),
        "n_lstm_layers": int(shape[0]),
        "shared_lstm": bool(policy.shared_lstm),
        "enable_critic_lstm": bool(policy.enable_critic_lstm),
    }


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


def algo_from_archive(model: str | Path) -> str | None:
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
                f"could restore; {TRUST_HINT}"
            )
    return out


def _default_policy(cls: Any) -> str:
    return "MlpLstmPolicy" if cls.__name__ == "RecurrentPPO" else "MlpPolicy"


def _policy_class(cls: Any, name: Any, shown: Mapping[str, Any], model_path: Path) -> Any:
    from agents.training.row_policy import POLICIES

    aliases = {**cls.policy_aliases, **POLICIES}
    if name not in aliases:
        raise AgentLoadError(
            f"{model_path}: policy {name!r} of the configuration is not one of {cls.__name__}'s "
            f"{sorted(aliases)}; {TRUST_HINT}"
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
    cls: type[BaseAlgorithm],
    model_path: str | Path,
    info: Mapping[str, Any],
    manifest: Mapping[str, Any] | None,
    *,
    trust: bool = False,
    env: Any = None,
    device: str = "cpu",
    **kwargs: Any,
) -> BaseAlgorithm:
    """``cls.load`` of an SB3 archive; without ``trust``, through :func:`safe_custom_objects`."""
    model_path = Path(model_path)
    custom = None
    if not trust:
        if manifest is None:
            raise AgentLoadError(
                f"{model_path} has no {MANIFEST_FILE} beside it (its spaces and file hashes); "
                f"loading it would unpickle the archive's data; {TRUST_HINT}"
            )
        custom = safe_custom_objects(cls, model_path, info, manifest)
    try:
        model = cls.load(model_path, env=env, device=device, custom_objects=custom, **kwargs)
    except AgentLoadError:
        raise
    except Exception as e:  # SB3 raises many kinds on a corrupt or mismatched archive
        raise AgentLoadError(
            f"cannot load {model_path} as a {cls.__name__} model: {type(e).__name__}: {e}"
        ) from e
    check_finite_weights(model, model_path)
    return model


def check_finite_weights(model: Any, model_path: str | Path) -> None:
    """Refuse a model whose policy has NaN or infinite weights (:class:`AgentLoadError` naming the file).

    Such a model loads but its first ``predict`` fails (or acts on NaN); the error lists the
    state-dict tensors that hold them.
    """
    import torch

    bad = [
        name
        for name, t in model.policy.state_dict().items()
        if torch.is_tensor(t) and t.is_floating_point() and not bool(torch.isfinite(t).all())
    ]
    if bad:
        shown = ", ".join(bad[:5]) + (f" and {len(bad) - 5} more" if len(bad) > 5 else "")
        raise AgentLoadError(
            f"{model_path}: the policy's weights have non-finite entries (NaN or inf) in {shown}"
        )
