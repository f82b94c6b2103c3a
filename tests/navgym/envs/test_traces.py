"""Every registered id reproduces its stored traces (``traces.py``) to rounding.

The traces were recorded before the platform skeleton refactoring; a change that alters an id's
observations, rewards, episode ends or position errors fails here (re-record only with a
version bump of the ids it changes).

The traces were recorded on the NumPy path of ``filters/``. The particle ids (``*Resample*``,
and ``*Jumps*`` whose Dirac-Gauss PF resamples its per-particle EKFs) are held to them on that
path (``filters.core.compiled.numpy_only``); on the compiled path their particles differ at
rounding level, and systematic resampling is discontinuous in such differences, so a few
sub-environments' particle paths branch (GpsInsResample-v1: 24 of 160
position errors differ by more than 1 mm, the first after one step): there the test holds the
episode ends equal and the mean position error to the stored one's.

A failure states the version rule (Gymnasium's convention, see CHANGELOG's header): a change of
a registered id's numbers needs a new version, ``-v<k+1>`` registered with the change, and the
old id's numbers left alone; a registered id without a recorded trace fails with the command
that records it.
"""

from collections.abc import Callable, Mapping
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import pytest

from filters.core.compiled import numpy_only
from navgym.envs.registration import ENVIRONMENTS
from tests.navgym.envs import traces

#: The particle-filter ids: the Resample tasks' bootstrap PFs and the Jumps task's Dirac-Gauss PF
#: (a bank of per-particle EKFs whose updates take the compiled observed-subspace kernel).
PARTICLE_IDS = [e[0] for e in ENVIRONMENTS if "Resample" in e[0] or "Jumps" in e[0]]


def version_rule(env_id: str) -> str:
    """The rule a changed trace of ``env_id`` breaks, and what to do instead."""
    return (
        f"{env_id}: its recorded trace ({traces.path(env_id).name}) changed. A change of a registered "
        "id's numbers (observations, rewards, episode ends, position errors) needs a new version: "
        "register the next version (-v<k+1>) with the change, leave the old id's numbers alone, "
        f"and record the new id's trace (python -m tests.navgym.envs.traces record <new id>); "
        "Gymnasium's convention, see CHANGELOG.md's header."
    )


def missing_trace(env_id: str) -> str:
    """The message for a registered id without a recorded trace."""
    return (
        f"{env_id} is registered but has no recorded trace ({traces.path(env_id)}); record it with: "
        f"python -m tests.navgym.envs.traces record {env_id}"
    )


def load_trace(env_id: str) -> Mapping[str, np.ndarray]:
    """The stored trace of ``env_id``; a missing one fails with the command that records it."""
    file: Path = traces.path(env_id)
    if not file.exists():
        pytest.fail(missing_trace(env_id), pytrace=False)
    return np.load(file)


def assert_same_trace(env_id: str, new: Mapping[str, np.ndarray], ref: Mapping[str, np.ndarray]) -> None:
    """Hold ``new`` equal to ``ref`` to rounding; a difference fails stating :func:`version_rule`."""
    _with_rule(env_id, lambda: _compare(new, ref))


def _with_rule(env_id: str, check: Callable[[], None]) -> None:
    try:
        check()
    except AssertionError as exc:
        raise AssertionError(f"{version_rule(env_id)}\n{exc}") from None


def _keys(ref: Mapping[str, np.ndarray]) -> set[str]:
    return set(ref.files) if hasattr(ref, "files") else set(ref)


def _compare(new: Mapping[str, np.ndarray], ref: Mapping[str, np.ndarray]) -> None:
    assert set(new) == _keys(ref), f"trace keys differ: {sorted(set(new) ^ _keys(ref))}"
    for key, a in new.items():
        b = ref[key]
        assert a.shape == b.shape, key
        if key.endswith(("terminated", "truncated")):
            np.testing.assert_array_equal(a, b, err_msg=key)
        elif key.endswith("obs"):
            np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6, err_msg=key)
        else:
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=key)


