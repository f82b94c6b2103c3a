"""Train SB3 agents on navgym's native vector environments from YAML configurations.

:func:`train` builds ``NavSB3VecEnv`` (the batched core, no per-env Python loop) wrapped in
``VecMonitor`` (episode statistics) and, when the configuration asks for it, ``VecNormalize``;
it logs to TensorBoard, checkpoints periodically (model + normalization statistics), resumes
from the latest checkpoint, and writes to its output folder::

    model.zip         the final model (SB3 archive)
    vecnormalize.pkl  VecNormalize statistics (only when ``normalize`` is on)
    config.yml        the configuration entry used, with env id, algo, seeds
    meta.json         command, seeds, timesteps, wall time, versions, git commit
    checkpoints/      model_<n>_steps.zip (+ model_vecnormalize_<n>_steps.pkl), the latest kept
    tb/               TensorBoard logs

Seeds: ``seed`` fixes torch, NumPy and the algorithm; the environment's sub-env i starts from
train seed ``seed * 1000 + i`` (:func:`agents.seeds.seeds` ``"train"`` range), so training never
sees a tuning or evaluation episode. A resumed run reseeds its environments with train seeds
derived from ``(seed, timesteps done)``: it does not replay the episodes it already saw.
"""

from __future__ import annotations

import json
import os
import platform
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.seeds import TUNE_START, check_seeds, seeds
from agents.training.config import (
    build_hyperparameters,
    check_algo,
    load_config,
    normalize_options,
    read_config_file,
    split_entry,
)
from agents.training.loading import MODEL_FILE, VECNORMALIZE_FILE, AgentLoadError, algo_class

#: Train-seed stride between training seeds (sub-env i of seed s starts at s * stride + i).
ENV_SEED_STRIDE = 1000
#: Environment steps between checkpoints when the configuration does not say.
DEFAULT_CHECKPOINT_FREQ = 100_000
CHECKPOINT_PREFIX = "model"
PROGRESS_FILE = "progress.json"
REPO_ROOT = Path(__file__).resolve().parents[2]


def env_name(env_id: str) -> str:
    """``navgym/GpsInsFading-v0`` -> ``GpsInsFading-v0`` (zoo folder and run names)."""
    return env_id.split("/")[-1]


def default_out_dir(env_id: str, algo: str, seed: int) -> Path:
    """``runs/<env name>/<algo>_seed<seed>``."""
    return Path("runs") / env_name(env_id) / f"{algo}_seed{seed}"


def env_base_seed(seed: int, n_envs: int, timesteps_done: int = 0) -> int:
    """First train seed of the sub-environments (see the module docstring)."""
    if n_envs > ENV_SEED_STRIDE:
        raise ValueError(f"n_envs must be <= {ENV_SEED_STRIDE}; got {n_envs}")
    if timesteps_done == 0:
        return seeds("train", n_envs, offset=int(seed) * ENV_SEED_STRIDE)[0]
    ss = np.random.SeedSequence([int(seed), int(timesteps_done)])
    base = int(ss.generate_state(1, dtype=np.uint64)[0] % (TUNE_START - n_envs))
    check_seeds("train", [base, base + n_envs - 1])
    return base


