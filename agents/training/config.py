"""Training configurations: YAML files keyed by env id, in the rl-zoo3 layout.

``agents/configs/<algo>.yml`` maps each environment id to one entry::

    navgym/GpsInsFading-v0:
      n_envs: 16                 # sub-environments of the native vector env
      n_timesteps: 1.0e6         # total environment steps (all sub-envs together)
      policy: MlpPolicy
      normalize: {norm_obs: true, norm_reward: false}   # VecNormalize options, or true / false
      env_kwargs: {eval_info: false}                    # keyword arguments of the environment
      learning_rate: lin_3e-4    # hyperparameters of the SB3 algorithm (flat, as in rl-zoo3) ...
      n_steps: 128
      policy_kwargs: {net_arch: [64, 64], activation_fn: tanh}
      hyperparameters: {gamma: 0.97}   # ... or nested under ``hyperparameters`` (merged)
      checkpoint_freq: 100000    # environment steps between checkpoints (training option)
      keep_checkpoints: 2        # newest checkpoints kept (older ones deleted)
      save_replay_buffer: false  # SAC / DQN: checkpoint the replay buffer too (large); without
                                 # it a resumed off-policy run refills its buffer from scratch
      frame_stack: 4             # observations of the last 4 steps side by side (run key, as in
                                 # rl-zoo3; default 1: no stacking)
      residual: {baseline: sage_husa, params: tuned, scale: 0.5, observe_base: true}
                                 # residual policy learning over a classical baseline (run key)
      eval_freq: 100000          # environment steps between evaluations on tuning seeds, keeping
                                 # the best model in best/ (0 or absent: none; run key)
      eval_episodes: 16          # tuning episodes per evaluation (run key)

Ids without an entry of their own take the file's ``defaults:`` section (:func:`default_entry`),
so that every trainable id (:func:`trainable_ids`, the newest version of each name) trains::

    defaults:
      all: {n_envs: 16, n_timesteps: 1.0e+6, ...}        # every id the algorithm fits
      task: {resample: {n_envs: 32, ent_coef: 0.01}}     # by the id's task (task= of the registration)
      platform: {GpsIns: {gamma: 0.98}}                  # by the id's platform (its name before the task)

merged in that order (a later level's keys win; ``env_kwargs`` and ``normalize`` key by key).
An id's own entry replaces the defaults whole (and is what rl-zoo3 reads; rl-zoo3 does not read
``defaults:``). A file without ``all`` covers only the tasks it names (``sac.yml``: the Box
tasks; ``dqn.yml``: resample). An id that is not registered raises :class:`UnknownEnvError`
with the closest registered ids (``did you mean ...``).

Policies with memory, for tasks whose regime must be inferred over time:

* ``frame_stack: n`` (an integer >= 1) wraps the training env in SB3's ``VecFrameStack`` *outside*
  ``VecNormalize`` (``VecFrameStack(VecNormalize(VecMonitor(env)))``, rl-zoo3's order): the
  normalization statistics stay those of one observation (``vecnormalize.npz`` keeps its
  shape), and the policy sees the last ``n`` normalized observations, oldest first, zeros before
  the episode's first step. A saved agent records ``frame_stack`` (``config.yml``, manifest) and
  :class:`agents.training.agent.TrainedAgent` stacks the same way at evaluation, per episode.
* algorithm ``ppo_lstm`` (``agents/configs/ppo_lstm.yml``): sb3-contrib's ``RecurrentPPO`` with
  ``policy: MlpLstmPolicy`` (the default for it); its ``policy_kwargs`` take, besides
  ``net_arch`` / ``activation_fn``, ``lstm_hidden_size`` and ``n_lstm_layers`` (integers >= 1),
  ``shared_lstm`` and ``enable_critic_lstm`` (booleans; a shared LSTM needs
  ``enable_critic_lstm: false``). Its LSTM state is carried from step to step and reset at each
  episode start when it is rolled out (:mod:`agents.policy_runner`). ``n_steps`` is also the
  length of the sequences the LSTM is trained on.

Residual policy learning (Silver et al. 2018, arXiv:1812.06298; Johannink et al. 2019, ICRA):
``residual`` (a mapping, or null / absent: none) makes the agent output a correction added to a
fixed classical baseline's action, ``a = clip(a_base + scale * a_res, low, high)`` with
``a_res`` in ``[-1, 1]``, so that a policy whose output starts near 0 starts from the baseline's
behaviour (:mod:`agents.training.residual`). Its keys:

* ``baseline`` (required): a baseline of the env's task (:func:`agents.baselines.baseline_specs`
  of the env, e.g. ``sage_husa`` on NoiseScale, ``chi_square`` on the per-row Mixture v2 ids);
* ``params``: ``tuned`` (default; the baseline's entry in ``agents/baselines/tuned/<id>.json``,
  written by ``navgym tune --env ID --episodes 256 --out agents/baselines/tuned``) or a mapping
  ``{parameter: number}`` (the baseline's other parameters keep their defaults);
* ``scale`` (default 0.5): the residual's range, in action units (> 0);
* ``observe_base`` (default true): the base action is appended to the observation;
* ``agent``: with ``baseline: supervised`` only (and then required), the folder of an
  :mod:`agents.supervised` agent of the env id (``agents/zoo/<Id>-supervised``), whose policy is
  the base: the warm start of the learned v3 agents (the composite starts as the supervised agent,
  and RL learns the correction). It takes no ``params`` (its manifest holds them).

Box actions only (a Discrete task's entry with ``residual`` is rejected). A run records the
resolved parameters in its ``config.yml`` and manifest, so the saved agent rebuilds the same
baseline (:func:`agents.training.loading.load_agent`).

Differences from rl-zoo3, all on the safe side: ``policy_kwargs`` and ``normalize`` are YAML
mappings, never Python strings to ``eval``; ``activation_fn`` is a name (``tanh``, ``relu``,
``elu``, ``leaky_relu``, ``gelu``); schedules are ``lin_<value>`` strings (linear decay from
``value`` to 0 over training, for ``learning_rate`` and ``clip_range``).

rl-zoo3 reads the shipped files as they are (``python -m rl_zoo3.train --algo ppo --env ID
--gym-packages navgym --conf-file agents/configs/ppo.yml``; docs/scaling.md), because:

* the per-env entries hold only keys rl-zoo3 knows (its run keys and the algorithm's keyword
  arguments); navgym's own run keys (:data:`NAVGYM_ONLY_KEYS`: ``checkpoint_freq``,
  ``keep_checkpoints``, ``save_replay_buffer``, ``residual``, ``hyperparameters``) sit in the
  file's top-level ``navgym:`` section (:data:`SIDECAR_KEY`), keyed by env id, which
  :func:`read_config_file` merges into the entries (rl-zoo3 only looks up the env id's entry);
* ``policy_kwargs`` may be rl-zoo3's string form ``"dict(net_arch=[64, 64],
  activation_fn=nn.Tanh)"``: navgym parses it with :func:`zoo_policy_kwargs` (``ast``: literal
  values and ``nn.<Activation>`` names only, nothing evaluated) into the mapping form above.

So a file's entries as navgym reads them (and as ``config.yml`` of a run records them) are the
mappings described above whichever form the file uses. Entries that keep navgym keys inline
still work with ``navgym train`` (not with rl-zoo3); a key given both inline and in the section
is an error.
"""

