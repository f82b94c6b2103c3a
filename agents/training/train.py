"""Train SB3 agents on navgym's native vector environments from YAML configurations.

:func:`train` builds ``NavSB3VecEnv`` (the batched core, no per-env Python loop) wrapped in
``VecMonitor`` (episode statistics) and, when the configuration asks for them, ``VecNormalize``
and, outside it, ``VecFrameStack`` (``frame_stack``, rl-zoo3's order); a ``residual`` entry puts
:class:`agents.training.residual.ResidualVecEnv` innermost, next to the env (the baseline reads
raw observations);
it logs to TensorBoard, checkpoints periodically, resumes from the newest valid checkpoint, and
writes to its output folder (the saved-agent layout of :mod:`agents.training.agent_files`)::

    model.zip         the final model (SB3 archive)
    vecnormalize.npz  normalization statistics as plain arrays (only when ``normalize`` is on)
    config.yml        the configuration entry used, with env id, algo, seeds
    meta.json         command, seeds, timesteps, wall time, versions, git commit
    manifest.json     SHA-256 of the four files above, spaces, timesteps (written last)
    checkpoints/      step_<n>/: model.zip, vecnormalize.npz, config.yml, progress.json (step
                      count, wall time), replay_buffer.npz (if asked) and manifest.json; the
                      newest ``keep_checkpoints`` kept
    tb/               TensorBoard logs

A checkpoint is one unit: it is written into a temporary folder and ``os.replace``-d into
place, so an interrupted save leaves no half checkpoint (model without statistics). Resume
takes the newest checkpoint whose manifest hashes check out (an older one, with a warning, when
the newest is damaged), or the final agent when it is newer; ``resume`` of a run that already
has the timesteps asked for does nothing. Nothing is unpickled on resume.

Seeds: ``seed`` fixes torch, NumPy and the algorithm; the environment's sub-env i starts from
train seed ``seed * 1000 + i`` (:func:`agents.seeds.seeds` ``"train"`` range), so training never
sees a tuning or evaluation episode. A resumed run reseeds its environments with train seeds
derived from ``(seed, timesteps done)``: it does not replay the episodes it already saw.
"""

from __future__ import annotations

import dataclasses
import json
import os
import platform
import re
import shlex
import shutil
import sys
import time
import warnings
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.reporting import git_commit
from agents.seeds import TUNE_START, check_seeds, seeds
from agents.training.agent_files import (
    CONFIG_FILE,
    MANIFEST_FILE,
    META_FILE,
    MODEL_FILE,
    STATS_FILE,
    VECNORMALIZE_FILE,
    AgentLoadError,
    run_info,
    write_json_atomic,
)
from agents.training.config import (
    DEFAULT_EVAL_EPISODES,
    build_hyperparameters,
    check_algo,
    check_algo_entry,
    default_policy,
    frame_stack_of,
    load_config,
    normalize_options,
    read_config_file,
    split_entry,
)
from agents.training.manifest import read_manifest, verify_manifest, write_manifest
from agents.training.normalization import expects_normalized_obs, restore_vec_normalize, save_normalization
from agents.training.sb3_archive import algo_class, load_sb3_model, lstm_sizes

