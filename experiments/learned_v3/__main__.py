"""``python -m experiments.learned_v3 {train,evaluate} [--env ID ...] [--quick]``: learned agents on v3.

The v3 RowScale ids passed gate G1 (the regime oracle beats the best tuned classical baseline by
>= 25 %) and G2 (the supervised agent of :mod:`agents.supervised` beats it by >= 10 %). This
study trains reinforcement-learning agents on them and measures them against the same bar.

**Agents** (``agents/configs/ppo.yml``, the v3 entries; training seeds only): PPO with the
per-row shared policy (:class:`agents.training.row_policy.RowSharedPolicy`: one network for
every row's multiplier, a global head for the process-noise scale), warm-started from the
supervised agent as a **residual** (:mod:`agents.training.residual`, ``baseline: supervised``):
``a = clip(a_supervised + 0.5 a_res, -1, 1)``, the residual's head initialized near 0, so the
composite starts as the supervised agent (an exact behaviour clone of it) and RL learns the
correction from the reward. The model kept is the best of the periodic evaluations on 64
**tuning** episodes (the initial policy included: ``TuneEvalCallback``); never the held-out
episodes.

``train``: ``--seeds`` (default 0 1 2) per id, ``--jobs`` runs in parallel (one torch thread
each), each into ``RUNS/<EnvName>/seed_<k>`` (``navgym train ID --seed k --out ...``).

``evaluate``: per id, on ``--episodes`` held-out episodes (evaluation seeds of
:mod:`agents.seeds`), the plain filter, the bar (the best tuned baseline, chosen by its tuning
score: :func:`agents.baselines.registry.best_tuned`), the supervised agent and each seed's
agent, all on the same episodes; then the bar, the supervised agent and the agents on
``--shift-episodes`` episodes of each shift of :mod:`experiments.learned_v2.shifts` (longer,
stronger, more events; the platforms it covers) and of a receiver whose C/N0 report is offset
by -3 and +3 dB (:data:`CN0_SHIFTS`). Numbers:

* per agent seed and for the **mean over seeds** (the per-episode RMSE averaged over the seeds'
  agents): ``ΔRMSE %`` against the bar with its paired 95 % bootstrap CI over episodes
  (:func:`agents.evaluation.comparison.delta_rmse`); the target is ``<= -15 %`` with the CI below 0;
* the spread across seeds: each seed's ``ΔRMSE %`` (min, max);
* the mean agent against the supervised agent (``ΔRMSE %`` and CI; "matches" when the CI's upper
  end is below +2 %, i.e. it is not worse by more than 2 %).

Writes ``OUT/results.json`` (per-episode RMSEs of every policy) and ``OUT/table.md``.

``zoo``: per id, the **median seed by its tuning score** (the mean return on the 64 tuning
episodes of its kept model; never a held-out number) is copied to ``agents/zoo/<EnvName>``
(the kept model's files, the run's ``meta.json``, a ``README.md`` with the command, seed,
configuration, wall time and every seed's tuning score).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from agents.training.callbacks import kept_model
from experiments.learned_v3.policies import plain_and_bar, rmse_of

#: The ids studied: the v3 RowScale ids (G1 and G2 passed; a residual over the supervised agent)
#: and PedestrianNoiseScale-v3 (G1 passed; no supervised agent: a residual over its tuned bar).
DEFAULT_ENVS = (
    "navgym/Robot2dRowScale-v3",
    "navgym/QuadrotorRowScale-v3",
    "navgym/PedestrianRowScale-v3",
    "navgym/GpsInsRowScale-v3",
    "navgym/PedestrianNoiseScale-v3",
)
RUNS = Path("results/learned_v3/runs")
OUT = Path("results/learned_v3")
ZOO = Path("agents/zoo")
#: The files of a kept model that a zoo folder holds (beside the run's ``meta.json``).
ZOO_FILES = ("model.zip", "vecnormalize.npz", "config.yml")
#: The targets of the study: ΔRMSE % against the bar, and the tolerance of "matches".
TARGET_PCT = 15.0
MATCH_PCT = 2.0
EPISODES, SHIFT_EPISODES = 500, 200
QUICK = {"episodes": 8, "shift_episodes": 4, "n_boot": 200, "timesteps": 2048}


def name_of(env_id: str) -> str:
    """``Robot2dRowScale-v3`` of ``navgym/Robot2dRowScale-v3``."""
    return env_id.split("/")[-1]


# ------------------------------------------------------------------------------------- train
def _train_one(job: tuple[str, int, int | None, str, str | None]) -> dict[str, Any]:
    env_id, seed, timesteps, out, config = job
    import torch

    from agents.training import train

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    folder = train(
        env_id,
        "ppo",
        config=config,
        seed=seed,
        total_timesteps=timesteps,
        out_dir=out,
        torch_threads=1,
        progress=False,
    )
    return {"env_id": env_id, "seed": seed, "folder": str(folder), "seconds": time.perf_counter() - t0}


def train_all(
    envs: Sequence[str],
    seeds: Sequence[int],
    runs: Path,
    timesteps: int | None,
    jobs: int,
    config: str | None = None,
) -> list[dict[str, Any]]:
    """Train every ``(id, seed)`` into ``runs/<EnvName>/seed_<k>``, ``jobs`` at a time."""
    work = [(e, int(s), timesteps, str(runs / name_of(e) / f"seed_{s}"), config) for e in envs for s in seeds]
    if jobs <= 1:
        return [_train_one(w) for w in work]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(_train_one, work))


# ---------------------------------------------------------------------------------- evaluate
def seed_dirs(runs: Path, env_id: str) -> list[Path]:
    """The trained seeds of ``env_id`` under ``runs`` (sorted by seed)."""
    base = runs / name_of(env_id)
    dirs = [d for d in base.glob("seed_*") if (d / "model.zip").is_file()]
    return sorted(dirs, key=lambda d: int(d.name.split("_")[1]))


def policies_of(env_id: str, runs: Path) -> tuple[dict[str, Any], str, list[str]]:
    """``({name: env -> policy}, bar name, agent names)`` of ``env_id``."""
    from agents.supervised.files import load_policy
    from agents.training import load_agent

    pol, bar = plain_and_bar(env_id)
    sup = ZOO / f"{name_of(env_id)}-supervised"
    if (sup / "manifest.json").is_file():  # the RowScale ids' warm start (none on a NoiseScale id)
        pol["supervised"] = lambda env: load_policy(sup, env)
    agents = []
    for d in seed_dirs(runs, env_id):
        folder = kept_model(d)
        pol[f"ppo {d.name}"] = lambda env, f=folder: load_agent(f, env=env)
        agents.append(f"ppo {d.name}")
    return pol, bar, agents


def compare(rm: Mapping[str, np.ndarray], bar: str, agents: Sequence[str], n_boot: int) -> dict[str, Any]:
    """The study's numbers (module docstring) of one episode set."""
    from agents.evaluation.comparison import delta_rmse

    out: dict[str, Any] = {"rmse_m": {k: float(np.nanmean(v)) for k, v in rm.items()}, "bar": bar}
    sup = "supervised" in rm
    if sup and bar != "supervised":
        out["supervised_vs_bar"] = delta_rmse(rm["supervised"], rm[bar], n_boot)
    if not agents:
        return out
    per_seed = {a: delta_rmse(rm[a], rm[bar], n_boot) for a in agents}
    pcts = [p["delta_pct"] for p in per_seed.values()]
    mean_agent = np.mean([rm[a] for a in agents], axis=0)
    out.update(
        per_seed=per_seed,
        mean_vs_bar=delta_rmse(mean_agent, rm[bar], n_boot),
        seed_range_pct=[min(pcts), max(pcts)],
        mean_rmse_m=float(np.nanmean(mean_agent)),
    )
    if sup:
        out["mean_vs_supervised"] = delta_rmse(mean_agent, rm["supervised"], n_boot)
    return out