from __future__ import annotations

import ast
import copy
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

#: Folder of the shipped configurations (``<algo>.yml``).
CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"
#: Algorithms that :func:`agents.training.train` runs (``ppo_lstm``: sb3-contrib's RecurrentPPO).
ALGOS = ("ppo", "sac", "dqn", "a2c", "ppo_lstm")
#: Algorithms whose policy keeps a recurrent state between steps.
RECURRENT_ALGOS = ("ppo_lstm",)
#: ``policy`` when an entry does not say.
DEFAULT_POLICY = {"ppo_lstm": "MlpLstmPolicy"}
#: ``policy_kwargs`` of recurrent policies only: integers >= 1 and booleans.
LSTM_INT_KWARGS = ("lstm_hidden_size", "n_lstm_layers")
LSTM_BOOL_KWARGS = ("shared_lstm", "enable_critic_lstm")
#: Entry keys that configure the run rather than the SB3 algorithm.
RUN_KEYS = (
    "n_envs",
    "n_timesteps",
    "policy",
    "normalize",
    "env_kwargs",
    "hyperparameters",
    "checkpoint_freq",
    "keep_checkpoints",
    "save_replay_buffer",
    "frame_stack",
    "residual",
    "eval_freq",
    "eval_episodes",
)
#: Run keys of navgym that rl-zoo3 does not know: kept in the ``navgym:`` section of a file.
NAVGYM_ONLY_KEYS = (
    "hyperparameters",
    "checkpoint_freq",
    "keep_checkpoints",
    "save_replay_buffer",
    "residual",
    "eval_freq",
    "eval_episodes",
)
#: Top-level key of a configuration file holding the navgym-only options, keyed by env id.
SIDECAR_KEY = "navgym"
#: Tuning episodes per periodic evaluation (``eval_freq``) when the entry does not say.
DEFAULT_EVAL_EPISODES = 16
#: Top-level key of a configuration file holding the defaults of ids without an entry of their own.
DEFAULTS_KEY = "defaults"
#: Levels of the defaults, merged in this order (a later level's keys win).
DEFAULT_LEVELS = ("all", "task", "platform")
#: Entry keys whose mappings the levels merge key by key (others are replaced whole).
MERGED_KEYS = ("env_kwargs", "normalize")
#: rl-zoo3's ``nn.<Class>`` activation names -> navgym's names.
ZOO_ACTIVATIONS = {
    "Tanh": "tanh",
    "ReLU": "relu",
    "ELU": "elu",
    "LeakyReLU": "leaky_relu",
    "GELU": "gelu",
    "SiLU": "silu",
}
#: Keys of an entry's ``residual`` mapping, and the defaults of the optional ones.
RESIDUAL_KEYS = ("baseline", "params", "scale", "observe_base", "agent")
RESIDUAL_DEFAULTS = {"params": "tuned", "scale": 0.5, "observe_base": True, "agent": None}
#: ``residual.baseline`` of a supervised agent's folder (``residual.agent``) as the base policy.
SUPERVISED_BASE = "supervised"
ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")


