"""Observation / return normalization statistics of a saved agent, as plain arrays (no pickle).

Training with ``normalize`` wraps the env in SB3's ``VecNormalize``; its statistics are saved as
``vecnormalize.npz`` (:func:`save_normalization`, the keys of :data:`STATS_KEYS`), read back
with ``np.load(allow_pickle=False)`` (:func:`read_normalization`), restored into a
``VecNormalize`` to resume training (:func:`restore_vec_normalize`) or applied to raw
observations by a loaded agent (:class:`VecNormalizeStats`). A pickled ``vecnormalize.pkl`` of
an older agent is read only with ``trust=True``.
"""

from __future__ import annotations

import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.training.agent_files import TRUST_HINT, AgentLoadError
from agents.training.config import normalize_options

if TYPE_CHECKING:
    from stable_baselines3.common.vec_env import VecNormalize

__all__ = [
    "STATS_KEYS",
    "VecNormalizeStats",
    "expects_normalized_obs",
    "normalization_arrays",
    "read_normalization",
    "restore_vec_normalize",
    "save_normalization",
]

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
    check_finite_statistics(path, data)
    return data


def check_finite_statistics(path: str | Path, data: Mapping[str, Any]) -> None:
    """Refuse statistics with NaN or infinite entries, or a negative variance (:class:`AgentLoadError`).

    Normalizing with them would turn every observation into NaN at the first ``predict``; the
    error names the file and the statistic.
    """
    for k, v in data.items():
        a = np.asarray(v)
        if a.dtype.kind in "iuf" and not np.isfinite(a).all():
            raise AgentLoadError(
                f"{path}: the normalization statistic {k} has non-finite entries (NaN or inf)"
            )
    for k in ("var", "ret_var"):
        if k in data and (np.asarray(data[k]) < 0).any():
            raise AgentLoadError(f"{path}: the normalization statistic {k} has negative entries")


def restore_vec_normalize(venv: Any, path: str | Path, training: bool = True) -> VecNormalize:
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
                f"arbitrary code; {TRUST_HINT}"
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
        stats = {"mean": rms.mean, "var": rms.var, "count": rms.count}
        check_finite_statistics(path, {k: np.asarray(v, dtype=np.float64) for k, v in stats.items()})
        return cls(rms.mean, rms.var, fields.get("epsilon", 1e-8), fields.get("clip_obs", 10.0), rms.count)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)


def expects_normalized_obs(info: Mapping[str, Any]) -> bool:
    """Whether a run's configuration (``normalize``) normalized the observations."""
    try:
        opts = normalize_options(info.get("normalize"))
    except ValueError as e:
        raise AgentLoadError(f"invalid 'normalize' in the configuration: {e}") from e
    return bool(opts and opts.get("norm_obs", True))