#: Train-seed stride between training seeds (sub-env i of seed s starts at s * stride + i).
ENV_SEED_STRIDE = 1000
#: Environment steps between checkpoints when the configuration does not say.
DEFAULT_CHECKPOINT_FREQ = 100_000
#: Checkpoint folders are ``checkpoints/step_<timesteps>``.
CHECKPOINT_PREFIX = "step_"
PROGRESS_FILE = "progress.json"
REPLAY_FILE = "replay_buffer.npz"


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
    frame_stack: int = 1,
    residual: Any = None,
):
    """``VecFrameStack?(VecNormalize?(VecMonitor(ResidualVecEnv?(NavSB3VecEnv(env_id, n_envs, seed)))))``.

    ``normalize`` holds ``VecNormalize`` options (``None``: no normalization); with
    ``normalize_path`` (a ``vecnormalize.npz`` of plain arrays) the saved statistics are loaded
    instead of starting fresh. ``frame_stack`` > 1 stacks that many observations outside the
    normalization (rl-zoo3's order: the statistics are those of one observation). ``residual``
    (a resolved :class:`~agents.training.residual.ResidualSpec`) wraps the env innermost in
    :class:`~agents.training.residual.ResidualVecEnv`: the agent's actions are residuals on the
    baseline's, and with ``observe_base`` its observations (normalized and stacked ones too)
    carry the base action.
    """
    from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor, VecNormalize

    import navgym  # noqa: F401 - registers the environments
    from navgym.envs.sb3 import NavSB3VecEnv

    venv = NavSB3VecEnv(env_id, num_envs=n_envs, seed=seed, **(env_kwargs or {}))
    if residual is not None:
        from agents.training.residual import ResidualVecEnv

        venv = ResidualVecEnv(venv, residual)
    venv = VecMonitor(venv)
    if normalize_path is not None:
        try:
            if Path(normalize_path).suffix != ".npz":
                raise AgentLoadError(
                    f"{normalize_path} is not a {STATS_FILE} statistics file (pickled VecNormalize "
                    "files are not loaded: convert them with agents.training.loading.convert_agent)"
                )
            venv = restore_vec_normalize(venv, normalize_path, training=training)
        except Exception:
            venv.close()
            raise
    elif normalize is not None:
        venv = VecNormalize(venv, training=training, **normalize)
    n_stack = frame_stack_of(frame_stack)
    if n_stack > 1:
        venv = VecFrameStack(venv, n_stack)
    return venv


def _manifest_memory(run: _RunSettings, model, venv) -> dict[str, Any]:
    """The manifest's ``frame_stack``, ``env_observation_space``, ``lstm`` and ``residual``."""
    from stable_baselines3.common.vec_env import VecFrameStack

    inner = venv.venv if isinstance(venv, VecFrameStack) else venv
    residual = None
    if run.residual is not None:
        from agents.training.residual import find_residual_env

        res_env = find_residual_env(venv)
        if res_env is None:
            raise RuntimeError("the run has a residual but its env has no ResidualVecEnv")
        residual = res_env.manifest_record()
    return {
        "frame_stack": run.frame_stack,
        "env_observation_space": inner.observation_space if run.frame_stack > 1 else None,
        "lstm": lstm_sizes(model),
        "residual": residual,
    }


def checkpoint_folders(out_dir: str | Path) -> list[tuple[int, Path]]:
    """``(timesteps, folder)`` of the checkpoint folders of a run, newest first (valid or not)."""
    ckdir = Path(out_dir) / "checkpoints"
    if not ckdir.is_dir():
        return []
    found = []
    for p in ckdir.iterdir():
        m = re.fullmatch(rf"{CHECKPOINT_PREFIX}(\d+)", p.name)
        if m and p.is_dir():
            found.append((int(m.group(1)), p))
    return sorted(found, reverse=True)


def checkpoint_problem(folder: str | Path) -> str | None:
    """Why the checkpoint ``folder`` cannot be resumed from (``None``: complete and hash-valid)."""
    folder = Path(folder)
    try:
        manifest = verify_manifest(folder)
        for name in (MODEL_FILE, CONFIG_FILE, PROGRESS_FILE):
            if name not in manifest["files"]:
                return f"{name} is not in its {MANIFEST_FILE}"
        progress = json.loads((folder / PROGRESS_FILE).read_text())
        n = int(progress["num_timesteps"])
        if n != int(manifest.get("num_timesteps", -1)):
            return f"{PROGRESS_FILE} says {n} timesteps, {MANIFEST_FILE} {manifest.get('num_timesteps')}"
        if expects_normalized_obs(run_info(folder)) and STATS_FILE not in manifest["files"]:
            return f"its configuration normalizes observations but it holds no {STATS_FILE}"
    except AgentLoadError as e:
        return str(e)
    except (OSError, ValueError, KeyError, TypeError) as e:
        return f"{type(e).__name__}: {e}"
    return None