def _evaluate_set(job: tuple[str, str, Mapping[str, Any], int, str, int]) -> dict[str, Any]:
    env_id, set_name, kwargs, episodes, runs, n_boot = job
    import torch

    from agents.seeds import seeds as seed_range

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    pol, bar, agents = policies_of(env_id, Path(runs))
    if set_name != "held-out":
        pol = {k: v for k, v in pol.items() if k != "plain"}
    rm = rmse_of(env_id, pol, seed_range("eval", episodes), kwargs)
    res = compare(rm, bar, agents, n_boot)
    return {
        "env_id": env_id,
        "set": set_name,
        "env_kwargs": dict(kwargs),
        "episodes": episodes,
        **res,
        "per_episode_rmse_m": {k: v.tolist() for k, v in rm.items()},
        "seconds": time.perf_counter() - t0,
    }


#: The receiver shifts: another receiver's C/N0 report, offset by this many dB (``cn0_offset_db``
#: of the v3 ids: the report and the accuracy figure derived from it move, the signal does not).
CN0_SHIFTS = {"C/N0 -3 dB": -3.0, "C/N0 +3 dB": 3.0}


def shift_sets(env_id: str) -> dict[str, dict[str, Any]]:
    """The shifts of ``env_id``: those of :mod:`experiments.learned_v2.shifts` for its platform (the
    platforms it covers), then the receiver shifts :data:`CN0_SHIFTS`."""
    from experiments.learned_v2.shifts import SHIFT_KWARGS

    out: dict[str, dict[str, Any]] = {}
    for platform, shifts in SHIFT_KWARGS.items():
        if name_of(env_id).startswith(platform):
            out.update(shifts)
    out.update({name: {"cn0_offset_db": db} for name, db in CN0_SHIFTS.items()})
    return out


