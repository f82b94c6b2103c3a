"""Registry-wide environment contracts (docs/architecture.md, "Environment contracts")."""

import copy
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import navgym
from navgym.envs.registration import ENVIRONMENTS, V1_PENALTY, V1_RESAMPLE

IDS = [e[0] for e in ENVIRONMENTS]
SHORT = {"max_episode_steps": 60}


def _actions(space, n, seed):
    space.seed(seed)
    return [space.sample() for _ in range(n)]


def test_registration_is_idempotent():
    before = {k for k in gym.registry if k.startswith("navgym/")}
    navgym.envs.register_all()
    navgym.envs.register_all()
    assert {k for k in gym.registry if k.startswith("navgym/")} == before == set(IDS)
    for env_id in IDS:
        spec = gym.spec(env_id)
        assert spec.vector_entry_point is not None and spec.max_episode_steps > 0


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_and_sb3_checkers(env_id):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make(env_id, **SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a checker warning is a failure
        check_env(env.unwrapped, skip_render_check=True)
        sb3_check(env.unwrapped, warn=True)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_episode_and_pickle(env_id):
    acts = _actions(gym.make(env_id).action_space, 25, 3)
    traces = []
    for _ in range(2):
        env = gym.make(env_id, **SHORT)
        obs, _ = env.reset(seed=42)
        trace = [obs]
        for a in acts:
            obs, r, term, trunc, info = env.step(a)
            trace.append(np.append(obs, [r, term, trunc, info["pos_err_m"]]))
            if term or trunc:
                break
        traces.append(np.concatenate([np.ravel(t) for t in trace]))
    np.testing.assert_array_equal(traces[0], traces[1])
    # A pickled copy continues exactly like the original.
    env = gym.make(env_id, **SHORT)
    env.reset(seed=7)
    for a in acts[:5]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in acts[5:12]:
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = clone.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2


@pytest.mark.parametrize("env_id", IDS)
def test_long_rollout_observations_finite_and_inside_space(env_id):
    """Random actions over whole episodes with outages forced on: obs finite, inside the box."""
    env = gym.make(env_id, max_episode_steps=150, outage_probability=1.0)
    space = env.observation_space
    obs, _ = env.reset(seed=5)
    terminated_or_truncated = 0
    for a in _actions(env.action_space, 300, 1):
        assert obs.dtype == np.float32 and np.isfinite(obs).all() and space.contains(obs)
        obs, r, term, trunc, info = env.step(a)
        assert np.isfinite(r)
        assert set(info["reward_terms"]) == {"accuracy", "cost", "divergence_penalty"}
        assert r == pytest.approx(sum(info["reward_terms"].values()))
        if term or trunc:
            terminated_or_truncated += 1
            obs, _ = env.reset()
    assert terminated_or_truncated >= 1


@pytest.mark.parametrize("env_id", IDS)
def test_divergence_terminates_with_penalty(env_id):
    env = gym.make(env_id, divergence_m=1e-3, divergence_penalty=100.0)
    obs, _ = env.reset(seed=0)
    obs, r, term, trunc, info = env.step(env.action_space.sample())
    assert term and not trunc and info["diverged"]
    core = env.unwrapped.core
    remaining = core.T - 1 if core.penalize_remaining_steps else 0
    expected = 100.0 + core.reward_clip * remaining
    assert info["reward_terms"]["divergence_penalty"] == -expected
    assert np.isfinite(obs).all() and env.observation_space.contains(obs)


@pytest.mark.parametrize("env_id", ["navgym/GpsInsFading-v1", "navgym/Robot2dResample-v1"])
def test_v1_penalty_is_the_same_in_single_and_vector_envs_under_a_shorter_limit(env_id):
    kw = {"divergence_m": 1e-3, "max_episode_steps": 50}
    env = gym.make(env_id, **kw)
    env.reset(seed=0)
    _, r, term, _, info = env.step(env.action_space.sample() * 0)
    venv = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", **kw)
    venv.reset(seed=0)
    _, rv, tv, _, iv = venv.step(venv.action_space.sample() * 0)
    T = env.unwrapped.core.T
    assert term and tv[0] and venv.unwrapped.core.truncate_steps == 50 < T
    assert info["reward_terms"]["divergence_penalty"] == -(100.0 + 10.0 * (T - 1))
    assert rv[0] == r


@pytest.mark.parametrize("env_id", [i for i in IDS if i.endswith("-v1")])
def test_v1_divergence_never_beats_finishing_the_episode(env_id):
    """With the remaining-steps penalty, diverging at the first step scores below the worst
    return an episode that survives to the horizon can get (every step clipped, every cost paid)."""
    env = gym.make(env_id, divergence_m=1e-3)
    core = env.unwrapped.core
    assert core.penalize_remaining_steps
    env.reset(seed=0)
    _, r, term, _, info = env.step(env.action_space.sample())
    assert term
    worst_surviving = -(core.reward_clip + getattr(core.task, "resample_cost", 0.0)) * core.truncate_steps
    assert r < worst_surviving


def test_every_v0_has_a_v1_that_changes_only_its_documented_defaults():
    by_id = {e[0]: e for e in ENVIRONMENTS}
    v0_ids = [i for i in IDS if i.endswith("-v0")]
    assert sorted(i[:-1] + "1" for i in v0_ids) == sorted(i for i in IDS if i.endswith("-v1"))
    for v0_id in v0_ids:
        v0, v1 = by_id[v0_id], by_id[v0_id[:-1] + "1"]
        assert v1[1:5] == v0[1:5]  # module, class, task, episode steps
        changes = V1_RESAMPLE if v0[3] == "resample" else V1_PENALTY
        assert v1[5] == {**v0[5], **changes}
        assert not gym.make(v0_id).unwrapped.core.penalize_remaining_steps


@pytest.mark.parametrize("env_id", IDS)
def test_non_finite_action_raises(env_id):
    env = gym.make(env_id, **SHORT)
    env.reset(seed=0)
    space = env.action_space
    if isinstance(space, gym.spaces.Box):
        with pytest.raises(ValueError, match="finite"):
            env.unwrapped.step(np.full(space.shape, np.nan, dtype=np.float32))
        obs, r, term, trunc, info = env.unwrapped.step(np.full(space.shape, 3.0, dtype=np.float32))
        assert info["action_clipped"]
    else:
        with pytest.raises(ValueError):
            env.unwrapped.step(np.float64(np.nan))
        with pytest.raises(ValueError):
            env.unwrapped.step(2)
        for not_an_integer in (0.9, 0.4, 1.7):  # no silent rounding towards 0
            with pytest.raises(ValueError, match="0 or 1"):
                env.unwrapped.step(np.float64(not_an_integer))
        env.unwrapped.step(np.float64(1.0))  # an integral float is the decision it names


@pytest.mark.parametrize("env_id", IDS)
def test_vector_sub_env_i_equals_single_env_seeded_s_plus_i(env_id):
    B, seed, steps = 3, 11, 30
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", **SHORT)
    singles = [gym.make(env_id, **SHORT) for _ in range(B)]
    vobs, _ = venv.reset(seed=seed)
    for i, e in enumerate(singles):
        np.testing.assert_allclose(vobs[i], e.reset(seed=seed + i)[0], rtol=1e-12, atol=0)
    done = np.zeros(B, dtype=bool)
    for a in _actions(venv.action_space, steps, 2):
        vobs, vr, vterm, vtrunc, _ = venv.step(a)
        for i, e in enumerate(singles):
            if done[i]:
                continue  # the vector env autoresets this index from here on
            o, r, term, trunc, _ = e.step(a[i])
            np.testing.assert_allclose(vobs[i], o, rtol=1e-12, atol=0)
            assert vr[i] == pytest.approx(r, rel=1e-12) and vterm[i] == term and vtrunc[i] == trunc
            done[i] = term or trunc


@pytest.mark.parametrize("env_id", IDS)
def test_vector_sub_env_equals_single_env_across_autoresets(env_id):
    """Episodes after the first too: sub-env i continues as the single env reset() without a seed.

    Also checks that no returned observation is changed afterwards (the core's buffers are
    not handed out and then overwritten by a reset).
    """
    B, seed, steps, limit = 2, 5, 11, 4
    venv = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", max_episode_steps=limit)
    singles = [gym.make(env_id, max_episode_steps=limit) for _ in range(B)]
    vobs, _ = venv.reset(seed=seed)
    sobs = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    returned = [(vobs, vobs.copy())] + [(o, o.copy()) for o in sobs]
    done = np.zeros(B, dtype=bool)
    for a in _actions(venv.action_space, steps, 4):
        vobs, _, vterm, vtrunc, _ = venv.step(a)
        returned.append((vobs, vobs.copy()))
        for i, e in enumerate(singles):
            if done[i]:
                o, _ = e.reset()
                done[i] = False
            else:
                o, _, term, trunc, _ = e.step(a[i])
                assert vterm[i] == term and vtrunc[i] == trunc
                done[i] = term or trunc
            returned.append((o, o.copy()))
            np.testing.assert_array_equal(vobs[i], o)
    for obs, copy_at_return in returned:
        np.testing.assert_array_equal(obs, copy_at_return)


@pytest.mark.parametrize("env_id", IDS[:1])
def test_vector_env_autoresets_next_step(env_id):
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=5)
    venv.reset(seed=0)
    a = np.zeros((2, 1), np.float32)
    for _ in range(5):
        obs, r, term, trunc, info = venv.step(a)
    assert trunc.all()
    obs, r, term, trunc, info = venv.step(a)  # the reset step
    assert (r == 0).all() and not term.any() and not trunc.any() and not info["_pos_err_m"].any()
    single = gym.make(env_id, max_episode_steps=5)
    single.reset(seed=0)
    for _ in range(5):
        single.step(a[0])
    np.testing.assert_array_equal(obs[0], single.reset()[0])  # same generator, same next episode