def latest_checkpoint(out_dir: str | Path) -> tuple[Path, Path | None, int] | None:
    """``(model zip, statistics npz or None, timesteps)`` of the newest valid checkpoint, or None.

    A checkpoint whose files are missing or do not match its manifest is skipped with a
    warning (the next older one is tried).
    """
    for n, folder in checkpoint_folders(out_dir):
        problem = checkpoint_problem(folder)
        if problem is None:
            stats = folder / STATS_FILE
            return folder / MODEL_FILE, stats if stats.is_file() else None, n
        warnings.warn(
            f"skipping checkpoint {folder} (incomplete or damaged: {problem}); trying an older one",
            stacklevel=2,
        )
    return None


@dataclass(frozen=True)
class _ResumePoint:
    """What a resumed run starts from: a checkpoint folder or the run's final agent."""

    folder: Path
    timesteps: int
    wall_time_s: float
    is_checkpoint: bool

    @property
    def model(self) -> Path:
        return self.folder / MODEL_FILE

    @property
    def stats(self) -> Path | None:
        p = self.folder / STATS_FILE
        return p if p.is_file() else None


def _final_timesteps(out: Path, warn: bool = False) -> int | None:
    """Timesteps of the run's final agent when its manifest checks out (else ``None``)."""
    try:
        manifest = read_manifest(out)
        if manifest is None or MODEL_FILE not in manifest["files"]:
            return None
        verify_manifest(out, manifest)
        return int(manifest["num_timesteps"])
    except (AgentLoadError, KeyError, TypeError, ValueError) as e:
        if warn:
            warnings.warn(
                f"the final agent in {out} is not usable ({e}); resuming from checkpoints", stacklevel=3
            )
        return None


def _resume_point(out: Path) -> _ResumePoint | None:
    """The newest valid checkpoint, or the final agent when newer; ``None``: start afresh.

    Raises:
        AgentLoadError: checkpoints exist but none is valid, and there is no final agent (a
            fresh start would silently discard them).
    """
    ck = latest_checkpoint(out)
    final = _final_timesteps(out, warn=True)
    if final is not None and (ck is None or final > ck[2]):
        meta = json.loads((out / META_FILE).read_text())
        return _ResumePoint(out, final, float(meta.get("wall_time_s", 0.0)), False)
    if ck is not None:
        progress = json.loads((ck[0].parent / PROGRESS_FILE).read_text())
        return _ResumePoint(ck[0].parent, ck[2], float(progress.get("wall_time_s", 0.0)), True)
    ckdir = out / "checkpoints"
    broken = [str(f) for _, f in checkpoint_folders(out)]
    legacy = sorted(str(p) for p in ckdir.glob("model_*_steps.zip")) if ckdir.is_dir() else []
    if broken or legacy:
        what = f"damaged checkpoints {broken}" if broken else f"checkpoints of an older format {legacy}"
        raise AgentLoadError(
            f"cannot resume from checkpoints in {out}: it has {what} and no valid one (an older "
            "navgym's pickled checkpoints are not loaded); start without --resume or with another --out"
        )
    return None


def save_checkpoint(
    ckdir: Path, model, vec_normalize, run: _RunSettings, wall_time_s: float, replay: bool
) -> Path:
    """Write the checkpoint of ``model`` as one unit: ``ckdir/step_<n>`` appears complete or not at all.

    Model, statistics, configuration, step count (``progress.json``), optional replay buffer and
    the manifest are written into a temporary folder, which is then ``os.replace``-d into place.
    """
    n = int(model.num_timesteps)
    final = ckdir / f"{CHECKPOINT_PREFIX}{n}"
    tmp = ckdir / f".{final.name}.{os.getpid()}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    files = [MODEL_FILE, CONFIG_FILE, PROGRESS_FILE]
    model.save(tmp / MODEL_FILE)
    if vec_normalize is not None:
        save_normalization(vec_normalize, tmp / STATS_FILE)
        files.append(STATS_FILE)
    buffer = replay_buffer_of(model) if replay else None
    if buffer is not None:
        save_replay_buffer(buffer, tmp / REPLAY_FILE)
        files.append(REPLAY_FILE)
    shutil.copy2(run.out / CONFIG_FILE, tmp / CONFIG_FILE)
    write_json_atomic(tmp / PROGRESS_FILE, {"num_timesteps": n, "wall_time_s": wall_time_s})
    write_manifest(
        tmp,
        files,
        algo=run.algo,
        env_id=run.env_id,
        num_timesteps=n,
        observation_space=model.observation_space,
        action_space=model.action_space,
        **_manifest_memory(run, model, model.get_env()),
    )
    if final.exists():  # the same step saved again (a resumed run): swap, then drop the old one
        old = ckdir / f".{final.name}.{os.getpid()}.old"
        shutil.rmtree(old, ignore_errors=True)
        os.replace(final, old)
        os.replace(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, final)
    return final


