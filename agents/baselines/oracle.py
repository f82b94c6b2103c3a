"""Truth-reading reference policies ("oracles") that act on copies of the live environment.

**Not baselines.** Both read the truth of the episodes they act in (through the reward, i.e.
the position error), which no real filter can; they are references, kept out of baseline
rankings (``is_baseline = False``, ``uses_truth = True``).

* :class:`HindsightOracle` (the ``oracle`` of evaluations): at the start of the episodes it
  plays every candidate policy to the end on deep copies of the live env, and then follows, per
  episode, the candidate with the highest return. Its return is the per-episode maximum over the
  candidates, so with the tuned baselines among the candidates it is an upper bound on every
  baseline, episode by episode (sub-environments are independent and deterministic).
* :class:`GreedyOracle`: greedy one-step lookahead over a grid of knob values. Kept for study:
  myopic knob choices can be far worse than a fixed knob (a large fading factor lowers the next
  step's error and degrades the velocity and bias estimates that carry the filter through the
  next outage), so it is no upper bound.

:class:`GreedyOracle` reads the truth (through the reward, i.e. the position
error in ``info``) of the episodes it acts in, which no real filter can. It is an optimistic
*reference* ("oracle", an upper-bound-style comparison), kept out of baseline rankings
(``is_baseline = False``, ``uses_truth = True``). It is greedy (one step of lookahead), so it is
not a strict upper bound on what a policy can reach, but on most steps it is far ahead of any
estimator-side policy.

At each step, for each candidate action (a small grid of knob values), it deep-copies the live
environment (filter state, episode data and generators included), steps the copy with that
action for every sub-environment, and picks per sub-environment the action with the highest
one-step reward (accuracy minus costs, divergence penalty included). The live env's generators
are not touched, so the episodes are the same as under any other policy.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.baselines.base import navigation_env
from agents.baselines.fading import lambda_to_action
from agents.baselines.mixture import eps_to_action
from agents.policy_runner import ResettablePolicy
from navgym.envs.base import NavigationAPI, NavVectorEnv

__all__ = ["GreedyOracle", "HindsightOracle", "constant_candidates", "default_candidates"]


def _stepper(env: Any) -> Any:
    """Step function of a copy: native vector envs without autoreset, single envs as usual."""
    nav = navigation_env(env)
    return nav.episode_stepper().step if isinstance(nav, NavVectorEnv) else env.step


def default_candidates(env: NavigationAPI) -> list[np.ndarray]:
    """Candidate actions of :class:`GreedyOracle` per task.

    Fading: lambda in {1, 1.5, 2.5, 5, lambda_max}; Mixture: eps in {0, .05, .15, .3, eps_max};
    Resample: {0, 1}.
    """
    name = env.task.name
    if name == "Fading":
        lm = float(env.task.lambda_max)
        lams = sorted({1.0, min(1.5, lm), min(2.5, lm), min(5.0, lm), lm})
        return [lambda_to_action(np.array([x]), lm)[0] for x in lams]
    if name == "Mixture":
        em = float(env.task.eps_max)
        eps = sorted({0.0, min(0.05, em), min(0.15, em), min(0.3, em), em})
        return [eps_to_action(np.array([x]), em)[0] for x in eps]
    if name == "Resample":
        return [np.array(0, dtype=np.int64), np.array(1, dtype=np.int64)]
    raise ValueError(f"no default oracle candidates for task {name!r}")


class GreedyOracle:
    """Truth-reading greedy one-step lookahead (reference only; see the module docstring).

    Args:
        env: the *live* environment the policy acts in (native vector env or single env); the
            evaluator passes it when it builds the policy from a factory.
        candidates: candidate actions (each of the single action shape); default
            :func:`default_candidates`.
    """

    name = "greedy_oracle"
    is_baseline = False
    uses_truth = True

    def __init__(self, env: Any, candidates: Sequence[np.ndarray] | None = None) -> None:
        self.env = env
        nav = navigation_env(env)
        self.candidates = [np.asarray(c) for c in (candidates or default_candidates(nav))]
        self.discrete = nav.task.name == "Resample"

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "class": f"{type(self).__module__}.{type(self).__qualname__}",
            "params": {"candidates": [c.tolist() for c in self.candidates]},
            "uses_truth": True,
        }

    def reset(self) -> None:
        return None

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """Best one-step action per sub-environment (reads the live env, not ``observation``)."""
        obs = np.asarray(observation)
        single = obs.ndim == 1
        B = 1 if single else obs.shape[0]
        best_r = np.full(B, -np.inf)
        best = None
        for c in self.candidates:
            act = c if single else np.broadcast_to(c, (B, *c.shape)).copy()
            sim = copy.deepcopy(self.env)
            with np.errstate(all="ignore"):
                _, r, *_ = _stepper(sim)(act)
            r = np.nan_to_num(np.atleast_1d(np.asarray(r, dtype=np.float64)), nan=-np.inf)
            better = r > best_r
            best_r = np.where(better, r, best_r)
            cand = np.broadcast_to(c, (B, *c.shape))
            best = cand.copy() if best is None else np.where(better.reshape(B, *([1] * c.ndim)), cand, best)
        assert best is not None
        return (best[0] if single else best), None


def constant_candidates(env: Any) -> dict[str, Any]:
    """Candidate policies of :class:`HindsightOracle`: a grid of constant knobs (and triggers)."""
    from agents.baselines.registry import make_baseline

    name = navigation_env(env).task.name
    if name == "Fading":
        return {
            f"lam={x:g}": make_baseline(env, "constant", lam=x)
            for x in (1.0, 1.05, 1.1, 1.2, 1.5, 2.0, 3.0, 5.0, 10.0)
        }
    if name == "Mixture":
        return {
            f"eps={x:g}": make_baseline(env, "constant", eps=x) for x in (0.0, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5)
        }
    if name == "Resample":
        out = {n: make_baseline(env, n) for n in ("never", "always", "redistribution")}
        out.update(
            {f"ess<{x:g}": make_baseline(env, "ess", threshold=x) for x in (0.05, 0.1, 0.2, 0.3, 0.5, 0.7)}
        )
        return out
    raise ValueError(f"no candidates for task {name!r}")


class HindsightOracle:
    """Per-episode hindsight choice among candidate policies (reference only; module docstring).

    Args:
        env: the *live* native vector env the policy acts in (the evaluator passes it).
        candidates: ``{label: policy}`` (default :func:`constant_candidates`); add the tuned
            baselines to make the oracle an upper bound on each of them.

    The plan is made when every sub-environment starts an episode (first call, or
    ``episode_start`` all True), as in the evaluator's synchronous rollouts; ``choice`` then holds
    the label chosen per episode.
    """

    name = "oracle"
    is_baseline = False
    uses_truth = True

    def __init__(self, env: Any, candidates: dict[str, Any] | None = None) -> None:
        self.env = env
        self.candidates = dict(candidates) if candidates is not None else constant_candidates(env)
        if not self.candidates:
            raise ValueError("need at least one candidate policy")
        self.plan: np.ndarray | None = None
        self.choice: list[str] = []
        self.candidate_returns: np.ndarray | None = None
        self._states: list[Any] = []

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "class": f"{type(self).__module__}.{type(self).__qualname__}",
            "params": {"candidates": list(self.candidates)},
            "uses_truth": True,
        }

    def reset(self) -> None:
        self.plan = None

    def _returns(self, policy: Any, obs: np.ndarray) -> np.ndarray:
        sim = copy.deepcopy(self.env)
        step = _stepper(sim)
        if isinstance(policy, ResettablePolicy):
            policy.reset()
        B = obs.shape[0]
        total = np.zeros(B)
        alive = np.ones(B, dtype=bool)
        state, start = None, np.ones(B, dtype=bool)
        while alive.any():
            a, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
            start = np.zeros(B, dtype=bool)
            with np.errstate(all="ignore"):
                obs, r, term, trunc, _ = step(a)
            total += np.where(alive, np.nan_to_num(np.asarray(r, dtype=np.float64), nan=-1e9), 0.0)
            alive &= ~(np.asarray(term) | np.asarray(trunc))
        return total

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """The chosen candidate's action in each sub-environment."""
        obs = np.asarray(observation)
        if obs.ndim != 2:
            raise ValueError("HindsightOracle acts on a native vector env: observation must be (B, d)")
        B = obs.shape[0]
        starts = np.ones(B, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool)
        if self.plan is None or starts.all():
            R = np.stack([self._returns(p, obs) for p in self.candidates.values()])  # (K, B)
            self.candidate_returns = R
            self.plan = np.argmax(R, axis=0)
            labels = list(self.candidates)
            self.choice = [labels[j] for j in self.plan]
            self._states = [None] * len(self.candidates)
            for p in self.candidates.values():
                if isinstance(p, ResettablePolicy):
                    p.reset()
        actions = []
        for j, p in enumerate(self.candidates.values()):
            a, self._states[j] = p.predict(
                obs, state=self._states[j], episode_start=starts, deterministic=True
            )
            actions.append(np.asarray(a))
        A = np.stack(actions)  # (K, B, ...)
        return A[self.plan, np.arange(B)], None