def set_key(job: tuple[str, str, Mapping[str, Any], int, str, int]) -> str:
    """What identifies an evaluated set: the id, the set, its episodes, and the agents' files.

    The agents' ``model.zip`` SHA-256 (each seed's kept model) enter it, so a retrained seed is
    evaluated again.
    """
    import hashlib

    env_id, set_name, kwargs, episodes, runs, n_boot = job
    h = hashlib.sha256(json.dumps([env_id, set_name, dict(kwargs), episodes, n_boot]).encode())
    for d in seed_dirs(Path(runs), env_id):
        h.update((kept_model(d) / "model.zip").read_bytes())
    return h.hexdigest()[:16]


def evaluate_all(
    envs: Sequence[str],
    runs: Path,
    episodes: int,
    shift_episodes: int,
    jobs: int,
    n_boot: int,
    cache: Path | None = None,
) -> list[dict[str, Any]]:
    """Every id's held-out set and shifts, ``jobs`` sets at a time.

    With ``cache``, each set's result is kept in ``cache/<key>.json`` (:func:`set_key`) and read
    back instead of evaluated again when its key matches (an interrupted or partial run resumes).
    """
    work = []
    for e in envs:
        work.append((e, "held-out", {}, episodes, str(runs), n_boot))
        if shift_episodes > 0:
            work += [(e, s, kw, shift_episodes, str(runs), n_boot) for s, kw in shift_sets(e).items()]
    keys = [set_key(w) for w in work] if cache is not None else [None] * len(work)
    done: dict[int, dict[str, Any]] = {}
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        for i, k in enumerate(keys):
            if (cache / f"{k}.json").is_file():
                done[i] = json.loads((cache / f"{k}.json").read_text())
    todo = [i for i in range(len(work)) if i not in done]

    def keep(i: int, r: dict[str, Any]) -> None:
        done[i] = r
        if cache is not None:
            (cache / f"{keys[i]}.json").write_text(json.dumps(r))

    if jobs <= 1:
        for i in todo:
            keep(i, _evaluate_set(work[i]))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for i, r in zip(todo, pool.map(_evaluate_set, [work[i] for i in todo]), strict=True):
                keep(i, r)
    return [done[i] for i in range(len(work))]


def met(d: Mapping[str, Any]) -> bool:
    """The target: ``ΔRMSE % <= -15`` against the bar with the CI below 0."""
    return bool(d["delta_pct"] <= -TARGET_PCT and d["high_pct"] < 0)


def _pct(d: Mapping[str, Any]) -> str:
    return f"{d['delta_pct']:+.1f} [{d['low_pct']:+.1f}, {d['high_pct']:+.1f}]"


def table_rows(results: Sequence[Mapping[str, Any]]) -> list[dict[str, str]]:
    """One markdown row per (id, episode set)."""
    rows = []
    for r in results:
        rm = r["rmse_m"]
        row = {
            "id": f"`{name_of(r['env_id'])}`",
            "set": r["set"],
            "episodes": str(r["episodes"]),
            "bar m": f"{r['bar']} {rm[r['bar']]:.3f}",
            "supervised m": f"{rm['supervised']:.3f}" if "supervised" in rm else "n/a",
        }
        if "mean_vs_bar" in r:
            mv, ms = r["mean_vs_bar"], r.get("mean_vs_supervised")
            lo, hi = r["seed_range_pct"]
            row.update(
                {
                    "PPO m (mean of seeds)": f"{r['mean_rmse_m']:.3f}",
                    "PPO vs bar % [95% CI]": _pct(mv),
                    "seeds' % (min, max)": f"{lo:+.1f}, {hi:+.1f}",
                    "PPO vs supervised %": _pct(ms) if ms else "n/a",
                    "target (<= -15 %)": "met" if met(mv) else "missed",
                }
            )
        rows.append(row)
    return rows