#: Array attributes of an SB3 replay buffer saved in ``replay_buffer.npz``.
_REPLAY_ARRAYS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")


def replay_buffer_of(model: Any) -> Any:
    """The replay buffer of an off-policy model (SAC, DQN, ...); ``None`` for PPO / A2C or none yet."""
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    return model.replay_buffer if isinstance(model, OffPolicyAlgorithm) else None


def save_replay_buffer(buffer, path: Path) -> None:
    """An SB3 ``ReplayBuffer``'s arrays and position as a ``.npz`` (no pickle)."""
    arrays = {k: v for k in _REPLAY_ARRAYS if isinstance(v := getattr(buffer, k, None), np.ndarray)}
    with path.open("wb") as f:
        np.savez(f, pos=np.asarray(buffer.pos), full=np.asarray(bool(buffer.full)), **arrays)


def load_replay_buffer(buffer, path: Path) -> bool:
    """Fill ``buffer`` from :func:`save_replay_buffer`'s file; ``False`` (unchanged) if shapes differ."""
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    for k in _REPLAY_ARRAYS:
        mine = getattr(buffer, k, None)
        if isinstance(mine, np.ndarray) and (k not in data or data[k].shape != mine.shape):
            return False
    for k in _REPLAY_ARRAYS:
        if isinstance(getattr(buffer, k, None), np.ndarray):
            setattr(buffer, k, data[k].astype(getattr(buffer, k).dtype, copy=True))
    buffer.pos = int(data["pos"])
    buffer.full = bool(data["full"])
    return True


