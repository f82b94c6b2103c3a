"""Chunks in forked workers (agents.workers): a tuning grid's scores as one process's, errors surfaced."""

from __future__ import annotations

import os

import pytest

from agents.tuning import tune
from agents.tuning.cli import strategy_of
from agents.tuning.search import LocalTuneStrategy
from agents.workers import can_fork, default_workers, map_chunks
from filters.core.threads import get_num_threads, num_threads

FADING = "navgym/GpsInsFading-v0"
KW = {"max_episode_steps": 30}
forked = pytest.mark.skipif(not can_fork(), reason="no fork start method here")


@forked
def test_forked_chunks_come_back_in_order_from_other_processes():
    seen = []
    out = map_chunks(lambda i: (i * i, os.getpid()), 5, workers=2, on_done=seen.append)
    assert [v for v, _ in out] == [0, 1, 4, 9, 16]
    assert os.getpid() not in {pid for _, pid in out}  # run in the workers, not here
    assert sorted(seen) == [0, 1, 2, 3, 4]


@forked
def test_workers_share_the_parents_threads():
    with num_threads(5):
        out = map_chunks(lambda i: get_num_threads(), 4, workers=2)
        assert get_num_threads() == 5  # the parent's count is left alone
    assert out == [2, 2, 2, 2]  # 5 threads over 2 workers
    with num_threads(1):
        assert map_chunks(lambda i: get_num_threads(), 2, workers=2) == [1, 1]


def test_one_worker_runs_here_in_order():
    seen = []
    out = map_chunks(lambda i: (i, os.getpid()), 3, workers=1, on_done=seen.append)
    assert out == [(0, os.getpid()), (1, os.getpid()), (2, os.getpid())] and seen == [0, 1, 2]


@forked
def test_a_failing_chunk_raises_its_error():
    def job(i: int) -> int:
        if i == 2:
            raise KeyError(f"chunk {i}")
        return i

    with pytest.raises(KeyError, match="chunk 2"):
        map_chunks(job, 4, workers=2)


def test_workers_below_one_are_refused():
    with pytest.raises(ValueError, match="workers must be at least 1; got 0"):
        map_chunks(lambda i: i, 2, workers=0)
    with pytest.raises(ValueError, match="workers must be at least 1; got 0"):
        tune(FADING, "suboptimal", {"rho": (0.5,), "beta": (1.0,)}, episodes=2, env_kwargs=KW, workers=0)


@forked
def test_tuning_with_workers_equals_one_process():
    """Four chunks of one grid point each (max_batch = episodes), scored by 2 workers and by 1."""
    grid = {"rho": (0.5, 0.9), "beta": (1.0, 3.0)}
    kw = {"episodes": 3, "env_kwargs": KW, "progress": False, "max_batch": 3}
    one = tune(FADING, "suboptimal", grid, workers=1, **kw)
    two = tune(FADING, "suboptimal", grid, workers=2, **kw)
    assert one["grid"] == two["grid"] and one["params"] == two["params"]
    assert len({r["mean_return"] for r in one["grid"]}) == 4  # the points do differ


def test_the_command_picks_its_workers():
    import argparse

    def args(**kw):
        base = {"ray": False, "samples": None, "address": None, "workers": None}
        return argparse.Namespace(**{**base, **kw})

    assert strategy_of(args()) == LocalTuneStrategy(default_workers())
    assert strategy_of(args(workers=3)) == LocalTuneStrategy(3)
    with pytest.raises(ValueError, match="--workers must be at least 1"):
        strategy_of(args(workers=0))
    with pytest.raises(ValueError, match="--workers goes without --ray"):
        strategy_of(args(ray=True, workers=2))