def summary_rows(results: Sequence[Mapping[str, Any]]) -> list[dict[str, str]]:
    """The top-level README's rows: per id, held-out and the shifts' ΔRMSE % of the mean agent."""
    out: dict[str, dict[str, str]] = {}
    shifts: dict[str, list[str]] = {}
    for r in results:
        if "mean_vs_bar" not in r:
            continue
        name = f"`{name_of(r['env_id'])}`"
        if r["set"] == "held-out":
            rm = r["rmse_m"]
            out[name] = {
                "id": name,
                "RMSE m: bar / supervised / PPO": (
                    f"{r['bar']} {rm[r['bar']]:.2f} / "
                    + (f"{rm['supervised']:.2f}" if "supervised" in rm else "n/a")
                    + f" / {r['mean_rmse_m']:.2f}"
                ),
                "PPO vs bar % [95% CI]": _pct(r["mean_vs_bar"]),
                "seeds' %": "{:+.1f} to {:+.1f}".format(*r["seed_range_pct"]),
                "PPO vs supervised % [95% CI]": (
                    _pct(r["mean_vs_supervised"]) if "mean_vs_supervised" in r else "n/a"
                ),
                "target": "met" if met(r["mean_vs_bar"]) else "missed",
            }
        else:
            shifts.setdefault(name, []).append(f"{r['mean_vs_bar']['delta_pct']:+.1f}")
    for name, row in out.items():
        row["vs bar % on shifts"] = " / ".join(shifts.get(name, [])) or "n/a"
    return list(out.values())


#: The README blocks this study writes (``evaluate --readme``).
BEGIN, END = "<!-- learned-v3:begin -->", "<!-- learned-v3:end -->"
STUDY_README = Path(__file__).resolve().parent / "README.md"
ROOT_README = Path(__file__).resolve().parents[2] / "README.md"


def write_block(path: Path, block: str) -> None:
    """Put ``block`` between :data:`BEGIN` and :data:`END` of ``path`` (both must be there)."""
    from agents.reporting import replace_marked_block

    replace_marked_block(path, BEGIN, END, block)


def merged_table(path: Path, table: str, envs: Sequence[str]) -> str:
    """``table`` with the rows of the other ids kept from ``path``'s block (same columns).

    ``evaluate --readme --env ID`` updates the rows of the ids it evaluated; the rows of the
    others stay as their last evaluation wrote them. Rows are ordered as :data:`DEFAULT_ENVS`.
    """
    body = path.read_text()
    old = body.partition(BEGIN)[2].partition(END)[0].strip().splitlines()
    lines = table.rstrip().splitlines()
    if len(old) < 2 or old[0] != lines[0]:
        return table  # no block yet, or other columns: the new table alone
    names = {name_of(e) for e in envs}
    kept = [r for r in old[2:] if r.startswith("| `") and r.split("`")[1] not in names]
    order = [name_of(e) for e in DEFAULT_ENVS]
    rows = sorted(
        kept + lines[2:],
        key=lambda r: order.index(r.split("`")[1]) if r.split("`")[1] in order else len(order),
    )
    return "\n".join([lines[0], lines[1], *rows]) + "\n"


def tuning_score(seed_dir: Path) -> dict[str, Any]:
    """The kept model's scores on the tuning episodes (``best/best.json``)."""
    return dict(json.loads((seed_dir / "best" / "best.json").read_text()))