@pytest.mark.parametrize("env_id", ["navgym/GpsInsFading-v0", "navgym/Robot2dResample-v0"])
def test_partial_autoreset_replaces_only_the_finished_sub_env(env_id):
    """A sub-env that diverges alone is reset alone; the others continue their episodes."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=50)
    venv.reset(seed=3)
    core = venv.unwrapped.core
    a = venv.action_space.sample() * 0
    venv.step(a)
    before = copy.deepcopy(core.episodes)
    t_before = core.t.copy()
    venv.unwrapped._autoreset[:] = [False, True, False]  # as if sub-env 1 had just ended
    venv.step(a)
    assert core.t.tolist() == [t_before[0] + 1, 0, t_before[2] + 1]
    changed = False
    for x, y in zip(before, core.episodes, strict=True):
        if isinstance(x, np.ndarray) and x.dtype.kind == "f" and x.ndim >= 2 and x.shape[0] == 3:
            np.testing.assert_array_equal(x[[0, 2]], y[[0, 2]])  # untouched episodes
            changed |= not np.array_equal(x[1], y[1])  # the reset row holds a new episode
    assert changed


def test_superseded_ids_quiet_silences_only_the_v0_notice():
    from navgym.envs.registration import superseded_ids_quiet

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with superseded_ids_quiet():
            gym.make("navgym/GpsInsFading-v0")
            warnings.warn("unrelated", DeprecationWarning, stacklevel=1)
        gym.make("navgym/GpsInsFading-v0")
    messages = [str(w.message) for w in caught]
    assert sum("navgym/GpsInsFading-v0 is out of date" in m for m in messages) == 1  # the one outside
    assert "unrelated" in messages


def _fading_features(module):
    """The card's reference table: the module's Fading id, else its first id (Iridium has no Fading)."""
    ids = [e for e in ENVIRONMENTS if e[1] == module]
    env_id = next((e[0] for e in ids if e[3] == "fading"), ids[0][0])
    with navgym.envs.registration.superseded_ids_quiet():
        return gym.make(env_id).unwrapped.core.obs_features


@pytest.mark.parametrize("env_id", IDS)
def test_card_documents_the_observation_of_every_id(env_id):
    """The card gives each id's column count and, against the Fading table, its changed columns."""
    import re

    from navgym.envs.core import SIGMA_DIVERGENCE

    with navgym.envs.registration.superseded_ids_quiet():
        env = gym.make(env_id)
    doc = type(env.unwrapped).__doc__
    assert not any(p in doc for p in ("{observation_table}", "{SIGMA_DIVERGENCE}", "{version_history}"))
    flat = " ".join(doc.split())
    assert f"SIGMA_DIVERGENCE = {SIGMA_DIVERGENCE:g}" in flat  # the covariance divergence rule
    section = flat[flat.index("## Observation Space") : flat.index("## Rewards")]
    short = f"``{env_id.removeprefix('navgym/')}``"
    entry = next(c for c in section.split(" * ") if short in c and "columns)" in c)
    fs, ref = env.unwrapped.core.obs_features, _fading_features(env.spec.entry_point.split(":")[0])
    assert f"({fs.dim} columns)" in entry
    if fs.names == ref.names:  # the Fading table itself
        assert all(f"| {name} |" in section for name in fs.names)
        return
    ref_size = {f.name: f.size for f in ref.features}
    for name in ref.names:
        if name not in fs.names:
            assert re.search(rf"without [^;]*``{name}``", entry), name
    for f in fs.features:
        i = fs.index(f.name)
        if f.name not in ref_size:
            span = f"{i.start}" if f.size == 1 else f"{i.start}-{i.stop - 1}"
            assert f"adds ``{f.name}`` (index {span}," in entry, f.name
        elif f.size != ref_size[f.name]:
            assert f"``{f.name}`` has {f.size} columns ({i.start}-{i.stop - 1})" in entry, f.name


def test_a_pinned_scenario_must_describe_the_episode():
    from navgym.scenarios import Scenario, critical_scenario

    env = gym.make("navgym/GpsInsFading-v1")
    with pytest.raises(ValueError, match="lasts 50 s but the episode 300 s"):
        env.reset(seed=0, options={"scenario": Scenario(duration=50.0)})
    with pytest.raises(ValueError, match="lasts 3600 s"):
        env.reset(seed=0, options={"scenario": critical_scenario()})
    with pytest.raises(TypeError, match="must be a navgym.scenarios.Scenario"):
        env.reset(seed=0, options={"scenario": {"duration": 300.0}})
    env.reset(seed=0, options={"scenario": Scenario(duration=300.0)})  # the right length is taken
