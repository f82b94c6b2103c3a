"""Plain stable-baselines3 saves in and out: ``navgym export`` and ``navgym import``.

A navgym agent folder (:mod:`agents.training.agent_files`) keeps its normalization as plain
arrays (``vecnormalize.npz``) and a manifest, so that loading never unpickles. Plain SB3 keeps
a pickled ``VecNormalize`` (``vecnormalize.pkl``) beside ``model.zip``. These two commands
convert between them:

* ``navgym export AGENT_DIR OUT`` writes SB3's own ``OUT/model.zip`` (``PPO.load``) and, when
  the agent normalizes, ``OUT/vecnormalize.pkl`` (``VecNormalize.load(path, venv)``). A
  frame-stacked agent's model takes ``VecFrameStack(VecNormalize(env), n)`` observations, as
  in training (the command says so); a residual agent cannot be exported (its action adds a
  baseline's, which plain SB3 does not know).
* ``navgym import SB3_ZIP [--vecnormalize PKL] --trust --env ID OUT_DIR`` turns an SB3 save
  into an agent folder (``model.zip``, ``vecnormalize.npz``, ``config.yml``, ``meta.json``,
  ``manifest.json``) that ``navgym eval --policies ALGO:OUT_DIR`` loads without ``--trust``.

.. warning::
   ``import`` unpickles the SB3 archive and the ``VecNormalize`` pickle once (SB3's own
   loader), which can run arbitrary code: ``--trust`` is required and says that you trust the
   files. The folder it writes loads without unpickling afterwards.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.cli_args import add_gym_packages
from agents.training.agent_files import (
    CONFIG_FILE,
    META_FILE,
    MODEL_FILE,
    STATS_FILE,
    VECNORMALIZE_FILE,
    AgentLoadError,
)

__all__ = ["export_agent", "import_sb3", "register_export", "register_import"]


def _env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> Any:
    import gymnasium as gym

    import navgym  # noqa: F401  (registers the ids)

    return gym.make(env_id, **dict(env_kwargs or {}))


def export_agent(agent_dir: str | Path, out: str | Path) -> Path:
    """Write SB3's ``model.zip`` (and ``vecnormalize.pkl`` when the agent normalizes) to ``out``.

    Args:
        agent_dir: a navgym agent folder (with its manifest; nothing is unpickled).
        out: output folder (created).

    Returns:
        ``out`` as a path.

    Raises:
        AgentLoadError: the agent does not load, or it is a residual agent.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.training.loading import load_agent
    from agents.training.normalization import restore_vec_normalize

    agent = load_agent(agent_dir)
    if agent.residual is not None:
        raise AgentLoadError(
            f"{agent_dir} is a residual agent (its action adds a {agent.residual.spec.baseline} "
            "baseline's action): plain SB3 cannot express it, so it is not exported"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    agent.model.save(out / MODEL_FILE)
    stats = Path(agent_dir) / STATS_FILE
    if stats.is_file():
        if not agent.env_id:
            raise AgentLoadError(f"{agent_dir} records no env id: cannot build VecNormalize's env")
        env_id, env_kwargs = str(agent.env_id), agent.env_kwargs
        venv = DummyVecEnv([lambda: _env(env_id, env_kwargs)])
        vn = restore_vec_normalize(venv, stats, training=False)
        vn.save(str(out / VECNORMALIZE_FILE))
        venv.close()
    return out


def _activation_name(fn: Any) -> str:
    from agents.training.config import ZOO_ACTIVATIONS

    name = getattr(fn, "__name__", str(fn))
    if name not in ZOO_ACTIVATIONS:
        raise AgentLoadError(
            f"activation_fn {name} is not one navgym records ({sorted(ZOO_ACTIVATIONS)}): evaluate "
            "the model with 'navgym eval --policies ALGO:PATH --trust' instead"
        )
    return ZOO_ACTIVATIONS[name]


def _policy_entry(model: Any, cls: Any) -> dict[str, Any]:
    """``policy`` and ``policy_kwargs`` of a loaded SB3 model in navgym's configuration form."""
    names = [k for k, v in cls.policy_aliases.items() if v is model.policy_class]
    if not names:
        raise AgentLoadError(
            f"the model's policy {model.policy_class.__name__} is not one of {cls.__name__}'s "
            f"{sorted(cls.policy_aliases)}"
        )
    entry: dict[str, Any] = {"policy": names[0]}
    pk = {k: v for k, v in (model.policy_kwargs or {}).items() if k != "device"}
    if "activation_fn" in pk:
        pk["activation_fn"] = _activation_name(pk["activation_fn"])
    try:
        yaml.safe_dump(pk)
    except yaml.YAMLError:
        raise AgentLoadError(
            f"policy_kwargs {pk} hold values that a YAML configuration cannot record: evaluate the "
            "model with 'navgym eval --policies ALGO:PATH --trust' instead"
        ) from None
    if pk:
        entry["policy_kwargs"] = pk
    return entry


def import_sb3(
    model_zip: str | Path,
    env_id: str,
    out: str | Path,
    *,
    vecnormalize: str | Path | None = None,
    algo: str | None = None,
    trust: bool = False,
) -> Path:
    """Turn a plain SB3 save into a navgym agent folder; return the folder.

    The archive (and ``vecnormalize``) are unpickled once by SB3's loader, so ``trust`` must be
    true; the folder written loads afterwards without unpickling
    (:func:`agents.training.loading.load_agent`), checked here against ``env_id``'s spaces and
    against the trusted model's actions on a few observations.

    Raises:
        AgentLoadError: without ``trust``; the model's spaces are not ``env_id``'s; its policy
            cannot be recorded in a configuration.
        FileNotFoundError: a file is missing.
        ValueError: ``out`` exists and is not empty.
    """
    from agents.training.config import check_algo
    from agents.training.loading import convert_agent, load_agent
    from agents.training.normalization import VecNormalizeStats
    from agents.training.sb3_archive import algo_class, algo_from_archive
    from agents.training.spaces import check_spaces

    model_zip, out = Path(model_zip), Path(out)
    if not trust:
        raise AgentLoadError(
            f"importing {model_zip} runs SB3's loader, which unpickles the archive (and the "
            "VecNormalize pickle) and can run arbitrary code: pass --trust (Python: trust=True) only "
            "if you trust the files"
        )
    for p in (model_zip, *([Path(vecnormalize)] if vecnormalize is not None else [])):
        if not p.is_file():
            raise FileNotFoundError(f"no such file: {p}")
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"{out} exists and is not empty: import writes a new agent folder")
    algo = check_algo(algo or algo_from_archive(model_zip) or "ppo")
    cls = algo_class(algo)
    model = cls.load(model_zip, device="cpu")
    env = _env(env_id)
    check_spaces(model.observation_space, model.action_space, env, f"the model {model_zip}")
    norm = VecNormalizeStats.load(vecnormalize, trust=True) if vecnormalize is not None else None
    entry: dict[str, Any] = {"env_id": env_id, "algo": algo, **_policy_entry(model, cls)}
    entry["normalize"] = {"norm_obs": norm is not None, "norm_reward": False} if vecnormalize else False
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(model_zip, out / MODEL_FILE)
    if vecnormalize is not None:
        shutil.copyfile(vecnormalize, out / VECNORMALIZE_FILE)
    (out / CONFIG_FILE).write_text(yaml.safe_dump(entry, sort_keys=False))
    meta = {"command": "navgym import", "imported_from": str(model_zip), "vecnormalize": vecnormalize}
    (out / META_FILE).write_text(json.dumps(meta, indent=2, default=str) + "\n")
    convert_agent(out)
    agent = load_agent(out, env=env)
    obs = np.stack([env.reset(seed=s)[0] for s in range(4)])
    raw = norm(obs) if norm is not None else obs
    want = model.predict(raw, deterministic=True)[0]
    got = agent.predict(obs, deterministic=True)[0]
    env.close()
    if not np.allclose(np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)):
        raise AgentLoadError(f"{out}: the imported agent's actions differ from {model_zip}'s")
    return out


