"""The trained-agent zoo: ``agents/zoo/<env name>/`` holds a trained agent and how it was made.

Each folder has ``model.zip``, ``vecnormalize.npz`` (when the run normalized observations),
``config.yml`` (the entry used, with env id, algo, seed), ``meta.json`` (command, seeds,
timesteps, wall time, versions, git commit), ``manifest.json`` (SHA-256 of those files, the
observation and action spaces) and a ``README.md``. :func:`load_zoo_agent` loads one with
:func:`agents.training.load_agent` (nothing is unpickled) and checks its spaces against the
environment's; :func:`export_run` copies a finished run (without its checkpoints and
TensorBoard logs) into the zoo.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from agents.reporting import REPO_ROOT
from agents.training.agent import TrainedAgent
from agents.training.agent_files import (
    CONFIG_FILE,
    MANIFEST_FILE,
    META_FILE,
    MODEL_FILE,
    STATS_FILE,
    VECNORMALIZE_FILE,
    AgentLoadError,
)
from agents.training.loading import convert_agent, load_agent
from agents.training.manifest import verify_manifest
from agents.training.train import env_name

#: Folder of the shipped agents.
ZOO_DIR = Path(__file__).resolve().parents[1] / "zoo"
ZOO_FILES = (MODEL_FILE, STATS_FILE, CONFIG_FILE, META_FILE, MANIFEST_FILE)


def zoo_path(env_id: str) -> Path:
    """``agents/zoo/<env name>`` of ``env_id`` (e.g. ``agents/zoo/GpsInsFading-v0``)."""
    return ZOO_DIR / env_name(env_id)


def zoo_agents() -> list[str]:
    """Env ids that have a zoo agent."""
    out = []
    for cfg in sorted(ZOO_DIR.glob(f"*/{MODEL_FILE}")):
        meta = cfg.parent / "meta.json"
        if meta.is_file():
            out.append(json.loads(meta.read_text())["env_id"])
    return out


def load_zoo_agent(env_id: str, device: str = "cpu") -> TrainedAgent:
    """The shipped agent of ``env_id`` (``FileNotFoundError`` naming the folder if none).

    Its manifest is checked (``AgentLoadError`` naming a changed file), it must have been
    trained on ``env_id``, and its observation and action spaces must be those of ``env_id``'s
    environment (made once, registered defaults). Nothing is unpickled.
    """
    folder = zoo_path(env_id)
    if not folder.is_dir():
        raise FileNotFoundError(f"no zoo agent for {env_id}: {folder} does not exist")
    agent = load_agent(folder, device=device, env=env_id)
    if agent.env_id != env_id:
        raise AgentLoadError(f"{folder} holds an agent of {agent.env_id!r}, not {env_id!r}")
    return agent


def export_run(run_dir: str | Path, dest: str | Path | None = None) -> Path:
    """Copy a finished run's final files into the zoo (default ``agents/zoo/<env name>``).

    The run's manifest must check out (``AgentLoadError`` naming a changed or missing file).
    """
    run_dir = Path(run_dir)
    verify_manifest(run_dir)
    meta = json.loads((run_dir / META_FILE).read_text())
    dest = Path(dest) if dest is not None else zoo_path(meta["env_id"])
    dest.mkdir(parents=True, exist_ok=True)
    for name in ZOO_FILES:
        src = run_dir / name
        if src.is_file():
            shutil.copy2(src, dest / name)
        elif (dest / name).exists():
            (dest / name).unlink()
    (dest / VECNORMALIZE_FILE).unlink(missing_ok=True)  # an older navgym's pickle
    verify_manifest(dest)
    return dest


def _rel(path: str | Path) -> str:
    p = Path(path).resolve()
    try:
        return p.relative_to(REPO_ROOT).as_posix()
    except ValueError:
        return p.as_posix()


def reference_policies(env_id: str) -> dict[str, Any]:
    """Fixed policies an agent of ``env_id`` is checked against (first: the plain filter).

    Fading / Mixture / NoiseScale: the plain filter (the task's neutral action: -1 for Fading and
    Mixture, one entry per component for vector knobs) and, for one-knob Fading and Mixture, when
    ``agents/baselines/tuned`` has one, the tuned constant knob. Resample: never, always, the
    ESS < N/2 threshold and, when tuned, the tuned ESS threshold.
    """
    import gymnasium as gym

    import navgym  # noqa: F401 - registers the environments
    from agents.baselines import load_tuned
    from agents.baselines.fading import lambda_to_action
    from agents.baselines.mixture import eps_to_action
    from agents.training.sanity import constant_policy, ess_threshold_policy
    from navgym.envs.base import navigation_env

    env = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    nav = navigation_env(env)  # the env's own observation columns and action range
    env.close()
    name = env_name(env_id)
    if "Resample" in name:
        i = nav.observation_features.index("ess_frac").start
        out = {
            "never resample": constant_policy(0),
            "always resample": constant_policy(1),
            "ESS < 0.5 N": ess_threshold_policy(i, 0.5),
        }
        t = float(load_tuned(env_id).get("ess", {}).get("threshold", 0.5))
        if t != 0.5:
            out[f"tuned ESS < {t:g} N"] = ess_threshold_policy(i, t)
        return out
    neutral = np.asarray(nav.task.neutral_action(), dtype=np.float64)  # (1,) or (k,) for vector knobs
    shown = f"{neutral[0]:g}" if neutral.size == 1 else np.array2string(neutral, precision=3)
    out = {f"plain (a = {shown})": constant_policy(neutral)}
    params = load_tuned(env_id).get("constant", {})
    if "lam" in params and "Fading" in name and neutral.shape == (1,):
        a = float(lambda_to_action(float(params["lam"]), nav.task.lambda_max)[0, 0])
        out[f"tuned constant lambda = {params['lam']:g}"] = constant_policy([a])
    elif "eps" in params and "Mixture" in name and neutral.shape == (1,):  # not per row
        a = float(eps_to_action(float(params["eps"]), nav.task.eps_max)[0, 0])
        out[f"tuned constant eps = {params['eps']:g}"] = constant_policy([a])
    return out


def sanity_check(path: str | Path, n_seeds: int = 64) -> dict[str, Any]:
    """The agent at ``path`` against :func:`reference_policies` on ``n_seeds`` tuning seeds.

    The environment is the registered default (the training-only kwargs such as the raised
    divergence penalty are not used), ``eval_info=False``. Not the evaluation: a quick check.
    """
    from agents.seeds import seeds
    from agents.training.sanity import agent_policy, compare, format_table

    agent = load_agent(path)
    policies = reference_policies(agent.env_id)
    policies[f"agent ({agent.algo})"] = agent_policy(agent)
    test_seeds = seeds("tune", n_seeds)
    results = compare(policies, agent.env_id, test_seeds)
    text = (
        f"{n_seeds} tuning seeds ({test_seeds[0]}-{test_seeds[-1]}; `agents.seeds` tune range, never "
        "trained on, not the held-out evaluation seeds), one episode each, registered default "
        "environment; RMSE over the whole horizon with each step's error capped at 2000 m (a "
        "diverged episode counts the cap for its missing steps). Command: "
        f"`python -m agents.training.zoo {_rel(path)} --seeds {n_seeds}`."
    )
    return {"text": text, "table": format_table(results), "results": results}


def _memory_note(dest: Path) -> str:
    """A sentence on the agent's memory (frame stack, LSTM) from its manifest; ``""`` without."""
    manifest = json.loads((dest / MANIFEST_FILE).read_text()) if (dest / MANIFEST_FILE).is_file() else {}
    n, lstm = int(manifest.get("frame_stack", 1)), manifest.get("lstm")
    parts = [f"stacks its last {n} observations" if n > 1 else ""]
    if lstm:
        parts.append(f"carries an LSTM state ({lstm['n_lstm_layers']} x {lstm['lstm_hidden_size']} units)")
    what = " and ".join(p for p in parts if p)
    if not what:
        return ""
    return (
        f" The agent has memory: it {what}, kept in the `state` that `predict` returns; pass it back "
        "each step with `episode_start` True where an episode starts (`agents.policy_runner."
        "PredictRunner` does this; `navgym eval` rolls it out that way)."
    )


