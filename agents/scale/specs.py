"""The trials of a sweep: ``--seeds`` and ``--grid`` parsing, overrides of a configuration entry."""

from __future__ import annotations

import copy
import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import yaml

__all__ = [
    "check_trials",
    "Trial",
    "apply_overrides",
    "config_label",
    "grid_configs",
    "make_trials",
    "parse_grid",
    "parse_seeds",
]


def parse_seeds(text: str | Sequence[int]) -> list[int]:
    """``"0..9"`` (inclusive), ``"0,3,7"``, ``"2"`` or a sequence -> a list of distinct seeds >= 0."""
    if not isinstance(text, str):
        out = [int(s) for s in text]
    else:
        out = []
        for part in text.split(","):
            part = part.strip()
            m = re.fullmatch(r"(\d+)\.\.(\d+)", part)
            if m:
                lo, hi = int(m.group(1)), int(m.group(2))
                if hi < lo:
                    raise ValueError(f"--seeds {text!r}: range {part} is empty")
                out += list(range(lo, hi + 1))
            elif re.fullmatch(r"\d+", part):
                out.append(int(part))
            else:
                raise ValueError(f"--seeds {text!r}: use A..B (inclusive), A,B,C or one seed (integers >= 0)")
    if not out or min(out) < 0 or len(set(out)) != len(out):
        raise ValueError(f"--seeds must be distinct integers >= 0; got {text!r}")
    return out


def _split_top(text: str) -> list[str]:
    """``text`` split at the commas outside brackets (``[64, 64],[32]`` -> two values)."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        if ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return [p.strip() for p in parts]


def parse_grid(items: Sequence[str] | None) -> dict[str, list[Any]]:
    """``["learning_rate=1e-4,3e-4", "policy_kwargs.net_arch=[32,32],[64,64]"]`` -> ``{key: values}``.

    Values are YAML scalars or flow collections; a dotted key sets a nested entry.
    """
    grid: dict[str, list[Any]] = {}
    for item in items or ():
        key, sep, values = item.partition("=")
        key = key.strip()
        if not sep or not key or not values.strip():
            raise ValueError(f"--grid {item!r}: expected KEY=V1,V2,...")
        if key in grid:
            raise ValueError(f"--grid: key {key!r} given twice")
        vals = []
        for v in _split_top(values):
            try:
                vals.append(yaml.safe_load(v))
            except yaml.YAMLError as e:
                raise ValueError(f"--grid {item!r}: value {v!r} is not valid YAML ({e})") from None
        grid[key] = [_number(v) for v in vals]
    return grid


def _number(v: Any) -> Any:
    """YAML 1.1 reads ``3e-4`` as a string: numbers written so become floats."""
    if isinstance(v, str):
        try:
            return float(v)
        except ValueError:
            return v
    return v


def grid_configs(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of the grid, in order (last key fastest); ``[{}]`` for no grid."""
    keys = list(grid)
    return [dict(zip(keys, vals, strict=True)) for vals in itertools.product(*(grid[k] for k in keys))]


def apply_overrides(entry: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of ``entry`` with ``overrides`` set (``a.b`` sets ``entry["a"]["b"]``)."""
    out = copy.deepcopy(dict(entry))
    for key, value in overrides.items():
        *path, last = key.split(".")
        node = out
        for p in path:
            child = node.get(p)
            if child is None:
                child = node[p] = {}
            if not isinstance(child, dict):
                raise ValueError(f"--grid {key}: {p!r} of the entry is not a mapping ({child!r})")
            node = child
        node[last] = copy.deepcopy(value)
    return out


def config_label(overrides: Mapping[str, Any]) -> str:
    """``lr=0.0003 gamma=0.97`` style label of a grid point (``default`` for none)."""
    return " ".join(f"{k}={v}" for k, v in overrides.items()) or "default"


@dataclass(frozen=True)
class Trial:
    """One training run of a sweep: a grid point (``config``: its index) and a seed."""

    index: int
    config: int
    seed: int
    overrides: dict[str, Any]
    entry: dict[str, Any]

    @property
    def name(self) -> str:
        """Folder name of the trial's run (``c00_seed3``)."""
        return f"c{self.config:02d}_seed{self.seed}"


def make_trials(
    entry: Mapping[str, Any], grid: Mapping[str, Sequence[Any]], seeds: Sequence[int]
) -> list[Trial]:
    """Every grid point x seed (grid point outer), each with its overridden entry."""
    trials = []
    for c, ov in enumerate(grid_configs(grid)):
        e = apply_overrides(entry, ov)
        for s in seeds:
            trials.append(Trial(len(trials), c, int(s), dict(ov), e))
    return trials


def check_trials(env_id: str, algo: str, trials: Sequence[Trial]) -> None:
    """Check every trial's entry before any trial starts (no Ray needed).

    Each distinct entry is split and built as :func:`agents.training.train` would
    (:func:`~agents.training.config.split_entry`, the algorithm's options), its hyperparameters
    must be arguments of the SB3 class, and its ``env_kwargs`` must make the environment.

    Raises:
        ValueError: naming the grid point and the key that is wrong.
    """
    import difflib
    import inspect

    import gymnasium as gym

    from agents.training.config import (
        RUN_KEYS,
        build_hyperparameters,
        check_algo_entry,
        split_entry,
    )
    from agents.training.sb3_archive import algo_class

    cls = algo_class(algo)
    params = set(inspect.signature(cls.__init__).parameters) - {"self", "env", "policy"}
    seen_env: list[Any] = []
    for t in trials:
        where = f"--grid point {t.overrides or '(the entry as it is)'}"
        try:
            run, hyper = split_entry(t.entry)
            check_algo_entry(algo, run, hyper)
            build_hyperparameters(hyper)
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None
        for key in sorted(set(hyper) - params):
            close = difflib.get_close_matches(key, [*params, *RUN_KEYS], n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"{where}: {key!r} is neither a run key nor an argument of {cls.__name__}{hint}")
        env_kwargs = dict(run.get("env_kwargs") or {})
        if env_kwargs not in seen_env:
            seen_env.append(env_kwargs)
            try:
                gym.make(env_id, **env_kwargs).close()
            except (TypeError, ValueError) as e:
                raise ValueError(f"{where}: env_kwargs {env_kwargs}: {e}") from None