def median_seed(dirs: Sequence[Path]) -> Path:
    """The seed whose tuning return is the median (the lower middle for an even count)."""
    if not dirs:
        raise FileNotFoundError("no trained seed (run the train step first)")
    ranked = sorted(dirs, key=lambda d: tuning_score(d)["return"])
    return ranked[(len(ranked) - 1) // 2]


def export_zoo(env_id: str, runs: Path, zoo: Path = ZOO) -> Path:
    """Copy the median seed's kept model of ``env_id`` to ``zoo/<EnvName>`` (module docstring)."""
    import shutil

    from agents.training.agent_files import sha256_file
    from agents.training.manifest import verify_manifest

    dirs = seed_dirs(runs, env_id)
    chosen = median_seed(dirs)
    src = kept_model(chosen)
    verify_manifest(src)
    dest = zoo / name_of(env_id)
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    scores = {d.name: tuning_score(d) for d in dirs}
    for name in ZOO_FILES:
        if (src / name).is_file():
            shutil.copy2(src / name, dest / name)
    meta = json.loads((chosen / "meta.json").read_text())
    meta["kept_on_tuning_seeds"] = scores[chosen.name]  # the model here: that step, not the last
    (dest / "meta.json").write_text(json.dumps(meta, indent=1) + "\n")
    manifest = json.loads((src / "manifest.json").read_text())
    files = [n for n in (*ZOO_FILES, "meta.json") if (dest / n).is_file()]
    manifest["files"] = {n: sha256_file(dest / n) for n in sorted(files)}
    (dest / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    verify_manifest(dest)
    res = meta.get("residual") or {}
    if res.get("baseline") == "supervised":
        title = "per-row shared residual over the supervised agent"
        base = (
            f"The base policy is the supervised agent `agents/zoo/{name_of(env_id)}-supervised` (read "
            "from `config.yml`'s `residual.agent`); loading checks both manifests and unpickles nothing."
        )
        initial = "the supervised agent with a near-zero residual"
    else:
        params = ", ".join(f"{k} = {v:g}" for k, v in (res.get("params") or {}).items())
        title = f"residual over the tuned `{res.get('baseline')}` baseline"
        base = (
            f"The base policy is the tuned `{res.get('baseline')}` baseline ({params}; "
            f"`{res.get('params_source', 'config.yml')}`); loading checks the manifest and unpickles nothing."
        )
        initial = "the tuned baseline with a near-zero residual"
    lines = [
        f"# {env_id} — PPO, {title} ({chosen.name})",
        "",
        f'Load with `agents.training.load_agent("agents/zoo/{name_of(env_id)}")`; `predict` takes raw '
        f"observations. {base}",
        "",
        "## How it was made",
        "",
        f"* command: `{meta['command']}` (through `python -m experiments.learned_v3 train`), the "
        "configuration `agents/configs/ppo.yml`'s entry (`config.yml` here)",
        f"* {meta['total_timesteps']:,} environment steps, {meta['n_envs']} sub-environments, wall time "
        f"{meta['wall_time_s'] / 60:.1f} min ({meta['steps_per_s']:.0f} steps/s, 1 torch thread, "
        "2 shared CPU cores); training seeds only",
        f"* the model kept: the best of the periodic evaluations on 64 tuning episodes "
        f"(step {scores[chosen.name]['num_timesteps']:,}, `meta.json`'s `kept_on_tuning_seeds`; the "
        "other figures of `meta.json` are the run's last step; the initial policy, "
        f"{initial}, is one of the candidates)",
        "* this seed is the median of the trained seeds by that tuning score:",
        "",
        "| seed | kept at step | tuning return | tuning RMSE m |",
        "|---|---|---|---|",
        *(
            f"| {k} | {v['num_timesteps']:,} | {v['return']:.2f} | {v['rmse_m']:.3f} |"
            for k, v in sorted(scores.items())
        ),
        "",
        "Held-out results: `experiments/learned_v3/README.md`.",
        "",
    ]
    (dest / "README.md").write_text("\n".join(lines))
    return dest


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.learned_v3", description=__doc__.split("\n\n")[1])
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train", help="train the agents (training seeds)")
    t.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    t.add_argument("--timesteps", type=int, default=None, help="default: the config's n_timesteps")
    t.add_argument(
        "--config", default=None, help="a YAML file keyed by env id (default: agents/configs/ppo.yml)"
    )
    z = sub.add_parser("zoo", help="copy each id's median seed (by tuning score) to agents/zoo")
    z.add_argument("--env", nargs="+", default=list(DEFAULT_ENVS))
    z.add_argument("--runs", type=Path, default=RUNS)
    ev = sub.add_parser("evaluate", help="evaluate the agents on held-out episodes and the shifts")
    ev.add_argument("--episodes", type=int, default=EPISODES)
    ev.add_argument("--shift-episodes", type=int, default=SHIFT_EPISODES)
    ev.add_argument("--out", type=Path, default=OUT)
    ev.add_argument(
        "--readme", action="store_true", help="write the tables into this study's and the project's README"
    )
    rp = sub.add_parser("replay", help="the Quadrotor's v3 agents on the real walk (ReplayRowScale-v3)")
    rp.add_argument("--episodes", type=int, default=256)
    rp.add_argument("--out", type=Path, default=OUT)
    rp.add_argument("--readme", action="store_true", help="write the table into this study's README")
    rp.add_argument("--quick", action="store_true", help="a smoke run (tiny budgets)")
    for q in (t, ev):
        q.add_argument("--env", nargs="+", default=list(DEFAULT_ENVS))
        q.add_argument("--runs", type=Path, default=RUNS, help="folder of the runs (<EnvName>/seed_<k>)")
        q.add_argument("--jobs", type=int, default=2, help="processes in parallel")
        q.add_argument("--quick", action="store_true", help="a smoke run (tiny budgets)")
    a = p.parse_args(argv)
    import navgym  # noqa: F401  (registers the ids)

    if a.cmd == "zoo":
        for e in a.env:
            print(f"{e} -> {export_zoo(e, a.runs)}")
        return 0
    if a.cmd == "train":
        steps = QUICK["timesteps"] if a.quick else a.timesteps
        for r in train_all(a.env, a.seeds, a.runs, steps, a.jobs, a.config):
            print(f"{r['env_id']} seed {r['seed']}: {r['folder']} ({r['seconds']:.0f} s)", flush=True)
        return 0
    from agents.evaluation.bootstrap import DEFAULT_RESAMPLES
    from agents.reporting import markdown_table
    from experiments.outputs import write_manifest

    if a.cmd == "replay":
        return _replay(a, argv)

    n, ns, boot = (
        (QUICK["episodes"], QUICK["shift_episodes"], QUICK["n_boot"])
        if a.quick
        else (a.episodes, a.shift_episodes, DEFAULT_RESAMPLES)
    )
    results = evaluate_all(a.env, a.runs, n, ns, a.jobs, boot, cache=a.out / "sets")
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "results.json").write_text(json.dumps(results, indent=1))
    table = markdown_table(table_rows(results))
    (a.out / "table.md").write_text(table)
    write_manifest(a.out, "experiments.learned_v3", argv, episodes=n, shift_episodes=ns)
    if a.readme and not a.quick:
        cmd = f"`python -m experiments.learned_v3 evaluate --episodes {n} --shift-episodes {ns}`"
        foot = (
            f"{cmd}: {n} held-out episodes per id, {ns} per shift; PPO = the mean over the training seeds' "
            "agents of each episode's RMSE; paired 95 % bootstrap CIs; the bar is the best tuned classical "
            "baseline (fixed by its tuning score); target: <= -15 % with the CI below 0."
        )
        full = merged_table(STUDY_README, table, a.env)
        write_block(STUDY_README, f"{full.rstrip()}\n\n{foot}")
        short = f"{cmd}: {n} held-out episodes per id, {ns} per shift; every row: the study's README."
        summary = merged_table(ROOT_README, markdown_table(summary_rows(results)), a.env)
        write_block(ROOT_README, f"{summary.rstrip()}\n\n{short}")
    print(table)
    return 0


def _replay(a: argparse.Namespace, argv: list[str] | None) -> int:
    """``replay``: :mod:`experiments.learned_v3.replay`."""
    from agents.evaluation.bootstrap import DEFAULT_RESAMPLES
    from agents.reporting import markdown_table, replace_marked_block
    from experiments.learned_v3 import replay
    from experiments.outputs import write_manifest

    n, boot = (QUICK["episodes"], QUICK["n_boot"]) if a.quick else (a.episodes, DEFAULT_RESAMPLES)
    res = replay.evaluate_replay(n, boot)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "replay.json").write_text(json.dumps(res, indent=1))
    table = markdown_table(replay.replay_rows(res))
    (a.out / "replay.md").write_text(table)
    write_manifest(a.out, "experiments.learned_v3", argv, episodes=n)
    if a.readme and not a.quick:
        foot = (
            f"`python -m experiments.learned_v3 replay --episodes {n}`: {n} held-out windows of the "
            "walk (evaluation seeds; each draws a window and its injected events); paired 95 % bootstrap "
            "CIs; the bar is the replay id's best tuned baseline (tuning windows, its tuning score)."
        )
        replace_marked_block(STUDY_README, replay.BEGIN, replay.END, f"{table.rstrip()}\n\n{foot}")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
