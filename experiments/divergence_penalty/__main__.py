"""``python -m experiments.divergence_penalty [--env navgym/GpsInsFading] [--episodes 256] [--quick]``.

Does ending an episode early pay? The same episodes are played by the plain filter (fading
factor 1 throughout) and by a policy that fades at the maximum from step ``--from-step`` on,
under the v0 reward (a constant divergence penalty) and the v1 reward (the penalty also charges
``reward_clip`` per step not played). Seeds: the tuning range (``agents.seeds``), never the
held-out evaluation seeds.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.reporting import markdown_table, write_csv
from agents.seeds import seeds
from experiments.outputs import write_manifest
from navgym.envs.registration import superseded_ids_quiet

#: Where the study's seeds start inside the tuning range (away from the grid searches' first seeds).
SEED_OFFSET = 100_000


def play(env_id: str, episodes: int, from_step: int | None, seed: int, **env_kwargs) -> dict[str, np.ndarray]:
    """Returns and terminations of ``episodes`` episodes (one native vector env, seeds seed + i).

    ``from_step=None`` plays the plain filter (action -1, fading factor 1); otherwise the
    action is +1 (the largest fading factor) from that step on.
    """
    with superseded_ids_quiet():
        env = gym.make_vec(env_id, num_envs=episodes, **env_kwargs)
    env.reset(seed=seed)
    shape = (episodes, *env.single_action_space.shape)
    ret, done, term = np.zeros(episodes), np.zeros(episodes, bool), np.zeros(episodes, bool)
    t = 0
    while not done.all():
        a = np.full(shape, 1.0 if from_step is not None and t >= from_step else -1.0, np.float32)
        _, r, te, tr, _ = env.step(a)
        ret += np.where(done, 0.0, r)
        term |= te & ~done
        done |= te | tr
        t += 1
    env.close()
    return {"return": ret, "terminated": term}


def _plot(played: dict, from_step: int, path: Path) -> None:
    """Per-episode return of the fading policy against the plain filter's, one panel per version."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(played), figsize=(5 * len(played), 4.2), sharex=True, sharey=True)
    for ax, (env_id, (plain, fade)) in zip(np.atleast_1d(axes), played.items(), strict=True):
        d = fade["terminated"]
        ax.scatter(plain["return"][~d], fade["return"][~d], s=10, label="played to the end")
        ax.scatter(plain["return"][d], fade["return"][d], s=10, c="tab:red", label="diverged")
        lo = min(plain["return"].min(), fade["return"].min())
        ax.plot([lo, 0], [lo, 0], "k--", lw=1)
        ax.set_title(env_id)
        ax.set_xlabel("return, plain filter")
    np.atleast_1d(axes)[0].set_ylabel(f"return, max fading from step {from_step}")
    np.atleast_1d(axes)[0].legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.divergence_penalty", description=__doc__)
    p.add_argument("--env", default="navgym/GpsInsFading", help="id without its version suffix")
    p.add_argument("--episodes", type=int, default=256)
    p.add_argument("--from-step", type=int, default=150)
    p.add_argument("--quick", action="store_true", help="8 episodes of 40 steps, fading from step 20")
    p.add_argument("--out", default="results/divergence_penalty")
    args = p.parse_args(argv)
    episodes, from_step, kw = args.episodes, args.from_step, {}
    if args.quick:
        episodes, from_step, kw = 8, 20, {"episode_steps": 40, "max_episode_steps": 40}
    seed = seeds("tune", episodes, offset=SEED_OFFSET)[0]
    rows, played = [], {}
    for version in ("v0", "v1"):
        env_id = f"{args.env}-{version}"
        plain = play(env_id, episodes, None, seed, **kw)
        fade = play(env_id, episodes, from_step, seed, **kw)
        played[env_id] = (plain, fade)
        for name, r in (("plain filter", plain), (f"max fading from step {from_step}", fade)):
            rows.append(
                {
                    "env": env_id,
                    "policy": name,
                    "mean return": round(float(r["return"].mean()), 1),
                    "terminated %": round(100.0 * float(r["terminated"].mean()), 1),
                    "better than plain %": round(100.0 * float((r["return"] > plain["return"]).mean()), 1),
                }
            )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", rows)
    table = markdown_table(rows)
    (out / "report.md").write_text(
        f"# Divergence penalty: does ending an episode early pay?\n\n{episodes} episodes, tuning seeds "
        f"from {seed}.\n\n{table}\n![returns](returns.png)\n"
    )
    _plot(played, from_step, out / "returns.png")
    write_manifest(
        out, "experiments.divergence_penalty", argv, episodes=episodes, first_seed=seed, from_step=from_step
    )
    print(table)
    print(f"wrote {out}/ (table.csv, report.md, returns.png, manifest.json)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