#: Particle ids whose trace is too short for the mean-error check (the Dirac-Gauss PF branches
#: within a few steps, its 160 errors vary 1-11 m): their compiled path is held to the NumPy
#: path's error statistics over 32 whole episodes instead
#: (``tests/navgym/signal_tracking/test_compiled_path.py``).
ERROR_STATISTICS_ELSEWHERE = ("navgym/SignalTrackingJumps-v2",)


def _compare_compiled_particles(
    new: Mapping[str, np.ndarray], ref: Mapping[str, np.ndarray], mean_error: bool = True
) -> None:
    for p in ("vec", "single"):
        for key in ("terminated", "truncated"):
            np.testing.assert_array_equal(new[f"{p}_{key}"], ref[f"{p}_{key}"], err_msg=key)
        np.testing.assert_allclose(new[f"{p}_obs"][0], ref[f"{p}_obs"][0], rtol=1e-5, atol=1e-5)
    if not mean_error:
        return
    errors = [np.concatenate([t[f"{p}_pos_err_m"].ravel() for p in ("vec", "single")]) for t in (new, ref)]
    assert abs(errors[0].mean() - errors[1].mean()) < 0.05 * errors[1].mean(), "mean position error"


@pytest.mark.parametrize("env_id", [e[0] for e in ENVIRONMENTS])
def test_traces_equal_to_rounding(env_id):
    ref = load_trace(env_id)
    with numpy_only() if env_id in PARTICLE_IDS else nullcontext():
        new = traces.run(env_id)
    assert_same_trace(env_id, new, ref)


@pytest.mark.parametrize("env_id", PARTICLE_IDS)
def test_particle_ids_on_the_compiled_path_keep_episode_ends_and_error_statistics(env_id):
    ref = load_trace(env_id)
    new = traces.run(env_id)
    mean_error = env_id not in ERROR_STATISTICS_ELSEWHERE
    _with_rule(env_id, lambda: _compare_compiled_particles(new, ref, mean_error))


def _fake_trace() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    out = {}
    for p in ("vec", "single"):
        out[f"{p}_obs"] = rng.normal(size=(4, 2, 3))
        out[f"{p}_reward"] = rng.normal(size=(4, 2))
        out[f"{p}_terminated"] = np.zeros((4, 2), bool)
        out[f"{p}_truncated"] = np.zeros((4, 2), bool)
        out[f"{p}_pos_err_m"] = rng.uniform(1, 2, size=(4, 2))
    return out


def test_a_changed_trace_fails_stating_the_version_rule():
    ref = _fake_trace()
    assert_same_trace("navgym/Fake-v3", {k: v.copy() for k, v in ref.items()}, ref)
    changed = {k: v.copy() for k, v in ref.items()}
    changed["vec_reward"][1, 0] += 1e-3
    with pytest.raises(AssertionError) as info:
        assert_same_trace("navgym/Fake-v3", changed, ref)
    text = str(info.value)
    assert "navgym/Fake-v3" in text and "needs a new version" in text and "-v<k+1>" in text
    assert "leave the old id's numbers alone" in text and "CHANGELOG" in text
    assert "vec_reward" in text
    ends = {k: v.copy() for k, v in ref.items()}
    ends["single_terminated"][2, 1] = True
    with pytest.raises(AssertionError, match="needs a new version"):
        _with_rule("navgym/Fake-v3", lambda: _compare_compiled_particles(ends, ref))


def test_a_registered_id_without_a_trace_fails_with_the_record_command(monkeypatch, tmp_path):
    monkeypatch.setattr(traces, "TRACE_DIR", tmp_path)
    with pytest.raises(pytest.fail.Exception) as info:
        load_trace("navgym/Fake-v3")
    assert "python -m tests.navgym.envs.traces record navgym/Fake-v3" in str(info.value)


def test_the_record_command_accepts_a_single_id(monkeypatch, tmp_path):
    monkeypatch.setattr(traces, "TRACE_DIR", tmp_path)
    monkeypatch.setattr(traces, "run", lambda env_id: _fake_trace())
    traces.main(["record", "navgym/Fake-v3"])
    assert [f.name for f in tmp_path.iterdir()] == ["Fake-v3.npz"]