def _checkpoint_callback(run: _RunSettings, wall0: float):
    """A checkpoint unit every ``run.ck_freq`` environment steps, the newest ``run.keep`` kept."""
    from stable_baselines3.common.callbacks import BaseCallback

    t0 = time.time()
    ckdir = run.out / "checkpoints"

    class _Checkpoint(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.save_freq = max(run.ck_freq // run.n_env, 1)

        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq == 0:
                save_checkpoint(
                    ckdir,
                    self.model,
                    self.model.get_vec_normalize_env(),
                    run,
                    wall0 + time.time() - t0,
                    run.replay,
                )
                _prune_checkpoints(run.out, run.keep)
            return True

    return _Checkpoint()


def _prune_checkpoints(out: Path, keep: int) -> None:
    for _, folder in checkpoint_folders(out)[keep:] if keep > 0 else []:
        shutil.rmtree(folder, ignore_errors=True)


def _remove_stale_temporaries(out: Path) -> None:
    """Temporary folders that an interrupted save left (never complete checkpoints)."""
    for parent in (out, out / "checkpoints"):
        if parent.is_dir():
            for p in [*parent.glob(".*.tmp"), *parent.glob(".*.old")]:
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)


def _write_json(path: Path, data: dict[str, Any]) -> None:
    write_json_atomic(path, data)


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
    for pkg in ("navgym", "numpy", "scipy", "gymnasium", "torch", "stable_baselines3", "sb3_contrib"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


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
    eval_freq: int | None = None,
    eval_episodes: int | None = None,
) -> Path:
    """Train ``algo`` on ``env_id`` and save the agent; return the output folder.

    Args:
        env_id: a registered navgym id (``navgym/GpsInsFading-v0``).
        algo: ``"ppo"`` (any action space), ``"sac"`` (Box), ``"dqn"`` (Discrete), ``"a2c"``,
            ``"ppo_lstm"`` (sb3-contrib's RecurrentPPO, any action space).
        config: ``None`` (the entry of ``env_id`` in ``agents/configs/<algo>.yml``), a YAML
            file keyed by env id (or holding one bare entry), or an entry as a dict.
        seed: training seed (torch, NumPy, algorithm; environment train seeds from it).
        total_timesteps: environment steps in all (default: the entry's ``n_timesteps``).
        out_dir: output folder (default ``runs/<env name>/<algo>_seed<seed>``).
        resume: continue from the newest valid checkpoint in ``out_dir`` (model, normalization
            statistics, timestep count; TensorBoard continues its curve), or from the final
            agent when it is newer; the saved ``config.yml`` is used unless ``config`` is given.
            Without a checkpoint it starts afresh; a run that already has ``total_timesteps``
            is left as it is (a message says so).
        progress: show a progress bar.
        n_envs: override the entry's ``n_envs``.
        verbose: SB3 verbosity (0: silent, 1: training tables).
        torch_threads: ``torch.set_num_threads`` (small MLPs: 1 is fastest on a shared CPU);
            ``None`` leaves torch's default.
        tensorboard: write TensorBoard logs to ``out_dir/tb``.
        eval_freq: environment steps between evaluations on tuning seeds, the best model kept
            in ``out_dir/best`` (:mod:`agents.training.callbacks`; default: the entry's
            ``eval_freq``, 0: none).
        eval_episodes: tuning episodes per evaluation (default: the entry's, else 16).

    Returns:
        The output folder, holding ``model.zip``, ``vecnormalize.npz`` (if normalized),
        ``config.yml``, ``meta.json`` and ``manifest.json`` (see the module docstring);
        :func:`load_agent` reads it.
    """
    import torch
    from stable_baselines3.common.utils import set_random_seed

    run = _run_settings(env_id, algo, config, seed, total_timesteps, out_dir, resume, n_envs, torch_threads)
    if eval_freq is not None or eval_episodes is not None:
        run = dataclasses.replace(
            run,
            eval_freq=run.eval_freq if eval_freq is None else _nonnegative_int(eval_freq, "eval_freq"),
            eval_episodes=run.eval_episodes
            if eval_episodes is None
            else _nonnegative_int(eval_episodes, "eval_episodes", 1),
        )
    _check_env_id(env_id)
    run = _resolve_residual(run)
    run = _resolve_row_layout(run)
    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    set_random_seed(run.seed)

    if resume and (done := _finished_timesteps(run.out, run.total)) is not None:
        print(finished_message(run.out, done, run.total))
        return run.out
    _remove_stale_temporaries(run.out)
    ckpt = _resume_point(run.out) if resume else None
    done_before = ckpt.timesteps if ckpt else 0
    if ckpt and run.norm is not None and ckpt.stats is None:
        raise AgentLoadError(
            f"cannot resume from checkpoint {ckpt.folder}: {ckpt.folder / STATS_FILE} is missing but the "
            "configuration normalizes observations (the statistics would restart from scratch)"
        )
    venv = _build_env(run, done_before, ckpt.stats if ckpt and run.norm else None)
    tb = str(run.out / "tb") if tensorboard else None
    wall0 = ckpt.wall_time_s if ckpt else 0.0
    t0 = time.time()
    model = _build_model(run, venv, ckpt, tb, verbose)
    if tb is None:
        model.set_logger(quiet_logger(run.out, verbose))
    _save_config(run)
    callbacks, use_rich = _callbacks(run, progress, wall0)
    base = _learn(run, model, venv, ckpt, done_before, callbacks, use_rich)
    wall = wall0 + time.time() - t0
    meta = _meta(run, model, ckpt, done_before, base, wall, total_timesteps)
    _save_agent(run, model, venv, meta)
    venv.close()
    return run.out


def _finished_timesteps(out: Path, total: int) -> int | None:
    """Timesteps of the run's valid final agent when it has at least ``total`` (else ``None``)."""
    n = _final_timesteps(out)
    return n if n is not None and n >= total else None


def finished_message(out: str | Path, done: int, total: int) -> str:
    """What ``resume`` of a run that already has the timesteps asked for says."""
    return (
        f"{out}: the run already finished {done:,} timesteps ({total:,} asked for); nothing to do "
        "(ask for more with --timesteps / total_timesteps to train it further)"
    )


def already_finished(
    env_id: str,
    algo: str = "ppo",
    config: str | Path | dict[str, Any] | None = None,
    seed: int = 0,
    total_timesteps: int | None = None,
    out_dir: str | Path | None = None,
) -> tuple[Path, int, int] | None:
    """``(out dir, timesteps done, timesteps asked)`` when resuming would have nothing to do.

    That is when ``train(..., resume=True)`` with these arguments finds a valid final agent with
    at least the timesteps asked for; else ``None``.
    """
    run = _run_settings(env_id, algo, config, seed, total_timesteps, out_dir, True, None, None)
    done = _finished_timesteps(run.out, run.total)
    return (run.out, done, run.total) if done is not None else None


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
    frame_stack: int  # observations stacked per step (1: none)
    residual: Any  # the entry's residual: checked (a dict) or, once resolved, a ResidualSpec; None: none
    ck_freq: int
    keep: int
    replay: bool
    cls: Any  # the SB3 algorithm class
    eval_freq: int = 0  # environment steps between evaluations on tuning seeds (0: none)
    eval_episodes: int = 16  # tuning episodes per evaluation


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
    check_algo_entry(algo, run, hyper)
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
        policy=run.get("policy", default_policy(algo)),
        frame_stack=frame_stack_of(run.get("frame_stack")),
        residual=run.get("residual"),
        ck_freq=int(float(run.get("checkpoint_freq", DEFAULT_CHECKPOINT_FREQ))),
        keep=int(run.get("keep_checkpoints", 2)),
        replay=bool(run.get("save_replay_buffer", False)),
        cls=algo_class(algo),
        eval_freq=_nonnegative_int(run.get("eval_freq", 0), "eval_freq"),
        eval_episodes=_nonnegative_int(run.get("eval_episodes", DEFAULT_EVAL_EPISODES), "eval_episodes", 1),
    )


