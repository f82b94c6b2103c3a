"""``navgym eval --env-kwargs``: a JSON object or ``key=value`` pairs."""

from __future__ import annotations

import pytest

from agents.evaluation.cli import _env_kwargs


def test_key_value_pairs_and_json_give_the_same_kwargs():
    assert _env_kwargs("recording=/data/walk,sigma_pos=0.2,clairvoyant=true") == {
        "recording": "/data/walk",
        "sigma_pos": 0.2,
        "clairvoyant": True,
    }
    assert _env_kwargs('{"recording": "/data/walk"}') == {"recording": "/data/walk"}
    assert _env_kwargs("{}") == {}


@pytest.mark.parametrize("text", ["recording", "=x", "[1, 2]", "a=1,,b=2"])
def test_neither_json_nor_pairs_is_refused(text):
    with pytest.raises(ValueError, match="--env-kwargs must be a JSON object or key=value pairs"):
        _env_kwargs(text)
