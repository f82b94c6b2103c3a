"""``python -m agents.supervised``: collect, train, save, and evaluate the supervised RowScale policy.

::

    python -m agents.supervised --env navgym/Robot2dRowScale-v3 --table 1,100,1e4,1,10 \
        --train-episodes 512 --dagger 2 --mode iae_mix --out runs/supervised \
        [--eval-episodes 256] [--seed-kind eval|tune] [--iae-q table|mix|iae] [--quick]
    python -m agents.supervised --env ... --load runs/supervised --seed-kind tune \
        --eval-episodes 128 --out runs/supervised_tune [--mode ...] [--table ...] [--iae-q ...]

1. collects labelled steps of ``--train-episodes`` **training** episodes under ``--behaviour``
   (:mod:`agents.supervised.collect`), the last :data:`VAL_FRACTION` of them held out for early
   stopping; ``--dagger K`` adds K rounds of as many episodes (further training seeds) run by the
   policy trained so far, labelled by the truth, and retrains (Ross et al. 2011);
2. trains :class:`~agents.supervised.model.RowRegimeNet` (:mod:`agents.supervised.train`) and
   prints the held-out accuracy per class;
3. saves weights and manifest to ``--out`` (:mod:`agents.supervised.files`);
4. evaluates the saved policy (loaded back) on ``--eval-episodes`` held-out **evaluation**
   episodes beside plain, the best tuned baseline and the regime oracle
   (:mod:`agents.supervised.study`), prints the markdown table and gate G2, and writes
   ``report.md`` and ``results.json`` to ``--out``. ``--eval-episodes 0``: no evaluation;
   ``--seed-kind tune``: on **tuning** seeds instead (to choose table, mode and ``--iae-q``
   without seeing an evaluation episode); ``--load FOLDER``: no training, the saved policy of
   ``FOLDER`` evaluated (with ``--mode`` / ``--table`` / ``--iae-q`` where given).

Mode ``iae_mix`` reads row_iae's tuned ``b, beta, s_q`` from the env id's tuned file
(``--tuned``, default ``agents/baselines/tuned/<Id>.json``;
:func:`agents.supervised.policy.tuned_iae`) and keeps them in the manifest.

``--quick``: a smoke run (few episodes of :data:`QUICK_STEPS` steps, two epochs).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from agents.evaluation.runner import make_vector_env
from agents.seeds import seeds as seed_range
from agents.supervised.collect import BEHAVIOURS, Dataset, collect
from agents.supervised.files import load_policy, save_policy
from agents.supervised.labels import MOTION_CLASSES, ROW_CLASSES
from agents.supervised.policy import IAE_Q, MODES, SupervisedRowScalePolicy, tuned_iae
from agents.supervised.study import compare, markdown_table
from agents.supervised.train import TrainConfig, TrainResult, train_model

__all__ = ["build_parser", "main", "run_supervised", "train_supervised"]

#: Fraction of the training episodes held out for early stopping.
VAL_FRACTION = 0.2
#: Episode length of ``--quick`` runs (``max_episode_steps``).
QUICK_STEPS = 40
#: The default placeholder table (``s_nominal, s_noisy, s_biased, s_q_nominal, s_q_event``).
DEFAULT_TABLE = (1.0, 100.0, 1e4, 1.0, 10.0)


def split_episodes(ds: Dataset, fraction: float = VAL_FRACTION) -> tuple[Dataset, Dataset]:
    """``(train, held out)``: the last ``fraction`` of the episodes (by seed) held out (at least one)."""
    eps = np.unique(ds.episode)
    n_val = max(1, int(round(fraction * eps.size))) if eps.size > 1 else 0
    val = np.isin(ds.episode, eps[eps.size - n_val :]) if n_val else np.zeros(ds.episode.size, bool)
    return ds.take(~val), ds.take(val if n_val else ~val)


def print_accuracy(acc: dict[str, Any], log: Any = print) -> None:
    """The held-out accuracy and per-class recall of :func:`agents.supervised.train.accuracy_report`."""
    for part, names in (("rows", ROW_CLASSES), ("motion", MOTION_CLASSES)):
        a = acc[part]
        per = ", ".join(f"{n} {100 * a['recall'][n]:.1f} % (n={a['count'][n]})" for n in names)
        log(f"held-out {part}: accuracy {100 * a['accuracy']:.1f} %; per class: {per}")


def _round(result: TrainResult) -> dict[str, Any]:
    return {"epochs": result.epochs, "best_epoch": result.best_epoch, "held_out_loss": result.val_loss}


def train_supervised(
    env_id: str,
    table: Sequence[float],
    train_episodes: int,
    behaviour: str = "mixed",
    dagger: int = 0,
    mode: str = "iae_mix",
    config: TrainConfig | None = None,
    env_kwargs: dict[str, Any] | None = None,
    log: Any = print,
    iae: dict[str, float] | None = None,
    iae_q: str = "table",
) -> tuple[SupervisedRowScalePolicy, dict[str, Any]]:
    """Steps 1-2 of the module docstring: ``(policy, training record)`` (training seeds only).

    Each DAgger round collects ``train_episodes`` further training episodes under the policy of
    the round before (its ``mode``), labelled by the truth, and trains a fresh model on all the
    steps so far (Ross et al. 2011). ``iae``: row_iae's parameters of mode ``"iae_mix"``
    (default :func:`~agents.supervised.policy.tuned_iae` of ``env_id``).
    """
    if mode == "iae_mix" and iae is None:
        iae = tuned_iae(env_id)
    t0 = time.perf_counter()
    config = config or TrainConfig()
    kwargs = dict(env_kwargs or {})
    table = [float(v) for v in table]
    train_seeds = seed_range("train", train_episodes)
    log(f"collecting {train_episodes} training episodes ({behaviour}) of {env_id}")
    train, val = split_episodes(collect(env_id, train_seeds, behaviour, table, kwargs))
    log(f"{train.row_y.shape[0]} training steps, {val.row_y.shape[0]} held-out steps")
    result: TrainResult = train_model(train, val, config, log)
    env = make_vector_env(env_id, 1, kwargs)
    policy = SupervisedRowScalePolicy(env, result.model, table, mode, iae, iae_q)
    rounds = [_round(result)]
    for r in range(1, dagger + 1):
        more = seed_range("train", train_episodes, offset=r * train_episodes)
        log(f"DAgger round {r}: {train_episodes} episodes under the policy ({mode})")
        t2, v2 = split_episodes(collect(env_id, more, policy, table, kwargs))
        train, val = Dataset.concat([train, t2]), Dataset.concat([val, v2])
        result = train_model(train, val, config, log)
        policy = SupervisedRowScalePolicy(env, result.model, table, mode, iae, iae_q)
        rounds.append(_round(result))
    env.close()
    print_accuracy(result.accuracy, log)
    n_seeds = train_episodes * (dagger + 1)
    record = {
        "behaviour": behaviour,
        "iae": iae,
        "iae_q": iae_q,
        "dagger_rounds": dagger,
        "train_seeds": [train_seeds[0], train_seeds[0] + n_seeds],
        "train_episodes": n_seeds,
        "held_out_fraction": VAL_FRACTION,
        "train_steps": int(train.row_y.shape[0]),
        "held_out_steps": int(val.row_y.shape[0]),
        "config": asdict(config),
        "epochs": result.epochs,
        "best_epoch": result.best_epoch,
        "held_out_loss": result.val_loss,
        "rounds": rounds,
        "accuracy": result.accuracy,
        "wall_s": time.perf_counter() - t0,
    }
    return policy, record


def run_supervised(
    env_id: str,
    table: Sequence[float],
    train_episodes: int,
    out: str | Path,
    eval_episodes: int | None = None,
    behaviour: str = "mixed",
    dagger: int = 0,
    mode: str = "iae_mix",
    config: TrainConfig | None = None,
    env_kwargs: dict[str, Any] | None = None,
    tuned_file: str | Path | None = None,
    n_boot: int = 2000,
    command: str = "",
    log: Any = print,
    iae_q: str = "table",
    seed_kind: str = "eval",
    load: str | Path | None = None,
) -> dict[str, Any]:
    """The whole job of the module docstring; returns the comparison (:func:`study.compare`).

    ``load``: evaluate the policy saved there (``mode``, ``table``, ``iae_q`` as given) instead of
    training one; ``eval_episodes`` 0: train and save only.
    """
    t0 = time.perf_counter()
    kwargs = dict(env_kwargs or {})
    if load is None:
        iae = tuned_iae(env_id, tuned_file) if mode == "iae_mix" else None
        policy, record = train_supervised(
            env_id, table, train_episodes, behaviour, dagger, mode, config, kwargs, log, iae, iae_q
        )
        record = {"command": command, **record}
        save_policy(out, policy, env_id, kwargs, record)
        log(f"saved to {out}")
        src: str | Path = out
    else:
        src, record = load, {"loaded": str(load)}
    n_eval = train_episodes if eval_episodes is None else eval_episodes
    if n_eval == 0:
        return {"training": record, "wall_s": time.perf_counter() - t0}
    res = compare(
        env_id,
        lambda e: load_policy(src, e, mode, table, iae_q),
        table,
        seed_range(seed_kind, n_eval),
        kwargs,
        tuned_file,
        n_boot,
        seed_kind,
    )
    text = markdown_table(res)
    log(text)
    res["wall_s"] = time.perf_counter() - t0
    res["training"] = record
    Path(out).mkdir(parents=True, exist_ok=True)
    Path(out, "report.md").write_text(f"`{command}`\n\n{text}")
    Path(out, "results.json").write_text(json.dumps(res, indent=1))
    return res


def build_parser() -> argparse.ArgumentParser:
    """The arguments of ``python -m agents.supervised``."""
    p = argparse.ArgumentParser(prog="python -m agents.supervised", description=__doc__.splitlines()[0])
    p.add_argument("--env", required=True, help="a RowScale id, e.g. navgym/Robot2dRowScale-v3")
    p.add_argument(
        "--table",
        default=",".join(f"{v:g}" for v in DEFAULT_TABLE),
        help="the oracle's s_nominal,s_noisy,s_biased,s_q_nominal,s_q_event (searched on tuning seeds)",
    )
    p.add_argument("--train-episodes", type=int, default=256, help="training episodes (training seeds)")
    p.add_argument(
        "--eval-episodes", type=int, default=None, help="held-out evaluation episodes (default: as many)"
    )
    p.add_argument("--out", required=True, help="folder of the weights, manifest and report")
    p.add_argument("--behaviour", choices=BEHAVIOURS, default="mixed", help="behaviour policy of the data")
    p.add_argument("--dagger", type=int, default=0, help="DAgger rounds after the first training")
    p.add_argument("--mode", choices=MODES, default="iae_mix", help="classes -> scales")
    p.add_argument(
        "--iae-q", choices=IAE_Q, default="table", help="iae_mix: s_q of the table, mixed, or row_iae's"
    )
    p.add_argument(
        "--seed-kind", choices=("eval", "tune"), default="eval", help="evaluate on evaluation or tuning seeds"
    )
    p.add_argument("--load", default=None, help="evaluate the policy saved in this folder (no training)")
    p.add_argument("--epochs", type=int, default=TrainConfig.epochs)
    p.add_argument("--hidden", type=int, default=TrainConfig.hidden)
    p.add_argument("--class-power", type=float, default=TrainConfig.class_power)
    p.add_argument("--env-kwargs", default="{}", help="JSON keyword arguments of the env")
    p.add_argument(
        "--tuned", default=None, help="tuned baselines file (default agents/baselines/tuned/<Id>.json)"
    )
    p.add_argument("--n-boot", type=int, default=2000)
    p.add_argument(
        "--quick", action="store_true", help=f"smoke run: 6 episodes of {QUICK_STEPS} steps, 2 epochs"
    )
    return p


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Parse ``argv`` and run :func:`run_supervised`."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    torch.set_num_threads(1)  # per-step batches are tiny: more threads only contend (10x slower)
    table = [float(v) for v in args.table.split(",")]
    if len(table) != 5:
        raise SystemExit(f"--table needs five scales; got {args.table!r}")
    kwargs = json.loads(args.env_kwargs)
    config = TrainConfig(hidden=args.hidden, epochs=args.epochs, class_power=args.class_power)
    train_n, eval_n, n_boot = args.train_episodes, args.eval_episodes, args.n_boot
    if args.quick:
        kwargs.setdefault("max_episode_steps", QUICK_STEPS)
        config = replace(config, epochs=2)
        train_n, eval_n, n_boot = min(train_n, 6), min(eval_n or 6, 6), min(n_boot, 200)
    return run_supervised(
        args.env,
        table,
        train_n,
        args.out,
        eval_n,
        args.behaviour,
        args.dagger,
        args.mode,
        config,
        kwargs,
        args.tuned,
        n_boot,
        command="python -m agents.supervised " + shlex.join(argv),
        iae_q=args.iae_q,
        seed_kind=args.seed_kind,
        load=args.load,
    )
