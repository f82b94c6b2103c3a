"""A toy task and a toy platform, each registered by one line (docs/add_a_task.md, docs/add_a_platform.md).

``toy_task.py`` declares the ``RScale`` task and registers it (``register_task(TaskSpec(...))``,
its last statement); ``toy_platform.py`` declares the ``ToyPlugin`` platform (``toy.py``'s
problem) with the toy task among its tasks, and its registry entries. The tests register the
platform with one line, ``register_platform(ENTRIES)`` or an entry point of the group
``navgym.platforms``, and check that nothing else was needed: the ids are made and pass
Gymnasium's checker, the vector env equals the single envs, the card fills itself, ``navgym
list`` lists the ids, and the keyword fuzz fuzzes the toy task's arguments.
"""

from __future__ import annotations

from dataclasses import replace
from importlib import metadata
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from navgym.cli import main as navgym_cli
from navgym.envs import registration
from navgym.envs.registration import ENVIRONMENTS, PLATFORM_GROUP, register_all, register_platform
from navgym.envs.tasks import make_task, task_spec
from tests.navgym.envs import toy_platform, toy_task
from tests.navgym.envs.test_kwargs_fuzz import CORE, attempt, task_table
from tests.navgym.envs.vector_twins import assert_vector_equals_singles

IDS = ["navgym-test/ToyPluginFading-v0", "navgym-test/ToyPluginRScale-v0"]


@pytest.fixture
def restored_registry():
    """Whatever a test registers is gone afterwards (navgym's registry and Gymnasium's)."""
    saved = list(registration.ENVIRONMENTS)
    platforms = list(registration._PLATFORMS)
    loaded = set(registration._LOADED)
    yield
    known = {e.id for e in saved}
    for e in registration.ENVIRONMENTS:
        if e.id not in known:
            gym.registry.pop(e.id, None)
    registration.ENVIRONMENTS[:] = saved
    registration._PLATFORMS[:] = platforms
    registration._LOADED.clear()
    registration._LOADED.update(loaded)


@pytest.fixture
def registered(restored_registry):
    return register_platform(toy_platform.ENTRIES)  # the platform's one registration line


def test_one_line_registers_each():
    """The task's module registers it in one statement; the platform needs one call (the fixture)."""
    text = Path(toy_task.__file__).read_text()
    assert text.count("register_task(") == 1
    assert task_spec("rscale") is toy_task.R_SCALE and task_spec("RScale").title == "RScale"
    task = make_task("rscale", decades=2.0)
    assert task.baseline_family == "RScale" and task.filter_name == "ekf"
    assert not any(e.prefix == "ToyPlugin" for e in ENVIRONMENTS)  # nothing until registered


def test_the_ids_are_made_and_pass_the_checkers(registered):
    assert registered == IDS
    for env_id in IDS:
        env = gym.make(env_id)
        check_env(env.unwrapped, skip_render_check=True)
        assert env.spec.max_episode_steps == 60
        assert_vector_equals_singles(env_id, 3, 5, 8)
    env = gym.make(IDS[1])
    env.reset(seed=0)
    *_, info = env.step(np.array([0.5], np.float32))
    assert info["r_scale"] == pytest.approx(10**0.5) and info["knob"] == pytest.approx(10**0.5)
    assert set(info["reward_terms"]) == {"accuracy", "cost", "divergence_penalty"}


def test_registration_needed_nothing_else(registered):
    # listed after navgym's own ids, made by the classes the entries name
    assert [e.id for e in ENVIRONMENTS][-2:] == IDS
    assert gym.spec(IDS[1]).entry_point == "tests.navgym.envs.toy_platform:ToyPluginEnv"
    # the card fills itself, from the task specs and the registered ids
    doc = " ".join(toy_platform.ToyPluginEnv.__doc__.split())
    assert "{" not in doc.replace('{"scenario"', "")
    assert "``RScale``: ``Box(-1, 1, (1,), float32)``, ``R' = 10 ** (decades a) R`` every 1 s." in doc
    assert '``RScale``: ``filter="ekf"``, ``decades=1.0``' in doc and "clairvoyant=True``" in doc
    assert "navgym-test/ToyPluginRScale-v0" in doc and "adds ``log_r_scale``" in doc
    # the keyword fuzz fuzzes the toy task's arguments from their declaration
    table = task_table("rscale")
    assert set(table) == {"filter", "decades", "clairvoyant"}
    outcomes = [attempt(gym.make, IDS[1], k, v) for k, arg in {**table, **CORE}.items() for v in arg.bad]
    wrong = [f"{o.argument}={o.value!r}: {o.error!r}" for o in outcomes if not o.named]
    assert not wrong, wrong


def test_an_entry_point_registers_a_platform_for_the_cli(restored_registry, monkeypatch, capsys):
    real = metadata.entry_points

    def entry_points(**params):
        if params.get("group") == PLATFORM_GROUP:
            return [metadata.EntryPoint("toy", "tests.navgym.envs.toy_platform:ENTRIES", PLATFORM_GROUP)]
        return real(**params)

    monkeypatch.setattr(metadata, "entry_points", entry_points)
    assert set(IDS) <= set(register_all())
    assert register_all()[-2:] == IDS  # loaded once
    assert navgym_cli(["list"]) == 0
    out = capsys.readouterr().out
    rscale = next(line for line in out.splitlines() if IDS[1] in line)
    assert "| rscale " in rscale and "| ekf " in rscale and "60 x 1 s" in rscale


#: Entries whose id is navgym's own, with another horizon (a clash).
CLASHING = [replace(ENVIRONMENTS[0], steps=1)]


def test_a_broken_or_clashing_entry_point_warns_and_is_skipped(restored_registry, monkeypatch):
    points = [
        metadata.EntryPoint("broken", "tests.navgym.envs.no_such_module:ENTRIES", PLATFORM_GROUP),
        metadata.EntryPoint("clash", f"{__name__}:CLASHING", PLATFORM_GROUP),
        metadata.EntryPoint("same", "navgym.robot2d.env_ids:ENTRIES", PLATFORM_GROUP),  # equal: nothing new
    ]
    monkeypatch.setattr(metadata, "entry_points", lambda **params: points)
    before = [e.id for e in ENVIRONMENTS]
    with pytest.warns(RuntimeWarning) as caught:
        register_all()
    text = " ".join(str(w.message) for w in caught)
    assert len(caught) == 2 and "'broken'" in text and "failed to load" in text
    assert "'clash'" in text and "taken already" in text
    assert [e.id for e in ENVIRONMENTS] == before and gym.spec(before[0]).max_episode_steps != 1
    with pytest.raises(ValueError, match="registered already with other entries"):
        register_platform(CLASHING)
