"""The AGENT arguments of ``navgym benchmark``: ``[LABEL=]PATH`` of a saved agent or of its seeds.

``PATH`` is one of

* a supervised RowScale agent folder (:mod:`agents.supervised`; ``manifest.json`` of kind
  ``supervised_rowscale``, which names the env id), such as
  ``agents/zoo/Robot2dRowScale-v3-supervised``: loaded with
  :func:`agents.supervised.files.load_policy` on the live env;
* a trained SB3 agent folder (``model.zip`` with navgym's ``manifest.json``; ``config.yml`` or
  the manifest names the env id): loaded with :func:`agents.training.loading.load_agent`
  (nothing unpickled). A training run that kept its best model on tuning seeds
  (``best/best.json``, ``navgym train --eval-freq``) is evaluated with that model, the one the
  run chose without seeing a held-out episode;
* a folder whose subfolders ``seed_*/`` are each one agent of the same kind and env id (the
  training seeds of one agent): each is evaluated, and the leaderboard aggregates across them.

The label defaults to the folder's name. Every folder is checked here (manifest, hashes, env
id), before any episode runs; an error names the argument and the path.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.training.callbacks import kept_model

__all__ = ["AgentSpec", "parse_agent"]

SUPERVISED_KIND = "supervised_rowscale"
#: Training env kwargs that change nothing about the episodes (left out of the notes).
NEUTRAL_KWARGS = frozenset({"eval_info"})


@dataclass
class AgentSpec:
    """One AGENT argument, checked.

    Attributes:
        label: the leaderboard's name of the agent.
        path: the folder given.
        kind: ``"supervised"`` or ``"sb3"``.
        env_id: the env id the agent was made for.
        seeds: ``[(seed name, folder)]``: ``[("", path)]`` for one agent, the ``seed_*``
            folders in numeric order for several training seeds.
        train_env_kwargs: the env kwargs of training (besides :data:`NEUTRAL_KWARGS`).
        loaded: SB3 agents loaded while checking, by seed folder (reused by the evaluation).
        record: what the manifest records of each seed folder (algo, command, ...).
    """

    label: str
    path: Path
    kind: str
    env_id: str
    seeds: list[tuple[str, Path]]
    train_env_kwargs: dict[str, Any] = field(default_factory=dict)
    loaded: dict[Path, Any] = field(default_factory=dict, repr=False)
    record: dict[str, Any] = field(default_factory=dict)

    @property
    def multi_seed(self) -> bool:
        """Whether the agent is given as several training-seed folders."""
        return bool(self.seeds and self.seeds[0][0])

    def policy_label(self, seed: str) -> str:
        """The label of one seed's row: ``LABEL/seed_k`` (``LABEL`` for a single agent)."""
        return f"{self.label}/{seed}" if seed else self.label

    def factory(self, folder: Path) -> Any:
        """The policy of ``folder``, or a factory of it taking the live vector env."""
        if self.kind == "sb3":
            return self.loaded[folder]
        from agents.supervised.files import load_policy

        return lambda env: load_policy(folder, env)


def split_label(spec: str) -> tuple[str, str]:
    """``(label, path)`` of ``[LABEL=]PATH`` (``""`` when no label; a path may hold ``=``)."""
    head, eq, tail = spec.partition("=")
    if eq and head and "/" not in head and "\\" not in head and tail:
        return head, tail
    return "", spec


def _seed_key(p: Path) -> tuple[int, str]:
    m = re.fullmatch(r"seed_(\d+)", p.name)
    return (int(m.group(1)) if m else 1 << 62, p.name)


def _kind_of(folder: Path) -> str | None:
    """``"supervised"``, ``"sb3"`` or None (neither) for one agent folder."""
    man = folder / "manifest.json"
    if man.is_file():
        try:
            kind = json.loads(man.read_text()).get("kind")
        except (json.JSONDecodeError, AttributeError):
            kind = None
        if kind == SUPERVISED_KIND:
            return "supervised"
    if (folder / "model.zip").is_file():
        return "sb3"
    return None


def _check_one(spec: str, folder: Path, kind: str) -> tuple[str, dict[str, Any], dict[str, Any], Any]:
    """``(env id, training env kwargs, record, loaded agent or None)`` of one agent folder."""
    if kind == "supervised":
        from agents.supervised.files import read_manifest

        try:
            man = read_manifest(folder)  # checks the weights' SHA-256
        except ValueError as e:
            raise ValueError(f"agent {spec!r}: {e}") from e
        env_id = man.get("env_id")
        record = {"kind": kind, "mode": man.get("mode"), "table": man.get("table")}
        record["command"] = (man.get("training") or {}).get("command")
        kwargs, agent = dict(man.get("env_kwargs") or {}), None
    else:
        from agents.training.loading import load_agent

        kept = kept_model(folder)
        try:
            agent = load_agent(kept)
        except (ValueError, FileNotFoundError) as e:
            raise ValueError(f"agent {spec!r}: {kept} does not load as an SB3 agent: {e}") from e
        env_id = agent.env_id or (agent.manifest or {}).get("env_id")
        kwargs = dict(agent.env_kwargs)
        record = {"kind": kind, "algo": agent.algo, "seed": agent.info.get("seed"), "model": str(kept)}
    if not env_id:
        raise ValueError(f"agent {spec!r}: {folder} does not name its env id (manifest.json / config.yml)")
    kwargs = {k: v for k, v in kwargs.items() if k not in NEUTRAL_KWARGS}
    return str(env_id), kwargs, record, agent


def parse_agent(spec: str) -> AgentSpec:
    """The :class:`AgentSpec` of one AGENT argument (module docstring).

    Raises:
        FileNotFoundError: the path does not exist (the message names it).
        ValueError: the folder is no agent nor a folder of ``seed_*`` agents, an agent does not
            load, or the seed folders differ in kind or env id.
    """
    label, raw = split_label(spec)
    path = Path(raw)
    if not path.exists():
        raise FileNotFoundError(f"agent {spec!r}: {path} does not exist")
    if not path.is_dir():
        raise ValueError(f"agent {spec!r}: {path} is not a folder (give the agent's folder, not a file)")
    kind = _kind_of(path)
    if kind is not None:
        seeds = [("", path)]
    else:
        seeds = [(p.name, p) for p in sorted(path.glob("seed_*"), key=_seed_key) if p.is_dir()]
        if not seeds:
            raise ValueError(
                f"agent {spec!r}: {path} is neither a supervised agent folder (manifest.json of kind "
                f"{SUPERVISED_KIND!r}), an SB3 agent folder (model.zip with manifest.json), nor a folder "
                "of seed_*/ agent folders"
            )
    kinds, ids = {}, {}
    out = AgentSpec(label or path.resolve().name, path, "", "", seeds)
    for name, folder in seeds:
        k = _kind_of(folder)
        if k is None:
            raise ValueError(f"agent {spec!r}: {folder} is neither a supervised nor an SB3 agent folder")
        env_id, kwargs, record, agent = _check_one(spec, folder, k)
        kinds[name], ids[name] = k, env_id
        out.record[name or "agent"] = record
        if agent is not None:
            out.loaded[folder] = agent
        if kwargs:
            out.train_env_kwargs[name or "agent"] = kwargs
    if len(set(kinds.values())) > 1 or len(set(ids.values())) > 1:
        raise ValueError(
            f"agent {spec!r}: the seed folders of {path} must be agents of one kind and env id; got "
            + ", ".join(f"{n}: {kinds[n]} {ids[n]}" for n in kinds)
        )
    out.kind, out.env_id = next(iter(kinds.values())), next(iter(ids.values()))
    return out