class UnknownEnvError(KeyError):
    """No configuration entry for an environment id (a ``KeyError`` with a readable message)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def check_algo(algo: str) -> str:
    """Lower-case ``algo`` after checking it is one of :data:`ALGOS` (``ValueError`` otherwise)."""
    a = str(algo).lower()
    if a not in ALGOS:
        raise ValueError(f"algo must be one of {list(ALGOS)}; got {algo!r}")
    return a


def default_policy(algo: str) -> str:
    """The SB3 policy of ``algo`` when an entry names none (``MlpPolicy``; ``MlpLstmPolicy``)."""
    return DEFAULT_POLICY.get(check_algo(algo), "MlpPolicy")


def config_path(algo: str) -> Path:
    """Path of the shipped configuration file of ``algo``."""
    return CONFIG_DIR / f"{check_algo(algo)}.yml"


def _read_yaml(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"configuration file not found: {path}")
    with path.open() as f:
        data = yaml.safe_load(f) or {}
    if not isinstance(data, Mapping):
        raise ValueError(f"{path}: expected a mapping of env ids to entries; got {type(data).__name__}")
    return dict(data)


def read_config_file(path: str | Path) -> dict[str, Any]:
    """The mapping ``env id -> entry`` of a YAML configuration file, in navgym's form.

    The ``navgym:`` section's options are merged into their entries (and the section dropped),
    rl-zoo3 ``policy_kwargs`` strings become mappings (module docstring), the ``defaults:``
    section is left out (:func:`read_defaults`). A file holding one bare entry (a run's
    ``config.yml``) is returned as it is.
    """
    data = _read_yaml(path)
    data.pop(DEFAULTS_KEY, None)
    try:
        return merge_sidecar(data)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def read_defaults(path: str | Path) -> dict[str, Any]:
    """The ``defaults:`` section of a configuration file, level by level.

    ``{"all": entry, "task": {name: entry}, "platform": {name: entry}}`` (absent levels empty;
    ``policy_kwargs`` strings parsed).

    Raises:
        ValueError: the section holds another level, or a level is not a mapping of mappings.
    """
    section = _read_yaml(path).get(DEFAULTS_KEY) or {}
    if not isinstance(section, Mapping):
        raise ValueError(f"{path}: {DEFAULTS_KEY!r} must be a mapping; got {section!r}")
    unknown = sorted(str(k) for k in set(section) - set(DEFAULT_LEVELS))
    if unknown:
        raise ValueError(f"{path}: {DEFAULTS_KEY}: unknown levels {unknown}; it takes {list(DEFAULT_LEVELS)}")

    def entry(value: Any, where: str) -> dict[str, Any]:
        if not isinstance(value, Mapping):
            raise ValueError(f"{path}: {where} must be a mapping of entry keys; got {value!r}")
        out = copy.deepcopy(dict(value))
        if isinstance(out.get("policy_kwargs"), str):
            out["policy_kwargs"] = zoo_policy_kwargs(out["policy_kwargs"])
        return out

    out: dict[str, Any] = {"all": entry(section.get("all") or {}, f"{DEFAULTS_KEY}.all")}
    for level in ("task", "platform"):
        named = section.get(level) or {}
        if not isinstance(named, Mapping):
            raise ValueError(f"{path}: {DEFAULTS_KEY}.{level} must map names to entries; got {named!r}")
        out[level] = {str(k): entry(v, f"{DEFAULTS_KEY}.{level}.{k}") for k, v in named.items()}
    return out


def merge_sidecar(data: Mapping[str, Any]) -> dict[str, Any]:
    """``env id -> entry`` of a file's parsed YAML: the ``navgym:`` section merged into the entries.

    Raises:
        ValueError: the section is not a mapping of env ids to mappings, names an env id that
            has no entry, holds a key that is not in :data:`NAVGYM_ONLY_KEYS`, or a key that the
            entry also holds.
    """
    data = dict(data)
    side = data.pop(SIDECAR_KEY, None) or {}
    if not isinstance(side, Mapping):
        raise ValueError(f"the {SIDECAR_KEY!r} section must map env ids to options; got {side!r}")
    out: dict[str, Any] = {}
    for env_id, entry in data.items():
        if isinstance(entry, Mapping) and isinstance(entry.get("policy_kwargs"), str):
            entry = {**entry, "policy_kwargs": zoo_policy_kwargs(entry["policy_kwargs"])}
        out[env_id] = entry
    for env_id, opts in side.items():
        if env_id not in out or not isinstance(out[env_id], Mapping):
            raise ValueError(f"the {SIDECAR_KEY!r} section names {env_id!r}, which has no entry")
        if not isinstance(opts, Mapping):
            raise ValueError(f"{SIDECAR_KEY}.{env_id} must be a mapping of options; got {opts!r}")
        unknown = sorted(str(k) for k in set(opts) - set(NAVGYM_ONLY_KEYS))
        if unknown:
            raise ValueError(
                f"{SIDECAR_KEY}.{env_id}: {unknown} are not navgym-only keys {list(NAVGYM_ONLY_KEYS)} "
                "(rl-zoo3 keys belong in the entry itself)"
            )
        both = sorted(str(k) for k in set(opts) & set(out[env_id]))
        if both:
            raise ValueError(f"{env_id}: {both} given both in the entry and in the {SIDECAR_KEY!r} section")
        out[env_id] = {**out[env_id], **copy.deepcopy(dict(opts))}
    return out


def _zoo_value(node: ast.AST, text: str) -> Any:
    """A literal, ``nn.<Activation>`` (its navgym name) or a nested ``dict(...)`` of rl-zoo3's form."""
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "nn":
        if node.attr not in ZOO_ACTIVATIONS:
            raise ValueError(
                f"policy_kwargs {text!r}: activation nn.{node.attr} is not one of "
                f"{['nn.' + k for k in ZOO_ACTIVATIONS]}"
            )
        return ZOO_ACTIVATIONS[node.attr]
    if isinstance(node, ast.Call):
        return _zoo_dict(node, text)
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise ValueError(
            f"policy_kwargs {text!r}: only literals, nn.<Activation> and dict(...) are read "
            f"(not {ast.unparse(node)!r}); nothing is evaluated"
        ) from None


