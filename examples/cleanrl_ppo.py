"""A minimal CleanRL-style PPO (one file, torch, no SB3) over navgym's native vector env.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")`` gives navgym's
batched core itself (one NumPy/numba step for all N sub-envs, no per-env Python loop). The loop
follows CleanRL's ``ppo_continuous_action.py`` (Huang et al. 2022, JMLR 23(274)): rollouts of
``num_steps`` x ``num_envs``, GAE, clipped surrogate with minibatches, value loss, entropy
bonus, advantage normalization, gradient clipping, linear learning-rate annealing. A Box action
space gets a diagonal Gaussian (state-independent log std), a Discrete one a categorical.

Gymnasium 1.x vector envs autoreset on the step *after* an episode ends (``NEXT_STEP``): that
step ignores the action, returns the new episode's first observation and reward 0. It is no
transition of the task, so it is masked out of the loss; in exchange the ended episode's last
observation is the next row's observation, so a truncated episode bootstraps from its value.

    python examples/cleanrl_ppo.py --env-id navgym/Robot2dFading-v2 --num-envs 16 --total-timesteps 200000
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
from torch.distributions import Categorical, Normal

import navgym  # noqa: F401 - registers the environments


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env-id", default="navgym/Robot2dFading-v2")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--num-envs", type=int, default=16)
    p.add_argument("--num-steps", type=int, default=128, help="steps per sub-env per rollout")
    p.add_argument("--total-timesteps", type=int, default=200_000)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.97)
    p.add_argument("--gae-lambda", type=float, default=0.9)
    p.add_argument("--num-minibatches", type=int, default=4)
    p.add_argument("--update-epochs", type=int, default=5)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--env-kwargs", type=json.loads, default={}, help="env keyword arguments (JSON)")
    return p.parse_args(argv)


class RunningNorm:
    """Running mean / variance of the observations (as gymnasium's NormalizeObservation), clipped."""

    def __init__(self, shape: tuple[int, ...], clip: float = 10.0) -> None:
        self.mean, self.var, self.count, self.clip = np.zeros(shape), np.ones(shape), 1e-4, clip

    def __call__(self, x: np.ndarray, update: bool = True) -> np.ndarray:
        if update:
            m, v, n = x.mean(0), x.var(0), x.shape[0]
            delta, tot = m - self.mean, self.count + n
            self.mean = self.mean + delta * n / tot
            self.var = (self.var * self.count + v * n + delta**2 * self.count * n / tot) / tot
            self.count = tot
        return np.clip((x - self.mean) / np.sqrt(self.var + 1e-8), -self.clip, self.clip).astype(np.float32)


def layer(i: int, o: int, std: float = np.sqrt(2)) -> nn.Linear:
    lin = nn.Linear(i, o)
    nn.init.orthogonal_(lin.weight, std)
    nn.init.constant_(lin.bias, 0.0)
    return lin


class Agent(nn.Module):
    """Separate actor and critic MLPs (64, 64, tanh), as CleanRL's."""

    def __init__(self, obs_dim: int, action_space: gym.Space) -> None:
        super().__init__()
        self.discrete = isinstance(action_space, gym.spaces.Discrete)
        out = int(action_space.n) if self.discrete else int(np.prod(action_space.shape))
        self.critic = nn.Sequential(
            layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, 1, 1.0)
        )
        self.actor = nn.Sequential(
            layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, out, 0.01)
        )
        if not self.discrete:
            self.log_std = nn.Parameter(torch.full((1, out), -1.0))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def act(self, x: torch.Tensor, action: torch.Tensor | None = None):
        """``(action, log prob, entropy, value)``; the given ``action``'s log prob when passed."""
        out = self.actor(x)
        if self.discrete:
            dist = Categorical(logits=out)
            action = dist.sample() if action is None else action
            return action, dist.log_prob(action), dist.entropy(), self.value(x)
        dist = Normal(out, self.log_std.expand_as(out).exp())
        action = dist.sample() if action is None else action
        return action, dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(x)


