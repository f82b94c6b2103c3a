"""Load a trained agent as a policy with SB3's ``predict`` that takes raw observations.

.. warning::
   Model files are zip archives that may contain pickled Python objects, and
   ``vecnormalize.pkl`` is a pickle: loading them can execute arbitrary code. Load agents only
   from trusted sources (this repository's ``agents/zoo`` or your own runs).
"""

from __future__ import annotations

import json
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.training.config import ALGOS

MODEL_FILE = "model.zip"
VECNORMALIZE_FILE = "vecnormalize.pkl"


class AgentLoadError(ValueError):
    """A model or normalization file exists but cannot be read as what it should be."""


def algo_class(algo: str):
    """The stable-baselines3 class of ``algo`` (``"ppo" | "sac" | "dqn" | "a2c"``)."""
    import stable_baselines3 as sb3

    classes = {"ppo": sb3.PPO, "sac": sb3.SAC, "dqn": sb3.DQN, "a2c": sb3.A2C}
    try:
        return classes[algo.lower()]
    except KeyError:
        raise ValueError(f"algo must be one of {list(ALGOS)}; got {algo!r}") from None


def _resolve(path: str | Path) -> tuple[Path, Path | None, Path]:
    """``(model zip, VecNormalize pickle or None, run folder)`` for a run folder or a zip."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no trained agent at {p}: the path does not exist")
    if p.is_dir():
        model = p / MODEL_FILE
        if not model.is_file():
            raise FileNotFoundError(f"no trained agent at {p}: {model} does not exist")
        norm = p / VECNORMALIZE_FILE
        return model, norm if norm.is_file() else None, p
    # A zip: the final model beside vecnormalize.pkl, or a checkpoint model_<n>_steps.zip beside
    # model_vecnormalize_<n>_steps.pkl.
    m = re.fullmatch(r"(.*)_(\d+)_steps\.zip", p.name)
    candidates = [p.with_name(VECNORMALIZE_FILE)]
    if m:
        candidates.insert(0, p.with_name(f"{m.group(1)}_vecnormalize_{m.group(2)}_steps.pkl"))
    norm = next((c for c in candidates if c.is_file()), None)
    run_dir = p.parent.parent if p.parent.name == "checkpoints" else p.parent
    return p, norm, run_dir


def _run_info(run_dir: Path) -> dict[str, Any]:
    info: dict[str, Any] = {}
    cfg = run_dir / "config.yml"
    if cfg.is_file():
        try:
            info.update(yaml.safe_load(cfg.read_text()) or {})
        except yaml.YAMLError:
            pass
    meta = run_dir / "meta.json"
    if meta.is_file():
        try:
            info.setdefault("meta", json.loads(meta.read_text()))
        except json.JSONDecodeError:
            pass
    return info


def _algo_from_zip(model: Path) -> str | None:
    """The algorithm of an SB3 archive from the module of its policy class (no unpickling)."""
    try:
        with zipfile.ZipFile(model) as z:
            data = json.loads(z.read("data"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, OSError) as e:
        raise AgentLoadError(
            f"{model} is not a stable-baselines3 model archive (zip with 'data'): {e}"
        ) from e
    module = str((data.get("policy_class") or {}).get("__module__", ""))
    for algo in ("sac", "dqn", "td3"):
        if f".{algo}." in module:
            return algo if algo in ALGOS else None
    return "ppo" if "common.policies" in module else None


class VecNormalizeStats:
    """Observation normalization of a saved ``VecNormalize``, applied to raw observations."""

    def __init__(self, mean: np.ndarray, var: np.ndarray, epsilon: float, clip_obs: float) -> None:
        self.mean = np.asarray(mean, dtype=np.float64)
        self.var = np.asarray(var, dtype=np.float64)
        self.epsilon = float(epsilon)
        self.clip_obs = float(clip_obs)

    @classmethod
    def load(cls, path: Path) -> VecNormalizeStats | None:
        """Statistics of ``path`` (a pickled ``VecNormalize``); ``None`` when it did not normalize obs."""
        try:
            with path.open("rb") as f:
                vn = pickle.load(f)  # trusted files only (module docstring)
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
        return cls(rms.mean, rms.var, fields.get("epsilon", 1e-8), fields.get("clip_obs", 10.0))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)


class TrainedAgent:
    """A trained SB3 model whose :meth:`predict` takes raw environment observations.

    Attributes:
        model: the stable-baselines3 model (its ``policy`` acts on normalized observations).
        normalizer: the saved observation normalization, or ``None``.
        algo, env_id, env_kwargs: from the run's ``config.yml`` when present.
        path: the model archive.
    """

    def __init__(
        self, model: Any, normalizer: VecNormalizeStats | None, path: Path, info: dict[str, Any]
    ) -> None:
        self.model = model
        self.normalizer = normalizer
        self.path = path
        self.info = info
        self.algo = info.get("algo")
        self.env_id = info.get("env_id")
        self.env_kwargs = dict(info.get("env_kwargs") or {})
        self.observation_space = model.observation_space
        self.action_space = model.action_space

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for raw observation(s) ``(n_obs,)`` or ``(B, n_obs)``; SB3's signature."""
        obs = np.asarray(observation, dtype=np.float32)
        if obs.shape[-1:] != self.observation_space.shape:
            raise ValueError(
                f"observation must have shape {self.observation_space.shape} or (B, "
                f"{self.observation_space.shape[0]}); got {obs.shape}"
            )
        if self.normalizer is not None:
            obs = self.normalizer(obs)
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)

    def __repr__(self) -> str:
        norm = "normalized obs" if self.normalizer is not None else "raw obs"
        return f"TrainedAgent({self.algo}, {self.env_id}, {norm}, {self.path})"