def _zoo_dict(node: ast.AST, text: str) -> dict[str, Any]:
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict"):
        raise ValueError(f"policy_kwargs {text!r}: expected rl-zoo3's form dict(key=value, ...)")
    if node.args or any(k.arg is None for k in node.keywords):
        raise ValueError(f"policy_kwargs {text!r}: dict(...) takes keyword arguments only")
    return {k.arg: _zoo_value(k.value, text) for k in node.keywords}


def zoo_policy_kwargs(text: str) -> dict[str, Any]:
    """rl-zoo3's ``policy_kwargs`` string as navgym's mapping, parsed without evaluating anything.

    ``"dict(net_arch=[64, 64], activation_fn=nn.Tanh, log_std_init=-1.0)"`` ->
    ``{"net_arch": [64, 64], "activation_fn": "tanh", "log_std_init": -1.0}``.

    Raises:
        ValueError: the string is not ``dict(...)`` of keyword arguments whose values are
            literals, ``nn.<Activation>`` of :data:`ZOO_ACTIVATIONS` or nested ``dict(...)``.
    """
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as e:
        raise ValueError(f"policy_kwargs {text!r} is not rl-zoo3's dict(...) form ({e.msg})") from None
    return _zoo_dict(tree.body, text)


def load_config(env_id: str, algo: str = "ppo", path: str | Path | None = None) -> dict[str, Any]:
    """The configuration of ``env_id`` in ``path`` (default: the shipped ``<algo>.yml``).

    The id's own entry when the file has one (complete, as rl-zoo3 reads it); otherwise the
    file's ``defaults:`` for the id's task and platform (:func:`default_entry`).

    Raises:
        UnknownEnvError: ``env_id`` is not registered (the message suggests a close id), or
            neither an entry nor the defaults cover it (the message says which tasks they cover).
    """
    path = config_path(algo) if path is None else Path(path)
    data = read_config_file(path)
    if env_id not in data:
        return default_entry(env_id, algo, path)
    entry = data[env_id]
    if not isinstance(entry, Mapping):
        raise ValueError(f"{path}: entry of {env_id!r} must be a mapping; got {type(entry).__name__}")
    return copy.deepcopy(dict(entry))