def register_export(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym export AGENT_DIR OUT`` to the ``navgym`` command (:mod:`navgym.cli`)."""
    p = subparsers.add_parser(
        "export", help="write an agent as plain SB3 files (model.zip, vecnormalize.pkl)"
    )
    p.add_argument("agent_dir", help="a navgym agent folder (model.zip, manifest.json, ...)")
    p.add_argument("out", help="output folder for model.zip and vecnormalize.pkl")
    add_gym_packages(p)
    p.set_defaults(_run=_run_export)


def _run_export(args: argparse.Namespace) -> int:
    from agents.cli_errors import report_errors

    def go(a: argparse.Namespace) -> int:
        out = export_agent(a.agent_dir, a.out)
        from agents.training.loading import load_agent

        agent = load_agent(a.agent_dir)
        print(
            f"wrote {out / MODEL_FILE}"
            + (f" and {out / VECNORMALIZE_FILE}" if (out / VECNORMALIZE_FILE).is_file() else "")
        )
        print(f"load with {str(agent.algo).upper()}.load(...) and VecNormalize.load(path, venv)")
        if agent.frame_stack > 1:
            print(f"the model takes VecFrameStack(VecNormalize(env), {agent.frame_stack}) observations")
        return 0

    return report_errors("navgym export", go, args)


def register_import(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym import SB3_ZIP --trust --env ID OUT_DIR`` to the ``navgym`` command."""
    p = subparsers.add_parser("import", help="turn a plain SB3 save into a navgym agent folder")
    p.add_argument("model_zip", help="an SB3 model archive (model.save's .zip)")
    p.add_argument("out_dir", help="the agent folder to write (new or empty)")
    p.add_argument("--env", required=True, help="the env id the model acts in")
    add_gym_packages(p)
    p.add_argument("--vecnormalize", default=None, metavar="PKL", help="SB3's vecnormalize.pkl")
    p.add_argument("--algo", default=None, help="SB3 algorithm (default: read from the archive)")
    p.add_argument(
        "--trust",
        action="store_true",
        help="required: SB3's loader unpickles the files once, which can run arbitrary code",
    )
    p.set_defaults(_run=_run_import)


def _run_import(args: argparse.Namespace) -> int:
    from agents.cli_errors import report_errors

    def go(a: argparse.Namespace) -> int:
        out = import_sb3(
            a.model_zip, a.env, a.out_dir, vecnormalize=a.vecnormalize, algo=a.algo, trust=a.trust
        )
        print(f"wrote the agent {out}; evaluate it with navgym eval --env {a.env} --policies ppo:{out}")
        return 0

    return report_errors("navgym import", go, args)