def load_agent(path: str | Path, algo: str | None = None, device: str = "cpu") -> TrainedAgent:
    """Load a trained agent from a run folder (``model.zip`` [+ ``vecnormalize.pkl``]) or a zip.

    The returned :class:`TrainedAgent` has SB3's ``predict(obs, state, episode_start,
    deterministic)`` and normalizes raw observations internally when the run used
    ``VecNormalize``, so evaluators pass the environment's observations unchanged.

    .. warning::
       Model archives and ``vecnormalize.pkl`` can contain pickles, which run code when loaded:
       load only files from trusted sources.

    Args:
        path: a run folder (``train``'s output, a zoo folder) or a model archive (also a
            checkpoint ``checkpoints/model_<n>_steps.zip``, whose statistics are found beside it).
        algo: the SB3 algorithm; default from the run's ``config.yml`` or the archive.
        device: torch device.

    Raises:
        FileNotFoundError: nothing at ``path`` (the message names the path and what is missing).
        AgentLoadError: a file exists but is not a valid model archive or VecNormalize pickle.
    """
    model_path, norm_path, run_dir = _resolve(path)
    info = _run_info(run_dir)
    algo = algo or info.get("algo") or _algo_from_zip(model_path)
    if algo is None:
        raise AgentLoadError(f"cannot tell the algorithm of {model_path}; pass algo=")
    cls = algo_class(algo)
    _algo_from_zip(model_path)  # checks the archive before SB3 sees it (clear message)
    try:
        model = cls.load(model_path, device=device)
    except Exception as e:  # SB3 raises many kinds on a corrupt archive
        raise AgentLoadError(
            f"cannot load {model_path} as a {algo.upper()} model: {type(e).__name__}: {e}"
        ) from e
    normalizer = VecNormalizeStats.load(norm_path) if norm_path is not None else None
    if normalizer is not None and normalizer.mean.shape != model.observation_space.shape:
        raise AgentLoadError(
            f"{norm_path} normalizes observations of shape {normalizer.mean.shape}, the model takes "
            f"{model.observation_space.shape}"
        )
    info.setdefault("algo", algo)
    return TrainedAgent(model, normalizer, model_path, info)
