"""A spy on the episodes' simulation (``navgym.envs.distinct._simulate``) for the reset tests."""

from typing import Any


def count_simulations(monkeypatch: Any) -> list[int]:
    """The rows of every simulation from now on (``monkeypatch``: pytest's fixture), in call order."""
    from navgym.envs import distinct

    calls: list[int] = []
    real = distinct._simulate
    monkeypatch.setattr(distinct, "_simulate", lambda p, r, s, T: calls.append(len(r)) or real(p, r, s, T))
    return calls