def make_vec_env(
    env_id: str,
    n_envs: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    normalize: dict[str, Any] | None = None,
    normalize_path: str | Path | None = None,
    training: bool = True,
):
    """``VecNormalize?(VecMonitor(NavSB3VecEnv(env_id, n_envs, seed)))``.

    ``normalize`` holds ``VecNormalize`` options (``None``: no normalization); with
    ``normalize_path`` the saved statistics are loaded instead of starting fresh.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    import navgym  # noqa: F401 - registers the environments
    from navgym.envs.sb3 import NavSB3VecEnv

    venv = VecMonitor(NavSB3VecEnv(env_id, num_envs=n_envs, seed=seed, **(env_kwargs or {})))
    if normalize_path is not None:
        try:
            venv = VecNormalize.load(str(normalize_path), venv)
        except Exception as e:  # a corrupt or foreign pickle
            venv.close()
            raise AgentLoadError(
                f"cannot load VecNormalize statistics {normalize_path}: {type(e).__name__}: {e}"
            ) from e
        venv.training = training
    elif normalize is not None:
        venv = VecNormalize(venv, training=training, **normalize)
    return venv


def latest_checkpoint(out_dir: str | Path) -> tuple[Path, Path | None, int] | None:
    """``(model zip, VecNormalize pickle or None, timesteps)`` of the newest checkpoint, or None."""
    ckdir = Path(out_dir) / "checkpoints"
    if not ckdir.is_dir():
        return None
    found = []
    for p in ckdir.glob(f"{CHECKPOINT_PREFIX}_*_steps.zip"):
        m = re.fullmatch(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip", p.name)
        if m:
            found.append((int(m.group(1)), p))
    if not found:
        return None
    n, model = max(found)
    norm = ckdir / f"{CHECKPOINT_PREFIX}_vecnormalize_{n}_steps.pkl"
    return model, norm if norm.is_file() else None, n


def _checkpoint_callback(
    out_dir: Path, save_freq_steps: int, n_envs: int, keep: int, replay: bool, wall0: float
):
    """SB3's checkpoints every ``save_freq_steps``, the newest ``keep`` kept, wall time recorded."""
    from stable_baselines3.common.callbacks import CheckpointCallback

    t0 = time.time()

    class _Checkpoint(CheckpointCallback):
        def _on_step(self) -> bool:
            saved = self.n_calls % self.save_freq == 0
            ok = super()._on_step()
            if saved:
                progress = {"num_timesteps": int(self.num_timesteps), "wall_time_s": wall0 + time.time() - t0}
                _write_json(Path(self.save_path) / PROGRESS_FILE, progress)
                _prune_checkpoints(Path(self.save_path), keep)
            return ok

    return _Checkpoint(
        save_freq=max(save_freq_steps // n_envs, 1),
        save_path=str(out_dir / "checkpoints"),
        name_prefix=CHECKPOINT_PREFIX,
        save_replay_buffer=replay,
        save_vecnormalize=True,
    )


def _prune_checkpoints(ckdir: Path, keep: int) -> None:
    steps = sorted(
        {int(m.group(1)) for p in ckdir.iterdir() if (m := re.search(r"_(\d+)_steps\.(zip|pkl)$", p.name))}
    )
    for n in steps[:-keep] if keep > 0 else []:
        for p in ckdir.glob(f"*_{n}_steps.*"):
            p.unlink(missing_ok=True)


def _wall_at_checkpoint(out_dir: Path, timesteps: int) -> float:
    """Wall time spent up to the checkpoint at ``timesteps`` (0 if not recorded)."""
    p = out_dir / "checkpoints" / PROGRESS_FILE
    if p.is_file():
        data = json.loads(p.read_text())
        if int(data.get("num_timesteps", -1)) == timesteps:
            return float(data.get("wall_time_s", 0.0))
    return 0.0


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=str) + "\n")
    os.replace(tmp, path)


def _progress_bar_available() -> bool:
    try:
        import rich  # noqa: F401
        import tqdm  # noqa: F401
    except ImportError:
        return False
    return True


def _tqdm_callback():
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class _Tqdm(BaseCallback):
        def _on_training_start(self) -> None:
            total = self.locals["total_timesteps"]
            self.bar = tqdm(total=total, initial=self.model.num_timesteps, unit="step", mininterval=5.0)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return _Tqdm()