def registered_ids() -> list[str]:
    """Every id registered with Gymnasium once navgym (and its platform entry points) loaded."""
    import gymnasium as gym

    import navgym  # noqa: F401  (registers navgym's ids)
    from navgym.envs import registration

    register_all = getattr(registration, "register_all", None)
    if register_all is not None:
        register_all()
    return sorted(gym.registry)


def unknown_id_message(env_id: str, known: list[str] | None = None) -> str:
    """``unknown env id ...``, with the closest registered ids as a suggestion.

    An id outside the ``navgym/`` namespace also points to ``--gym-packages`` (the module that
    registers it).
    """
    import difflib

    known = registered_ids() if known is None else known
    close = difflib.get_close_matches(env_id, known, n=3, cutoff=0.6)
    shown = " or ".join(repr(c) for c in close)
    hint = f"; did you mean {shown}?" if close else " (navgym list shows the ids)"
    if not env_id.startswith("navgym/"):
        hint += "; an id registered outside navgym needs its module: --gym-packages MODULE"
    return f"unknown env id {env_id!r}{hint}"


def task_and_platform(env_id: str) -> tuple[str | None, str | None]:
    """The task (``task=`` of the registration) and the platform (the id's name before the task).

    ``navgym/Robot2dFading-v2`` -> ``("fading", "Robot2d")``; ``(None, None)`` for an id
    registered without ``task``.
    """
    import gymnasium as gym

    task = gym.spec(env_id).kwargs.get("task")
    if not isinstance(task, str):
        return None, None
    name = env_id.split("/")[-1].rsplit("-v", 1)[0]
    platform = name[: len(name) - len(task)] if name.lower().endswith(task.lower()) else None
    return task, platform or None


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if k in MERGED_KEYS and isinstance(out.get(k), Mapping) and isinstance(v, Mapping):
            out[k] = {**out[k], **copy.deepcopy(dict(v))}
        else:
            out[k] = copy.deepcopy(v)
    return out


