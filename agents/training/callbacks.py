"""Training callbacks that log what a navigation run is judged on, and keep the best model.

* :class:`NavMetricsCallback` (always on in :func:`agents.training.train`): from the steps'
  infos, per rollout, the per-episode horizontal RMSE of the episodes that ended
  (``nav/ep_rmse_m``), the share of them that diverged (``nav/divergence_rate``), their count
  (``nav/episodes``) and the statistics of the knob the filter applied over the rollout's steps
  (``nav/knob_mean``, ``nav/knob_std``, ``nav/knob_min``, ``nav/knob_max``), to SB3's logger
  (TensorBoard under ``tb/``, the console with ``verbose=1``).
* :class:`TuneEvalCallback` (``eval_freq`` > 0 in the entry, or ``navgym train --eval-freq N``):
  every ``eval_freq`` environment steps, ``eval_episodes`` episodes on **tuning** seeds
  (``agents.seeds.seeds("tune", n)``; never the held-out evaluation seeds), at the start of a
  fresh run too (the initial policy is a candidate: a warm start is kept when training never
  beats it), deterministic
  actions, observations normalized with the training statistics of that moment; logs
  ``eval/tune_return``, ``eval/tune_rmse_m``, ``eval/tune_divergence_rate`` and keeps the model
  of the best mean return in ``OUT/best/step_<n>`` (a checkpoint unit :func:`load_agent
  <agents.training.loading.load_agent>` reads; ``best/best.json`` records its scores).
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from agents.training.config import DEFAULT_EVAL_EPISODES

__all__ = ["DEFAULT_EVAL_EPISODES", "NavMetricsCallback", "TuneEvalCallback", "episode_scores", "kept_model"]


def kept_model(folder: str | Path) -> Path:
    """The model a training run kept on tuning seeds, else ``folder`` itself (its final model).

    The kept one is ``best/<step>``, named by :class:`TuneEvalCallback`'s ``best/best.json``.
    """
    folder = Path(folder)
    record = folder / "best" / "best.json"
    if record.is_file():
        kept = folder / "best" / str(json.loads(record.read_text()).get("folder", ""))
        if (kept / "model.zip").is_file():
            return kept
    return folder


class NavMetricsCallback(BaseCallback):
    """Per-episode RMSE, divergence rate and knob statistics of the training episodes, per rollout."""

    def __init__(self) -> None:
        super().__init__()
        self._sq: np.ndarray | None = None
        self._n: np.ndarray | None = None
        self._rmse: list[float] = []
        self._diverged: list[bool] = []
        self._knobs: list[np.ndarray] = []

    def _on_step(self) -> bool:
        infos = self.locals.get("infos") or []
        dones = np.asarray(self.locals.get("dones", np.zeros(len(infos), dtype=bool)))
        if self._sq is None or self._sq.shape[0] != len(infos):
            self._sq, self._n = np.zeros(len(infos)), np.zeros(len(infos))
        assert self._n is not None
        for i, info in enumerate(infos):
            err = info.get("pos_err_m")
            if err is not None and math.isfinite(float(err)):
                self._sq[i] += float(err) ** 2
                self._n[i] += 1
            knob = info.get("knob")
            if knob is not None:
                self._knobs.append(np.asarray(knob, dtype=np.float64).ravel())
            if bool(dones[i]):
                if self._n[i] > 0:
                    self._rmse.append(float(np.sqrt(self._sq[i] / self._n[i])))
                    self._diverged.append(bool(info.get("diverged", False)))
                self._sq[i] = self._n[i] = 0.0
        return True

    def _on_rollout_end(self) -> None:
        if self._rmse:
            self.logger.record("nav/ep_rmse_m", float(np.mean(self._rmse)))
            self.logger.record("nav/divergence_rate", float(np.mean(self._diverged)))
            self.logger.record("nav/episodes", len(self._rmse))
        if self._knobs:
            k = np.concatenate(self._knobs)
            k = k[np.isfinite(k)]
            if k.size:
                for name, value in (("mean", k.mean()), ("std", k.std()), ("min", k.min()), ("max", k.max())):
                    self.logger.record(f"nav/knob_{name}", float(value))
        self._rmse, self._diverged, self._knobs = [], [], []


def episode_scores(model: Any, venv: Any, deterministic: bool = True) -> dict[str, np.ndarray]:
    """Roll every sub-env of ``venv`` through one episode with ``model``; per-episode scores.

    ``venv`` is an SB3 VecEnv whose sub-env ``i`` plays one episode (its first); returns
    ``{"return", "rmse_m", "diverged"}`` arrays of one value per sub-env.
    """
    n = venv.num_envs
    obs = venv.reset()
    ret, sq, cnt = np.zeros(n), np.zeros(n), np.zeros(n)
    diverged, done = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    state, starts = None, np.ones(n, dtype=bool)
    while not done.all():
        action, state = model.predict(obs, state=state, episode_start=starts, deterministic=deterministic)
        obs, reward, dones, infos = venv.step(action)
        live = ~done
        for i in np.flatnonzero(live):
            info = infos[i]
            ret[i] += float(info["episode"]["r"]) if dones[i] and "episode" in info else 0.0
            err = info.get("pos_err_m")
            if err is not None and math.isfinite(float(err)):
                sq[i] += float(err) ** 2
                cnt[i] += 1
            if dones[i]:
                diverged[i] = bool(info.get("diverged", False))
        done |= np.asarray(dones, dtype=bool)
        starts = np.asarray(dones, dtype=bool)
    rmse = np.where(cnt > 0, np.sqrt(sq / np.maximum(cnt, 1)), np.nan)
    return {"return": ret, "rmse_m": rmse, "diverged": diverged}


class TuneEvalCallback(BaseCallback):
    """Every ``eval_freq`` environment steps, score the policy on tuning seeds; keep the best.

    Args:
        make_eval_env: builds the evaluation VecEnv (one sub-env per tuning episode, the
            training wrappers, a ``VecNormalize`` that does not update its statistics).
        eval_freq: environment steps (all sub-envs together) between evaluations.
        save_best: ``save_best(model, folder)`` writes the model as a checkpoint unit in
            ``folder`` and returns its path.
        best_dir: folder of the best model (``OUT/best``).
    """

    def __init__(
        self,
        make_eval_env: Callable[[], Any],
        eval_freq: int,
        save_best: Callable[[Any, Path], Path],
        best_dir: Path,
    ) -> None:
        super().__init__()
        self.make_eval_env = make_eval_env
        self.eval_freq = int(eval_freq)
        self.save_best = save_best
        self.best_dir = Path(best_dir)
        self.best = -math.inf
        self._next = 0

    def _on_training_start(self) -> None:
        self._next = (self.model.num_timesteps // self.eval_freq + 1) * self.eval_freq
        record = self.best_dir / "best.json"
        if record.is_file():  # a resumed run keeps the best so far
            self.best = float(json.loads(record.read_text()).get("return", -math.inf))
        elif self.model.num_timesteps == 0:
            # The initial policy is a candidate too: a warm start (a residual over a supervised
            # agent) is kept when fine-tuning never beats it on the tuning episodes.
            self.evaluate()

    def _on_step(self) -> bool:
        if self.model.num_timesteps >= self._next:
            self._next += self.eval_freq
            self.evaluate()
        return True

    def evaluate(self) -> dict[str, float]:
        """Score the current policy on the tuning episodes; log it; save it when best."""
        from stable_baselines3.common.vec_env import sync_envs_normalization

        venv = self.make_eval_env()
        try:
            sync_envs_normalization(self.training_env, venv)
            s = episode_scores(self.model, venv)
        finally:
            venv.close()
        out = {
            "return": float(np.mean(s["return"])),
            "rmse_m": float(np.nanmean(s["rmse_m"])) if np.isfinite(s["rmse_m"]).any() else math.nan,
            "divergence_rate": float(np.mean(s["diverged"])),
            "episodes": len(s["return"]),
            "num_timesteps": int(self.model.num_timesteps),
        }
        self.logger.record("eval/tune_return", out["return"])
        self.logger.record("eval/tune_rmse_m", out["rmse_m"])
        self.logger.record("eval/tune_divergence_rate", out["divergence_rate"])
        if out["return"] > self.best:
            self.best = out["return"]
            saved = self.save_best(self.model, self.best_dir)
            for old in self.best_dir.glob("step_*"):
                if old != saved and old.is_dir():
                    shutil.rmtree(old, ignore_errors=True)
            record = {**out, "folder": saved.name}
            (self.best_dir / "best.json").write_text(json.dumps(record, indent=1) + "\n")
        return out