def _nonnegative_int(value: Any, key: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or int(value) < low:
        raise ValueError(f"{key} must be an integer >= {low}; got {value!r}")
    return int(value)


def _check_env_id(env_id: str) -> None:
    """``ValueError`` naming the registered navgym ids when ``env_id`` is not one of them."""
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the environments

    if env_id not in gym.registry:
        known = sorted(k for k in gym.registry if k.startswith("navgym/"))
        raise ValueError(f"unknown environment id {env_id!r}; registered navgym ids: {known}")


def _resolve_residual(run: _RunSettings) -> _RunSettings:
    """The run with its ``residual`` resolved against the env (baseline, parameters, Box actions)."""
    if run.residual is None:
        return run
    import dataclasses

    from agents.evaluation.runner import make_vector_env
    from agents.training.residual import resolve_residual

    probe = make_vector_env(run.env_id, 1, run.env_kwargs)
    try:
        spec = resolve_residual(run.residual, run.env_id, probe)
    finally:
        probe.close()
    return dataclasses.replace(run, residual=spec)


def _resolve_row_layout(run: _RunSettings) -> _RunSettings:
    """``policy: RowSharedPolicy``: its ``row_columns`` / ``global_columns`` from the env, when not given.

    :func:`agents.training.row_policy.row_layout` of the env's observation features (with a
    residual's appended base action); written into the entry, so ``config.yml`` records them.
    """
    if run.policy != "RowSharedPolicy":
        return run
    pk = dict(run.hyper.get("policy_kwargs") or {})
    if "row_columns" in pk and "global_columns" in pk:
        return run
    from agents.evaluation.runner import make_vector_env
    from agents.training.row_policy import row_layout
    from navgym.envs.base import navigation_env
    from navgym.envs.tasks import RowScaleTask

    probe = make_vector_env(run.env_id, 1, run.env_kwargs)
    try:
        nav = navigation_env(probe)
        if not isinstance(nav.task, RowScaleTask):
            raise ValueError(
                f"policy: RowSharedPolicy needs a per-row task (RowScale); {run.env_id} has {nav.task.name}"
            )
        observe = run.residual is not None and run.residual.observe_base
        layout = row_layout(nav.observation_features, nav.task.m_max, observe_base=observe)
    finally:
        probe.close()
    pk.update(layout)
    hyper = {**run.hyper, "policy_kwargs": pk}
    entry = dict(run.entry)
    nested = entry.get("hyperparameters")
    if isinstance(nested, dict) and "policy_kwargs" in nested:
        entry["hyperparameters"] = {**nested, "policy_kwargs": pk}
    else:
        entry["policy_kwargs"] = pk
    return dataclasses.replace(run, hyper=hyper, entry=entry)


def _build_env(run: _RunSettings, done_before: int, normalize_path: Path | None):
    """Step 2: the training vector env (checkpointed VecNormalize statistics on resume)."""
    venv = make_vec_env(
        run.env_id,
        run.n_env,
        env_base_seed(run.seed, run.n_env, done_before),
        run.env_kwargs,
        normalize=run.norm,
        normalize_path=normalize_path,
        frame_stack=run.frame_stack,
        residual=run.residual,
    )
    if not isinstance(venv.action_space, _ok_spaces(run.algo)):
        venv.close()
        raise ValueError(f"{run.algo.upper()} cannot act in {run.env_id}'s action space {venv.action_space}")
    return venv


def _save_config(run: _RunSettings) -> None:
    """Write ``config.yml``: the entry used, with env id, algo, seed, n_envs and n_timesteps.

    A ``residual`` is written resolved (every parameter of the baseline), so the saved agent and
    a resumed run use the baseline it was trained with even if the tuned file changes.
    """
    run.out.mkdir(parents=True, exist_ok=True)
    record = {
        "env_id": run.env_id,
        "algo": run.algo,
        "seed": run.seed,
        **run.entry,
        "n_envs": run.n_env,
        "n_timesteps": run.total,
    }
    if run.residual is not None:
        record["residual"] = run.residual.config_record()
    tmp = run.out / f".{CONFIG_FILE}.{os.getpid()}.tmp"
    tmp.write_text(yaml.safe_dump(record, sort_keys=False))
    os.replace(tmp, run.out / CONFIG_FILE)


def quiet_logger(folder: Path | str, verbose: int) -> Any:
    """SB3's logger of a run without TensorBoard: the console table when ``verbose``, no files.

    What SB3 configures itself in that case, but in ``folder`` (the run's, which exists): left to
    SB3, every ``learn`` makes an empty ``SB3-<date and time>`` folder in the system's temporary
    directory (``stable_baselines3.common.logger.configure`` with no folder).
    """
    from stable_baselines3.common.logger import configure

    return configure(str(folder), ["stdout"] if verbose >= 1 else [])


def _build_model(run: _RunSettings, venv, ckpt: _ResumePoint | None, tb: str | None, verbose: int):
    """Step 3: the model, loaded from the resume point (and its replay buffer) or built afresh.

    A checkpoint is loaded without unpickling (:func:`agents.training.sb3_archive.load_sb3_model`
    with its own ``config.yml`` and manifest).
    """
    if not ckpt:
        from agents.training.row_policy import POLICIES

        return run.cls(
            POLICIES.get(run.policy, run.policy),
            venv,
            seed=run.seed,
            verbose=verbose,
            tensorboard_log=tb,
            device="cpu",
            **build_hyperparameters(run.hyper),
        )
    try:
        model = load_sb3_model(
            run.cls,
            ckpt.model,
            run_info(ckpt.folder),
            read_manifest(ckpt.folder),
            env=venv,
            device="cpu",
            tensorboard_log=tb,
            verbose=verbose,
        )
    except AgentLoadError as e:
        venv.close()
        what = "checkpoint" if ckpt.is_checkpoint else "the final agent in"
        raise AgentLoadError(f"cannot resume from {what} {ckpt.folder}: {e}") from e
    rb = ckpt.folder / REPLAY_FILE
    buffer = replay_buffer_of(model) if run.replay and rb.is_file() else None
    if buffer is not None:
        if not load_replay_buffer(buffer, rb):
            warnings.warn(f"{rb} does not fit this run's replay buffer; it refills afresh", stacklevel=2)
    model.set_random_seed(run.seed + ckpt.timesteps)
    return model


def _eval_callback(run: _RunSettings, wall0: float):
    """The periodic evaluation on tuning seeds (:class:`agents.training.callbacks.TuneEvalCallback`)."""
    from agents.training.callbacks import TuneEvalCallback

    t0 = time.time()
    first = seeds("tune", run.eval_episodes)[0]

    def make_eval_env():
        return make_vec_env(
            run.env_id,
            run.eval_episodes,
            first,
            run.env_kwargs,
            normalize=run.norm,
            training=False,
            frame_stack=run.frame_stack,
            residual=run.residual,
        )

    def save_best(model, folder: Path) -> Path:
        wall = wall0 + time.time() - t0
        return save_checkpoint(folder, model, model.get_vec_normalize_env(), run, wall, False)

    return TuneEvalCallback(make_eval_env, run.eval_freq, save_best, run.out / "best")


def _callbacks(run: _RunSettings, progress: bool, wall0: float) -> tuple[list[Any], bool]:
    """Step 4: ``(callbacks, use_rich)``: checkpoints, metrics, evaluation, a bar.

    Checkpointing, the navigation metrics, the periodic evaluation on tuning seeds (``eval_freq``
    > 0), and a tqdm bar where rich is missing. No bar when stderr is not a terminal (a log
    file, a pipe, a batch job).
    """
    from agents.training.callbacks import NavMetricsCallback

    callbacks = [_checkpoint_callback(run, wall0), NavMetricsCallback()]
    if run.eval_freq > 0:
        callbacks.append(_eval_callback(run, wall0))
    progress = progress and sys.stderr.isatty()  # no bar flooding a log file or a pipe
    use_rich = progress and _progress_bar_available()
    if progress and not use_rich:
        callbacks.append(_tqdm_callback())
    return callbacks, use_rich


def _learn(
    run: _RunSettings,
    model,
    venv,
    ckpt: _ResumePoint | None,
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


def _save_agent(run: _RunSettings, model, venv, meta: dict[str, Any]) -> None:
    """Step 7: ``model.zip``, ``vecnormalize.npz``, ``meta.json`` and, last, ``manifest.json``.

    The files are written into a temporary folder and moved into place after the old manifest
    is removed; the new manifest comes last, so an interrupted save leaves a folder that does
    not load (no manifest) rather than one whose files do not belong together.
    """
    out = run.out
    tmp = out / f".final.{os.getpid()}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    files = [MODEL_FILE, CONFIG_FILE, META_FILE]
    model.save(tmp / MODEL_FILE)
    if run.norm is not None:
        save_normalization(model.get_vec_normalize_env(), tmp / STATS_FILE)
        files.append(STATS_FILE)
    shutil.copy2(out / CONFIG_FILE, tmp / CONFIG_FILE)
    _write_json(tmp / META_FILE, meta)
    write_manifest(
        tmp,
        files,
        algo=run.algo,
        env_id=run.env_id,
        num_timesteps=model.num_timesteps,
        observation_space=model.observation_space,
        action_space=model.action_space,
        **_manifest_memory(run, model, venv),
    )
    (out / MANIFEST_FILE).unlink(missing_ok=True)
    for name in files:
        os.replace(tmp / name, out / name)
    if run.norm is None:
        (out / STATS_FILE).unlink(missing_ok=True)
    (out / VECNORMALIZE_FILE).unlink(missing_ok=True)  # an older navgym's pickle
    os.replace(tmp / MANIFEST_FILE, out / MANIFEST_FILE)
    tmp.rmdir()


def _meta(
    run: _RunSettings,
    model,
    ckpt: _ResumePoint | None,
    done_before: int,
    base: int,
    wall: float,
    total_timesteps: int | None,
) -> dict[str, Any]:
    """Step 6: the contents of ``meta.json`` (earlier sessions of a resumed run in ``history``)."""
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
        "frame_stack": run.frame_stack,
        "residual": run.residual.record() if run.residual is not None else None,
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
        "ppo_lstm": (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary),
    }[algo]