def default_entry(env_id: str, algo: str = "ppo", path: str | Path | None = None) -> dict[str, Any]:
    """The entry of ``env_id`` from the ``defaults:`` section of ``path`` (the shipped file).

    ``all``, then ``task.<task>``, then ``platform.<Platform>`` (later keys win; ``env_kwargs``
    and ``normalize`` merged key by key). An algorithm whose file has no ``all`` level covers
    only the tasks it names (``sac``: Box actions; ``dqn``: Discrete).

    Raises:
        UnknownEnvError: ``env_id`` is not registered, or the defaults do not cover its task.
    """
    path = config_path(algo) if path is None else Path(path)
    known = registered_ids()
    if env_id not in known:
        raise UnknownEnvError(unknown_id_message(env_id, known))
    defaults = read_defaults(path)
    task, platform = task_and_platform(env_id)
    if not defaults["all"] and task not in defaults["task"]:
        covered = sorted(defaults["task"]) or "none"
        raise UnknownEnvError(
            f"no {check_algo(algo)} configuration for env id {env_id!r} in {path}: it has no entry of its "
            f"own, and the defaults cover tasks {covered}, not {task!r}"
        )
    entry = _merge(defaults["all"], defaults["task"].get(str(task), {}))
    return _merge(entry, defaults["platform"].get(str(platform), {}))


def trainable_ids() -> list[str]:
    """The navgym ids to train on: the newest version of each ``navgym/<Name>``, in registry order.

    The evaluation-only ids (real data, :data:`navgym.envs.ids.EVALUATION_ONLY`) are left out.
    """
    from navgym.envs.ids import EVALUATION_ONLY
    from navgym.envs.registration import ENVIRONMENTS

    registered_ids()
    newest: dict[str, tuple[int, str]] = {}
    order: list[str] = []
    for e in ENVIRONMENTS:
        name, _, version = e[0].rpartition("-v")
        if name not in newest:
            order.append(name)
        if name not in newest or int(version) > newest[name][0]:
            newest[name] = (int(version), e[0])
    return [newest[n][1] for n in order if newest[n][1] not in EVALUATION_ONLY]


