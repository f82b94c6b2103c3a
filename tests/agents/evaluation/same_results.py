"""Bit-for-bit equality of two evaluations of the same episodes (one process and split into parts)."""

from pathlib import Path

import numpy as np

from agents.evaluation.runner import EvalResults


def assert_same_results(
    split: EvalResults, one: EvalResults, split_out: Path, one_out: Path, parts: int
) -> None:
    """``split`` (run in ``parts`` parts, written to ``split_out``) equals ``one`` in every array and file."""
    assert split.config.pop("workers") == parts
    assert split.seeds == one.seeds and split.reference == one.reference
    assert split.policies == one.policies and split.config == one.config
    for name in one.episodes:
        for m, x in one.episodes[name].items():
            np.testing.assert_array_equal(x, split.episodes[name][m], err_msg=f"{name} {m}")
        for k, x in one.rollouts[name].steps.items():
            np.testing.assert_array_equal(x, split.rollouts[name].steps[k], err_msg=f"{name} {k}")
    np.testing.assert_equal(split.summary, one.summary)  # bootstrap CIs too (NaN == NaN here)
    np.testing.assert_equal(split.paired, one.paired)
    assert (split_out / "summary.csv").read_bytes() == (one_out / "summary.csv").read_bytes()