def main(argv: Sequence[str] | None = None) -> dict[str, float]:
    """Train; return the last rollout's statistics (``episodes``, ``mean_return``, ``sps``, ``steps``)."""
    args = parse_args(argv)
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    envs = gym.make_vec(
        args.env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point", **args.env_kwargs
    )
    space = envs.single_action_space
    obs_dim = int(np.prod(envs.single_observation_space.shape))
    agent = Agent(obs_dim, space)
    optim = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    norm = RunningNorm((obs_dim,))
    N, T = args.num_envs, args.num_steps
    batch = N * T
    iterations = max(1, args.total_timesteps // batch)
    obs_b = torch.zeros((T, N, obs_dim))
    act_b = torch.zeros((T, N) + (() if agent.discrete else space.shape))
    logp_b, rew_b, val_b = torch.zeros((T, N)), torch.zeros((T, N)), torch.zeros((T, N))
    term_b, end_b, valid_b = torch.zeros((T, N)), torch.zeros((T, N)), torch.zeros((T, N))
    raw, _ = envs.reset(seed=args.seed)
    obs = torch.as_tensor(norm(raw.reshape(N, -1)))
    autoreset = np.zeros(N, dtype=bool)  # the next step only resets these sub-envs
    ep_ret, finished = np.zeros(N), []
    stats: dict[str, float] = {}
    t0, steps = time.time(), 0
    for it in range(iterations):
        optim.param_groups[0]["lr"] = args.learning_rate * (1.0 - it / iterations)
        finished.clear()
        for t in range(T):
            obs_b[t], valid_b[t] = obs, torch.as_tensor(~autoreset, dtype=torch.float32)
            with torch.no_grad():
                action, logp, _, value = agent.act(obs)
            act_b[t], logp_b[t], val_b[t] = action, logp, value
            a = action.numpy()
            a = a.astype(space.dtype) if agent.discrete else np.clip(a, space.low, space.high)
            raw, reward, term, trunc, _ = envs.step(a)
            steps += N
            rew_b[t] = torch.as_tensor(reward, dtype=torch.float32)
            term_b[t] = torch.as_tensor(term, dtype=torch.float32)
            end_b[t] = torch.as_tensor(term | trunc, dtype=torch.float32)
            ep_ret += np.where(autoreset, 0.0, reward)
            done = (term | trunc) & ~autoreset
            finished += ep_ret[done].tolist()
            ep_ret[done] = 0.0
            autoreset = term | trunc
            obs = torch.as_tensor(norm(raw.reshape(N, -1), update=not autoreset.all()))
        with torch.no_grad():  # GAE; an episode's last step bootstraps from its final observation
            next_value = agent.value(obs)
            adv = torch.zeros((T, N))
            last = torch.zeros(N)
            for t in reversed(range(T)):
                nv = next_value if t == T - 1 else val_b[t + 1]
                delta = rew_b[t] + args.gamma * nv * (1.0 - term_b[t]) - val_b[t]
                last = (delta + args.gamma * args.gae_lambda * (1.0 - end_b[t]) * last) * valid_b[t]
                adv[t] = last
            ret = adv + val_b
        b_obs, b_act = obs_b.reshape(batch, obs_dim), act_b.reshape((batch,) + act_b.shape[2:])
        b_logp, b_adv, b_ret = logp_b.reshape(-1), adv.reshape(-1), ret.reshape(-1)
        b_valid = valid_b.reshape(-1).bool()
        idx_valid = torch.nonzero(b_valid).squeeze(-1)
        mb = max(1, idx_valid.numel() // args.num_minibatches)
        for _ in range(args.update_epochs):
            perm = idx_valid[torch.randperm(idx_valid.numel())]
            for start in range(0, perm.numel(), mb):
                i = perm[start : start + mb]
                _, newlogp, entropy, newv = agent.act(b_obs[i], b_act[i])
                ratio = (newlogp - b_logp[i]).exp()
                a_mb = (b_adv[i] - b_adv[i].mean()) / (b_adv[i].std() + 1e-8)
                pg = torch.max(
                    -a_mb * ratio, -a_mb * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)
                ).mean()
                v_loss = 0.5 * ((newv - b_ret[i]) ** 2).mean()
                loss = pg - args.ent_coef * entropy.mean() + args.vf_coef * v_loss
                optim.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optim.step()
        sps = steps / (time.time() - t0)
        mean_ret = float(np.mean(finished)) if finished else float("nan")
        stats = {
            "iteration": it + 1,
            "steps": steps,
            "episodes": len(finished),
            "mean_return": mean_ret,
            "sps": sps,
        }
        print(
            f"iter {it + 1}/{iterations}  steps {steps}  episodes {len(finished)}  "
            f"mean return {mean_ret:.1f}  value loss {v_loss.item():.3f}  {sps:.0f} steps/s",
            flush=True,
        )
    envs.close()
    return stats


if __name__ == "__main__":
    main()