def split_entry(entry: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(run options, SB3 hyperparameters)`` of a configuration entry (nested ones merged)."""
    run = {k: copy.deepcopy(v) for k, v in entry.items() if k in RUN_KEYS}
    hyper = {k: copy.deepcopy(v) for k, v in entry.items() if k not in RUN_KEYS}
    nested = run.pop("hyperparameters", None) or {}
    if not isinstance(nested, Mapping):
        raise ValueError(f"'hyperparameters' must be a mapping; got {type(nested).__name__}")
    clash = sorted(set(nested) & set(hyper))
    if clash:
        raise ValueError(f"hyperparameters given both flat and under 'hyperparameters': {clash}")
    hyper.update(nested)
    if "n_envs" in run and (not isinstance(run["n_envs"], int) or run["n_envs"] < 1):
        raise ValueError(f"n_envs must be an integer >= 1; got {run['n_envs']!r}")
    if "n_timesteps" in run:
        run["n_timesteps"] = int(float(run["n_timesteps"]))
    if "frame_stack" in run:
        run["frame_stack"] = frame_stack_of(run["frame_stack"])
    if "residual" in run:
        run["residual"] = residual_of(run["residual"])
    return run, hyper


def frame_stack_of(value: Any) -> int:
    """The checked ``frame_stack`` of an entry (``None``: 1, no stacking)."""
    if value is None:
        return 1
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"frame_stack must be an integer >= 1 (1: no stacking); got {value!r}")
    return int(value)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def residual_of(value: Any) -> dict[str, Any] | None:
    """The checked ``residual`` of an entry, defaults filled in (``None``, ``false``: no residual).

    This checks the fields themselves; whether ``baseline`` and ``params`` fit the environment
    is checked when the run starts (:func:`agents.training.residual.resolve_residual`).

    Raises:
        ValueError: naming the key (``residual.scale`` ...) that is wrong.
    """
    if value is None or value is False:
        return None
    if not isinstance(value, Mapping):
        raise ValueError(
            "residual must be a mapping {baseline, params, scale, observe_base} (or null: none); "
            f"got {value!r}"
        )
    unknown = sorted(str(k) for k in set(value) - set(RESIDUAL_KEYS))
    if unknown:
        raise ValueError(f"residual: unknown keys {unknown}; it takes {list(RESIDUAL_KEYS)}")
    out = {**RESIDUAL_DEFAULTS, **dict(value)}
    if "baseline" not in value:
        raise ValueError(
            "residual.baseline is required: the name of one of the env's baselines (e.g. sage_husa)"
        )
    if not isinstance(out["baseline"], str) or not out["baseline"]:
        raise ValueError(
            f"residual.baseline must be a baseline name (e.g. sage_husa); got {out['baseline']!r}"
        )
    params = out["params"]
    if isinstance(params, Mapping):
        for k, v in params.items():
            if not isinstance(k, str) or not _number(v):
                raise ValueError(f"residual.params.{k} must be a finite number; got {v!r}")
        out["params"] = {k: float(v) for k, v in params.items()}
    elif params != "tuned":
        raise ValueError(
            f"residual.params must be 'tuned' (the tuned file of the env id) or a mapping of parameter "
            f"-> number; got {params!r}"
        )
    if not _number(out["scale"]) or out["scale"] <= 0:
        raise ValueError(
            "residual.scale must be a number > 0 (the residual's range in action units); "
            f"got {out['scale']!r}"
        )
    out["scale"] = float(out["scale"])
    if not isinstance(out["observe_base"], bool):
        raise ValueError(f"residual.observe_base must be true or false; got {out['observe_base']!r}")
    _check_supervised_base(value, out)
    return {k: out[k] for k in RESIDUAL_KEYS if k != "agent" or out["agent"] is not None}


def _check_supervised_base(value: Mapping[str, Any], out: dict[str, Any]) -> None:
    """``residual.agent`` goes with ``baseline: supervised`` (and it only); no ``params`` then."""
    agent = out["agent"]
    if (out["baseline"] == SUPERVISED_BASE) != (agent is not None):
        raise ValueError(
            "residual.agent (the folder of an agents.supervised agent) goes with baseline: supervised, "
            f"and baseline: supervised needs it; got baseline {out['baseline']!r}, agent {agent!r}"
        )
    if agent is None:
        return
    if not isinstance(agent, str) or not agent:
        raise ValueError(f"residual.agent must be a folder path; got {agent!r}")
    if value.get("params", {}) not in ({}, "tuned"):
        raise ValueError("residual.params: a supervised base takes no parameters (its folder holds them)")
    out["params"] = {}


def check_algo_entry(algo: str, run: Mapping[str, Any], hyper: Mapping[str, Any]) -> None:
    """``ValueError`` naming the key when an entry's policy or LSTM options do not fit ``algo``."""
    algo = check_algo(algo)
    policy = run.get("policy", default_policy(algo))
    pk = hyper.get("policy_kwargs") or {}
    pk = pk if isinstance(pk, Mapping) else {}
    lstm_keys = sorted(k for k in (*LSTM_INT_KWARGS, *LSTM_BOOL_KWARGS) if k in pk)
    if algo in RECURRENT_ALGOS:
        if "Lstm" not in str(policy):
            raise ValueError(f"policy of {algo} must be a recurrent policy (MlpLstmPolicy); got {policy!r}")
    elif lstm_keys:
        raise ValueError(
            f"policy_kwargs {lstm_keys} configure an LSTM: only recurrent algorithms "
            f"{list(RECURRENT_ALGOS)} take them (algo {algo})"
        )
    elif "Lstm" in str(policy):
        raise ValueError(f"policy {policy!r} is recurrent: use algo ppo_lstm (algo {algo})")


def normalize_options(value: Any) -> dict[str, Any] | None:
    """``VecNormalize`` keyword arguments from an entry's ``normalize`` (``None``: no wrapper)."""
    if value is None or value is False:
        return None
    if value is True:
        return {"norm_obs": True, "norm_reward": False}
    if isinstance(value, Mapping):
        opts = {"norm_obs": True, "norm_reward": False}
        opts.update(value)
        return opts
    raise ValueError(f"normalize must be true, false or a mapping of VecNormalize options; got {value!r}")


def linear_schedule(initial: float):
    """Linear decay from ``initial`` to 0 over training (SB3 passes ``progress_remaining``)."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    schedule.initial = initial  # type: ignore[attr-defined]
    return schedule


def _schedule(value: Any) -> Any:
    if isinstance(value, str) and value.startswith("lin_"):
        return linear_schedule(float(value[4:]))
    if isinstance(value, str):
        return float(value)
    return value


def _activation(name: str):
    import torch.nn as nn

    table = {
        "tanh": nn.Tanh,
        "relu": nn.ReLU,
        "elu": nn.ELU,
        "leaky_relu": nn.LeakyReLU,
        "gelu": nn.GELU,
        "silu": nn.SiLU,
    }
    try:
        return table[str(name).lower()]
    except KeyError:
        raise ValueError(f"activation_fn must be one of {list(ACTIVATIONS)}; got {name!r}") from None


def _check_lstm_kwargs(pk: Mapping[str, Any]) -> None:
    """The LSTM options of ``policy_kwargs``: integers >= 1, booleans, no shared LSTM beside a critic's."""
    for key in LSTM_INT_KWARGS:
        v = pk.get(key)
        if key in pk and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise ValueError(f"policy_kwargs.{key} must be an integer >= 1; got {v!r}")
    for key in LSTM_BOOL_KWARGS:
        if key in pk and not isinstance(pk[key], bool):
            raise ValueError(f"policy_kwargs.{key} must be true or false; got {pk[key]!r}")
    if pk.get("shared_lstm") and pk.get("enable_critic_lstm", True):
        raise ValueError(
            "policy_kwargs.shared_lstm: true needs enable_critic_lstm: false (the critic either shares "
            "the actor's LSTM or has its own, not both)"
        )


def build_hyperparameters(hyper: Mapping[str, Any]) -> dict[str, Any]:
    """SB3 constructor keyword arguments from YAML values (schedules, activation names, floats)."""
    out: dict[str, Any] = {}
    for k, v in hyper.items():
        if k in ("learning_rate", "clip_range", "clip_range_vf"):
            out[k] = _schedule(v)
        elif k == "policy_kwargs":
            if not isinstance(v, Mapping):
                raise ValueError(
                    f"policy_kwargs must be a YAML mapping (not a string to eval); got {type(v).__name__}"
                )
            pk = dict(v)
            if "activation_fn" in pk:
                pk["activation_fn"] = _activation(pk["activation_fn"])
            if isinstance(pk.get("net_arch"), Mapping):
                pk["net_arch"] = dict(pk["net_arch"])
            _check_lstm_kwargs(pk)
            out[k] = pk
        elif isinstance(v, str) and k not in ("device", "target_kl", "ent_coef"):
            # YAML reads "3e-4" as a string; numbers only here (ent_coef may be "auto").
            try:
                out[k] = float(v) if any(c in v for c in ".eE") else int(v)
            except ValueError:
                out[k] = v
        else:
            out[k] = v
    return out