def versions() -> dict[str, str]:
    """Versions of Python and the packages that shape a training run."""
    out = {"python": platform.python_version()}
    for pkg in ("navgym", "numpy", "scipy", "gymnasium", "torch", "stable_baselines3"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def git_commit() -> dict[str, Any]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the repository."""
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        return {"commit": sha, "dirty": bool(dirty)}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def train_command(
    env_id: str,
    algo: str,
    seed: int,
    total_timesteps: int | None,
    out_dir: Path,
    config: Any,
    resume: bool = False,
) -> str:
    """The ``navgym train`` command line equivalent to a :func:`train` call."""
    parts = ["navgym", "train", env_id, "--algo", algo, "--seed", str(seed)]
    if total_timesteps is not None:
        parts += ["--timesteps", str(int(total_timesteps))]
    if isinstance(config, (str, Path)):
        parts += ["--config", str(config)]
    parts += ["--out", str(out_dir)]
    if resume:
        parts.append("--resume")
    return shlex.join(parts)


def resolve_config(env_id: str, algo: str, config: Any) -> dict[str, Any]:
    """The configuration entry: from the shipped file (``None``), a YAML file, or a mapping."""
    if config is None:
        return load_config(env_id, algo)
    if isinstance(config, (str, Path)):
        data = read_config_file(config)
        if env_id in data:
            return load_config(env_id, algo, config)
        # A file holding one bare entry (e.g. a zoo agent's config.yml) is accepted as well.
        if "policy" in data or "n_timesteps" in data:
            entry = dict(data)
            for k in ("env_id", "algo", "seed", "env_seed"):
                entry.pop(k, None)
            return entry
        return load_config(env_id, algo, config)  # raises UnknownEnvError naming env_id
    if isinstance(config, dict):
        return dict(config)
    raise TypeError(f"config must be None, a path or a dict; got {type(config).__name__}")


def train(
    env_id: str,
    algo: str = "ppo",
    config: str | Path | dict[str, Any] | None = None,
    seed: int = 0,
    total_timesteps: int | None = None,
    out_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
    n_envs: int | None = None,
    verbose: int = 0,
    torch_threads: int | None = 1,
    tensorboard: bool = True,
) -> Path:
    """Train ``algo`` on ``env_id`` and save the agent; return the output folder.

    Args:
        env_id: a registered navgym id (``navgym/GpsInsFading-v0``).
        algo: ``"ppo"`` (any action space), ``"sac"`` (Box), ``"dqn"`` (Discrete), ``"a2c"``.
        config: ``None`` (the entry of ``env_id`` in ``agents/configs/<algo>.yml``), a YAML
            file keyed by env id (or holding one bare entry), or an entry as a dict.
        seed: training seed (torch, NumPy, algorithm; environment train seeds from it).
        total_timesteps: environment steps in all (default: the entry's ``n_timesteps``).
        out_dir: output folder (default ``runs/<env name>/<algo>_seed<seed>``).
        resume: continue from the newest checkpoint in ``out_dir`` (model, VecNormalize
            statistics, timestep count; TensorBoard continues its curve); the saved
            ``config.yml`` is used unless ``config`` is given. Without a checkpoint it starts
            afresh.
        progress: show a progress bar.
        n_envs: override the entry's ``n_envs``.
        verbose: SB3 verbosity (0: silent, 1: training tables).
        torch_threads: ``torch.set_num_threads`` (small MLPs: 1 is fastest on a shared CPU);
            ``None`` leaves torch's default.
        tensorboard: write TensorBoard logs to ``out_dir/tb``.

    Returns:
        The output folder, holding ``model.zip``, ``vecnormalize.pkl`` (if normalized),
        ``config.yml`` and ``meta.json`` (see the module docstring); :func:`load_agent` reads it.
    """
    import torch
    from stable_baselines3.common.utils import set_random_seed

    run = _run_settings(env_id, algo, config, seed, total_timesteps, out_dir, resume, n_envs, torch_threads)
    _check_env_id(env_id)
    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    set_random_seed(run.seed)

    ckpt = latest_checkpoint(run.out) if resume else None
    done_before = ckpt[2] if ckpt else 0
    venv = _build_env(run, done_before, ckpt[1] if ckpt and run.norm else None)
    _save_config(run)
    tb = str(run.out / "tb") if tensorboard else None
    wall0 = _wall_at_checkpoint(run.out, done_before) if ckpt else 0.0
    t0 = time.time()
    model = _build_model(run, venv, ckpt, tb, verbose)
    callbacks, use_rich = _callbacks(run, progress, wall0)
    base = _learn(run, model, venv, ckpt, done_before, callbacks, use_rich)
    wall = wall0 + time.time() - t0
    _save_agent(run, model, venv)
    _write_json(run.out / "meta.json", _meta(run, model, ckpt, done_before, base, wall, total_timesteps))
    venv.close()
    return run.out


@dataclass(frozen=True)
class _RunSettings:
    """What one :func:`train` call runs: the arguments resolved against the configuration entry."""

    env_id: str
    algo: str
    seed: int
    out: Path
    config_arg: Any  # the ``config`` argument as given (recorded in the command line)
    entry: dict[str, Any]  # the configuration entry (saved to config.yml)
    hyper: dict[str, Any]  # the algorithm's hyperparameters
    n_env: int
    total: int
    env_kwargs: dict[str, Any]
    norm: dict[str, Any] | None  # VecNormalize options, None: no normalization
    policy: str
    ck_freq: int
    keep: int
    replay: bool
    cls: Any  # the SB3 algorithm class


def _run_settings(
    env_id: str,
    algo: str,
    config: Any,
    seed: int,
    total_timesteps: int | None,
    out_dir: str | Path | None,
    resume: bool,
    n_envs: int | None,
    torch_threads: int | None,
) -> _RunSettings:
    """Step 1: the configuration entry (the saved one on resume) and the checked run settings."""
    algo = check_algo(algo)
    seed = int(seed)
    out = Path(out_dir) if out_dir is not None else default_out_dir(env_id, algo, seed)
    saved_cfg = out / "config.yml"
    config_arg = config
    if resume and config is None and saved_cfg.is_file():
        config = saved_cfg
    entry = resolve_config(env_id, algo, config)
    run, hyper = split_entry(entry)
    if n_envs is not None:
        run["n_envs"] = int(n_envs)
    n_env = int(run.get("n_envs", 8))
    if n_env < 1:
        raise ValueError(f"n_envs must be >= 1; got {n_env}")
    if torch_threads is not None and int(torch_threads) < 1:
        raise ValueError(f"threads must be >= 1; got {torch_threads}")
    total = int(total_timesteps if total_timesteps is not None else run.get("n_timesteps", 0))
    if total < 1:
        raise ValueError(f"total_timesteps must be >= 1 (or n_timesteps in the config); got {total}")
    norm = normalize_options(run.get("normalize"))
    if norm is not None and norm.get("norm_reward") and "gamma" not in norm:
        norm["gamma"] = float(hyper.get("gamma", 0.99))  # discount of the return it scales by
    return _RunSettings(
        env_id=env_id,
        algo=algo,
        seed=seed,
        out=out,
        config_arg=config_arg,
        entry=entry,
        hyper=hyper,
        n_env=n_env,
        total=total,
        env_kwargs=dict(run.get("env_kwargs") or {}),
        norm=norm,
        policy=run.get("policy", "MlpPolicy"),
        ck_freq=int(float(run.get("checkpoint_freq", DEFAULT_CHECKPOINT_FREQ))),
        keep=int(run.get("keep_checkpoints", 2)),
        replay=bool(run.get("save_replay_buffer", False)),
        cls=algo_class(algo),
    )


def _check_env_id(env_id: str) -> None:
    """``ValueError`` naming the registered navgym ids when ``env_id`` is not one of them."""
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the environments

    if env_id not in gym.registry:
        known = sorted(k for k in gym.registry if k.startswith("navgym/"))
        raise ValueError(f"unknown environment id {env_id!r}; registered navgym ids: {known}")


def _build_env(run: _RunSettings, done_before: int, normalize_path: Path | None):
    """Step 2: the training vector env (checkpointed VecNormalize statistics on resume)."""
    venv = make_vec_env(
        run.env_id,
        run.n_env,
        env_base_seed(run.seed, run.n_env, done_before),
        run.env_kwargs,
        normalize=run.norm,
        normalize_path=normalize_path,
    )
    if not isinstance(venv.action_space, _ok_spaces(run.algo)):
        venv.close()
        raise ValueError(f"{run.algo.upper()} cannot act in {run.env_id}'s action space {venv.action_space}")
    return venv


def _save_config(run: _RunSettings) -> None:
    """Write ``config.yml``: the entry used, with env id, algo, seed, n_envs and n_timesteps."""
    run.out.mkdir(parents=True, exist_ok=True)
    record = {
        "env_id": run.env_id,
        "algo": run.algo,
        "seed": run.seed,
        **run.entry,
        "n_envs": run.n_env,
        "n_timesteps": run.total,
    }
    (run.out / "config.yml").write_text(yaml.safe_dump(record, sort_keys=False))


def _build_model(
    run: _RunSettings, venv, ckpt: tuple[Path, Path | None, int] | None, tb: str | None, verbose: int
):
    """Step 3: the model, loaded from the checkpoint (and its replay buffer) or built afresh."""
    if not ckpt:
        return run.cls(
            run.policy,
            venv,
            seed=run.seed,
            verbose=verbose,
            tensorboard_log=tb,
            device="cpu",
            **build_hyperparameters(run.hyper),
        )
    try:
        model = run.cls.load(ckpt[0], env=venv, device="cpu", tensorboard_log=tb, verbose=verbose)
    except Exception as e:  # SB3 raises many kinds on a corrupt or mismatched archive
        venv.close()
        raise AgentLoadError(
            f"cannot resume from checkpoint {ckpt[0]} as a {run.algo.upper()} model: {type(e).__name__}: {e}"
        ) from e
    done_before = ckpt[2]
    rb = run.out / "checkpoints" / f"{CHECKPOINT_PREFIX}_replay_buffer_{done_before}_steps.pkl"
    if run.replay and rb.is_file() and hasattr(model, "load_replay_buffer"):
        model.load_replay_buffer(rb)
    model.set_random_seed(run.seed + done_before)
    return model


def _callbacks(run: _RunSettings, progress: bool, wall0: float) -> tuple[list[Any], bool]:
    """Step 4: ``(callbacks, use_rich)``: checkpointing, and a tqdm bar where rich is missing."""
    callbacks = [_checkpoint_callback(run.out, run.ck_freq, run.n_env, run.keep, run.replay, wall0)]
    use_rich = progress and _progress_bar_available()
    if progress and not use_rich:
        callbacks.append(_tqdm_callback())
    return callbacks, use_rich


def _learn(
    run: _RunSettings,
    model,
    venv,
    ckpt: tuple[Path, Path | None, int] | None,
    done_before: int,
    callbacks: list[Any],
    use_rich: bool,
) -> int:
    """Step 5: seed the sub-envs, learn the remaining timesteps; return the first sub-env seed."""
    remaining = run.total - model.num_timesteps
    # SB3 reseeds the env with ``seed + i`` whenever a model is built or loaded
    # (BaseAlgorithm.set_random_seed -> VecEnv.seed), which would replace the train seeds and,
    # after ``set_random_seed(seed + done_before)``, could reach the tuning range: seed the
    # sub-envs last, so the reset that starts learning uses the documented train seeds.
    base = env_base_seed(run.seed, run.n_env, done_before)
    venv.seed(base)
    if remaining > 0:
        model.learn(
            total_timesteps=remaining,
            callback=callbacks,
            tb_log_name=run.algo.upper(),
            reset_num_timesteps=not ckpt,
            progress_bar=use_rich,
        )
    return base


def _save_agent(run: _RunSettings, model, venv) -> None:
    """Step 6: ``model.zip`` and ``vecnormalize.pkl`` (a stale one removed without normalization)."""
    model.save(run.out / MODEL_FILE)
    if run.norm is not None:
        venv.save(str(run.out / VECNORMALIZE_FILE))
    else:
        (run.out / VECNORMALIZE_FILE).unlink(missing_ok=True)


def _meta(
    run: _RunSettings,
    model,
    ckpt: tuple[Path, Path | None, int] | None,
    done_before: int,
    base: int,
    wall: float,
    total_timesteps: int | None,
) -> dict[str, Any]:
    """Step 7: the contents of ``meta.json`` (earlier sessions of a resumed run in ``history``)."""
    import torch

    out = run.out
    ep = list(model.ep_info_buffer or [])
    history = []
    if ckpt and (out / "meta.json").is_file():  # an earlier session of this run finished here
        prev = json.loads((out / "meta.json").read_text())
        history = prev.get("history", []) + [
            {k: prev.get(k) for k in ("command", "total_timesteps", "wall_time_s", "finished")}
        ]
    return {
        "command": train_command(
            run.env_id,
            run.algo,
            run.seed,
            total_timesteps,
            out,
            None if isinstance(run.config_arg, dict) else run.config_arg,
            resume=bool(ckpt),
        ),
        "argv": sys.argv,
        "out_dir": str(out),
        "env_id": run.env_id,
        "algo": run.algo,
        "seed": run.seed,
        "env_base_seed": env_base_seed(run.seed, run.n_env, 0),
        "env_seeds_this_session": [base, base + run.n_env - 1],  # first and last sub-env seed
        "n_envs": run.n_env,
        "total_timesteps": int(model.num_timesteps),
        "resumed_from_timesteps": done_before if ckpt else None,
        "wall_time_s": round(wall, 1),
        "steps_per_s": round(model.num_timesteps / max(wall, 1e-9), 1),
        "final_ep_rew_mean": float(np.mean([e["r"] for e in ep])) if ep else None,
        "final_ep_len_mean": float(np.mean([e["l"] for e in ep])) if ep else None,
        "normalize": run.norm,
        "torch_threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "versions": versions(),
        "git": git_commit(),
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "history": history,
    }


def _ok_spaces(algo: str):
    from gymnasium import spaces

    return {
        "ppo": (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary),
        "a2c": (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary),
        "sac": (spaces.Box,),
        "dqn": (spaces.Discrete,),
    }[algo]