def write_readme(dest: str | Path, sanity: dict[str, Any] | None = None, notes: str = "") -> Path:
    """``README.md`` of a zoo folder from its ``meta.json`` and ``config.yml`` (+ a sanity table).

    ``notes`` replaces the README's "Notes" section; when empty, an existing README's notes are
    kept (they are hand-written: training history, failed attempts, reproductions).
    """
    dest = Path(dest)
    old = dest / "README.md"
    if not notes and old.is_file() and "\n## Notes\n" in old.read_text():
        notes = old.read_text().split("\n## Notes\n", 1)[1].strip()
    meta = json.loads((dest / "meta.json").read_text())
    cfg = (dest / "config.yml").read_text()
    args = meta["command"].split(" ", 2)[2]
    run_dir = meta.get("out_dir") or meta["command"].rsplit("--out ", 1)[-1]
    lines = [
        f"# {meta['env_id']} — {meta['algo'].upper()} (seed {meta['seed']})",
        "",
        'Load with `agents.training.load_zoo_agent("' + meta["env_id"] + '")` (or `load_agent` on this '
        "folder); `predict` takes raw observations (the normalization statistics of `vecnormalize.npz` "
        "are applied inside). Loading checks `manifest.json` (SHA-256 of each file, the spaces) and "
        "unpickles nothing." + _memory_note(dest),
        "",
        "## How it was made",
        "",
        f"* command: `{meta['command']}` (the same as `python -m agents.training {args}`), then "
        f"`python -m agents.training.zoo {run_dir} --export` copied the final files here",
        f"* seed {meta['seed']}: torch/NumPy/SB3 seed; environment sub-env i starts from train seed "
        f"{meta['env_base_seed']} + i (`agents.seeds` train range)",
        f"* {meta['total_timesteps']:,} environment steps with {meta['n_envs']} sub-environments, "
        f"wall time {meta['wall_time_s'] / 60:.1f} min ({meta['steps_per_s']:.0f} steps/s, "
        f"{meta['torch_threads']} torch thread, {meta['cpu_count']} shared CPU cores)",
        f"* git commit {meta['git'].get('commit')} (dirty: {meta['git'].get('dirty')}), "
        + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()),
        (
            f"* final training episodes: mean return {meta['final_ep_rew_mean']:.1f} "
            f"(training env kwargs, see below), mean length {meta['final_ep_len_mean']:.0f}"
            if meta.get("final_ep_rew_mean") is not None
            else "* final training episodes: none finished during training"
        ),
    ]
    for h in meta.get("history") or []:
        lines.append(
            f"* earlier session of this run: `{h['command']}` ({h['total_timesteps']:,} steps, "
            f"{h['wall_time_s'] / 60:.1f} min); the command above resumed from its last checkpoint"
        )
    lines += [
        "",
        "## Configuration (`config.yml`)",
        "",
        "```yaml",
        cfg.rstrip(),
        "```",
        "",
    ]
    if sanity:
        lines += [
            "## Quick check (not the evaluation)",
            "",
            sanity["text"].rstrip(),
            "",
            sanity["table"].rstrip(),
            "",
        ]
    if notes:
        lines += ["## Notes", "", notes.rstrip(), ""]
    path = dest / "README.md"
    path.write_text("\n".join(lines))
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.training.zoo RUN_OR_ZOO_DIR [--export] [--seeds N] [--convert]``.

    With ``--export`` the run's final files are copied to ``agents/zoo/<env name>`` first; then
    the quick check runs and the zoo folder's ``README.md`` is written. ``--convert`` only
    converts an older agent folder (:func:`agents.training.loading.convert_agent`).
    """
    import argparse

    parser = argparse.ArgumentParser(prog="python -m agents.training.zoo", description=main.__doc__)
    parser.add_argument("path", help="a finished run folder (with --export) or a zoo folder")
    parser.add_argument("--export", action="store_true", help="copy the run into agents/zoo first")
    parser.add_argument("--seeds", type=int, default=64, help="tuning seeds of the quick check")
    parser.add_argument(
        "--notes", default="", help="text for the README's Notes section (default: keep the existing notes)"
    )
    parser.add_argument(
        "--convert",
        action="store_true",
        help="only convert an agent folder of an older navgym (vecnormalize.pkl, no manifest.json) to "
        "vecnormalize.npz + manifest.json; this unpickles it once: trusted agents only",
    )
    args = parser.parse_args(argv)
    if args.convert:
        print(f"wrote {convert_agent(args.path)}")
        return 0
    dest = export_run(args.path) if args.export else Path(args.path)
    sanity = sanity_check(dest, args.seeds) if args.seeds > 0 else None
    if sanity:
        print(sanity["table"])
    print(f"wrote {write_readme(dest, sanity, args.notes)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
