"""The upper references of the leaderboard: the clairvoyant filter and the regime oracle.

Both read truth and are never baselines; each runs the task's neutral action on its own env,
on the same seeds as the policies (so its rows are paired with theirs):

* **clairvoyant**: env kwarg ``clairvoyant=True``, the filter told the step's true noise (the
  tasks that have it, on ids whose platform simulates it);
* **regime oracle** (RowScale ids): env kwarg ``regime_oracle=(s_nominal, s_noisy, s_biased,
  s_q_nominal, s_q_event)``, each row's scale set from its true regime. The table comes from the
  supervised zoo agent of the id (``agents/zoo/<EnvName-vK>-supervised/manifest.json``: the
  table its classifier maps regimes to, chosen on tuning seeds; its gate-G2 report evaluates the
  oracle with it), else from ``experiments.knob_reach``'s results (``results/knob_reach/
  results.json`` of a run, else the table committed in ``experiments/knob_reach/README.md``:
  the table searched on tuning seeds).

A reference that an id does not have is skipped; :func:`reference_policies` says why.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agents.reporting import REPO_ROOT

__all__ = ["CLAIRVOYANT", "REGIME_ORACLE", "ZOO", "neutral_policy", "reference_policies", "regime_table"]

CLAIRVOYANT = "clairvoyant (truth)"
REGIME_ORACLE = "regime oracle (truth)"
ZOO = REPO_ROOT / "agents" / "zoo"
KNOB_REACH = REPO_ROOT / "experiments" / "knob_reach"
KNOB_REACH_RESULTS = REPO_ROOT / "results" / "knob_reach" / "results.json"
_ENTRIES = ("s_nominal", "s_noisy", "s_biased", "s_q_nominal", "s_q_event")


def neutral_policy(env: Any) -> Any:
    """The task's neutral action every step (what the references play; the knob is ignored or 1)."""
    from agents.baselines import ConstantAction
    from navgym.envs.base import navigation_env

    return ConstantAction(env.single_action_space, navigation_env(env).task.neutral_action(), "neutral")


def _shown(p: Path) -> str:
    """``p`` relative to the repository where it lies inside it (the files' own spelling)."""
    return str(p.relative_to(REPO_ROOT)) if p.is_relative_to(REPO_ROOT) else str(p)


def _valid(table: Any) -> tuple[float, ...] | None:
    try:
        t = tuple(float(v) for v in table)
    except (TypeError, ValueError):
        return None
    return t if len(t) == 5 and all(math.isfinite(v) and v > 0 for v in t) else None


def _read_json(path: Path) -> Any:
    """The JSON of ``path``, or None where it is missing or not JSON (the source is skipped)."""
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError:
        return None


def _from_zoo(env_id: str, zoo: Path) -> tuple[tuple[float, ...], str] | None:
    p = zoo / f"{env_id.split('/')[-1]}-supervised" / "manifest.json"
    man = _read_json(p)
    if not isinstance(man, dict) or man.get("env_id") != env_id:
        return None
    t = _valid(man.get("table"))
    return (t, _shown(p)) if t else None


def _from_results(env_id: str, path: Path) -> tuple[tuple[float, ...], str] | None:
    results = _read_json(path)
    for r in results if isinstance(results, list) else []:
        table = r.get("table") if isinstance(r, dict) and r.get("env_id") == env_id else None
        if isinstance(table, Mapping) and set(_ENTRIES) <= set(table):
            t = _valid(table[k] for k in _ENTRIES)
            if t:
                return t, _shown(path)
    return None


def _from_readme(env_id: str, readme: Path) -> tuple[tuple[float, ...], str] | None:
    """The table of ``env_id``'s row in the README's ``knob-reach-v3`` block: ``(a, b, c; d, e)``."""
    if not readme.is_file():
        return None
    m = re.search(r"<!-- knob-reach-v3:begin -->(.*?)<!-- knob-reach-v3:end -->", readme.read_text(), re.S)
    if m is None:
        return None
    name = env_id.split("/")[-1]
    number = r"\s*([0-9.eE+-]+)\s*"
    pattern = r"\(" + ",".join([number] * 3) + ";" + ",".join([number] * 2) + r"\)"
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0].strip("`") == name:
            for c in cells:
                t = re.fullmatch(pattern, c)
                if t and (v := _valid(t.groups())):
                    return v, f"{_shown(readme)} (knob-reach-v3 table)"
    return None


def regime_table(
    env_id: str, zoo: Path = ZOO, results: Path = KNOB_REACH_RESULTS, readme: Path | None = None
) -> tuple[tuple[float, ...] | None, str]:
    """``(table, source)`` of the regime oracle of ``env_id``, or ``(None, why not)`` (module docstring)."""
    readme = readme or KNOB_REACH / "README.md"
    for found in (_from_zoo(env_id, zoo), _from_results(env_id, results), _from_readme(env_id, readme)):
        if found is not None:
            return found
    return None, (
        f"no regime-oracle table for {env_id}: no supervised zoo manifest, no knob_reach result "
        "(python -m experiments.knob_reach --env ID)"
    )


def _refusal(env_id: str, kwargs: Mapping[str, Any]) -> str | None:
    """Why ``gym.make(env_id, **kwargs)`` fails (None: it does not)."""
    import gymnasium as gym

    try:
        gym.make(env_id, **kwargs).close()
    except (TypeError, ValueError) as e:
        return " ".join(str(e).split())
    return None


def reference_policies(
    env_id: str, env_kwargs: Mapping[str, Any] | None = None, zoo: Path = ZOO
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """The references ``env_id`` has and the ones it lacks.

    Returns:
        ``({label: {"env_kwargs": the env's kwargs, "source": where its table came from}},
        {label: why skipped})``.
    """
    from agents.baselines.registry import baseline_task

    base = dict(env_kwargs or {})
    have: dict[str, dict[str, Any]] = {}
    skipped: dict[str, str] = {}
    kw = {**base, "clairvoyant": True}
    why = _refusal(env_id, kw)
    if why is None:
        have[CLAIRVOYANT] = {"env_kwargs": kw, "source": "env kwarg clairvoyant=True"}
    else:
        skipped[CLAIRVOYANT] = why
    if baseline_task(env_id) != "RowScale":
        skipped[REGIME_ORACLE] = "the regime oracle belongs to the RowScale ids"
        return have, skipped
    table, source = regime_table(env_id, zoo)
    if table is None:
        skipped[REGIME_ORACLE] = source
        return have, skipped
    kw = {**base, "regime_oracle": table}
    why = _refusal(env_id, kw)
    if why is None:
        have[REGIME_ORACLE] = {"env_kwargs": kw, "source": source, "table": list(table)}
    else:
        skipped[REGIME_ORACLE] = why
    return have, skipped
