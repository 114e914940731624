"""The vector env (`mate.make_vec`): env i of a batch replays the single env seeded s + i step by
step (autoresets included), Gymnasium vector conventions, autoreset modes, validation, buffers."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mate
from mate.envs.vector import AutoresetMode
from mate.envs.vector_contract import INFO_KEYS

ID = 'MATE-4v8-9-v0'
SHORT = 9  # max_episode_steps of the autoreset tests: a few episodes in a few dozen steps


def _singles(count: int, seed: int, **overrides):
    envs = [mate.make(ID, **overrides) for _ in range(count)]
    first = [env.reset(seed=seed + i)[0] for i, env in enumerate(envs)]
    return envs, first


def _assert_row(vector_obs, i, single_obs, where=''):
    np.testing.assert_array_equal(vector_obs[0][i], single_obs[0], err_msg=f'camera obs, env {i} {where}')
    np.testing.assert_array_equal(vector_obs[1][i], single_obs[1], err_msg=f'target obs, env {i} {where}')


def _single_info(infos) -> dict:
    info = infos[1][0] if infos[1] else infos[0][0]
    return {key: info[key] for key in ('coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
                                       'num_delivered_cargoes')}


@pytest.mark.parametrize('num_envs, seed', [(1, 7), (4, 100)])
def test_env_i_replays_the_single_env_seeded_s_plus_i_across_autoresets(num_envs, seed):
    envs = mate.make_vec(ID, num_envs=num_envs, max_episode_steps=SHORT)
    singles, first = _singles(num_envs, seed, max_episode_steps=SHORT)
    obs, infos = envs.reset(seed=seed)
    for i in range(num_envs):
        _assert_row(obs, i, first[i], 'after reset')
    rng = np.random.default_rng(seed)
    single_done = [False] * num_envs
    resets = 0
    for t in range(2 * SHORT + 3):
        actions = envs.sample_actions(rng)
        obs, (camera_reward, target_reward), terminated, truncated, infos = envs.step(actions)
        np.testing.assert_array_equal(camera_reward, -target_reward)
        for i, single in enumerate(singles):
            if single_done[i]:  # NEXT_STEP: this step starts env i's next episode, actions ignored
                single_obs, single_infos = single.reset()  # no seed: the stream continues
                reward, term, trunc = 0.0, False, False
                resets += 1
            else:
                single_obs, (_, reward), term, trunc, single_infos = single.step((actions[0][i], actions[1][i]))
            _assert_row(obs, i, single_obs, f'at step {t}')
            assert (target_reward[i], terminated[i], truncated[i]) == (reward, term, trunc), (t, i)
            for key, value in _single_info(single_infos).items():
                assert infos[key][i] == value, (key, t, i)
            np.testing.assert_array_equal(envs.state()[i], single.state())
            np.testing.assert_array_equal(envs.obstacle_states[i], single.obstacle_states)
            np.testing.assert_array_equal(envs.remaining_cargoes[i], single.remaining_cargoes)
            single_done[i] = term or trunc
    assert resets == 2 * num_envs


def test_envs_that_finish_at_different_steps_and_partial_resets():
    """reset_mask mid-episode desynchronises the rows; each still replays its single env."""
    num_envs, seed = 3, 11
    envs = mate.make_vec(ID, num_envs=num_envs, max_episode_steps=SHORT)
    singles, _ = _singles(num_envs, seed, max_episode_steps=SHORT)
    envs.reset(seed=seed)
    rng = np.random.default_rng(0)
    single_done = [False] * num_envs
    for t in range(2 * SHORT):
        if t == 4:  # restart env 1 only, with its own new seed; env 2's stream continues
            mask = np.array([False, True, True])
            obs, _ = envs.reset(seed=[None, 50, None], options={'reset_mask': mask})
            _assert_row(obs, 1, singles[1].reset(seed=50)[0])
            _assert_row(obs, 2, singles[2].reset()[0])
            single_done[1] = single_done[2] = False
        actions = envs.sample_actions(rng)
        obs, _, terminated, truncated, _ = envs.step(actions)
        for i, single in enumerate(singles):
            if single_done[i]:
                single_obs, term, trunc = single.reset()[0], False, False
            else:
                single_obs, _, term, trunc, _ = single.step((actions[0][i], actions[1][i]))
            _assert_row(obs, i, single_obs, f'at step {t}')
            assert (terminated[i], truncated[i]) == (term, trunc)
            single_done[i] = term or trunc


def test_same_step_autoreset_reports_the_final_observation():
    envs = mate.make_vec(ID, num_envs=2, max_episode_steps=3, autoreset_mode='same_step')
    singles, _ = _singles(2, 5, max_episode_steps=3)
    envs.reset(seed=5)
    assert envs.metadata['autoreset_mode'] is AutoresetMode.SAME_STEP
    rng = np.random.default_rng(1)
    for t in range(7):
        actions = envs.sample_actions(rng)
        obs, (_, target_reward), terminated, truncated, infos = envs.step(actions)
        for i, single in enumerate(singles):
            single_obs, (_, reward), term, trunc, single_infos = single.step((actions[0][i], actions[1][i]))
            assert (target_reward[i], terminated[i], truncated[i]) == (reward, term, trunc)
            if term or trunc:
                assert infos['_final_obs'][i] and infos['_final_info'][i]
                _assert_row(tuple(np.stack([o]) for o in infos['final_obs'][i]), 0, single_obs, 'final')
                assert infos['final_info']['coverage_rate'][i] == _single_info(single_infos)['coverage_rate']
                single_obs, _ = single.reset()
            else:
                assert 'final_obs' not in infos or (not infos['_final_obs'][i] and infos['final_obs'][i] is None)
            _assert_row(obs, i, single_obs, f'at step {t}')
    assert t + 1 > 3


def test_disabled_autoreset_refuses_to_step_a_finished_env():
    envs = mate.make_vec(ID, num_envs=2, max_episode_steps=2, autoreset_mode=gym.vector.AutoresetMode.DISABLED)
    envs.reset(seed=0)
    envs.step(envs.sample_actions(0))
    _, _, _, truncated, _ = envs.step(envs.sample_actions(0))
    assert truncated.all()
    with pytest.raises(RuntimeError, match=r'envs \[0, 1\] finished'):
        envs.step(envs.sample_actions(0))
    envs.reset(options={'reset_mask': np.array([True, True])})
    envs.step(envs.sample_actions(0))


def test_gymnasium_vector_conventions():
    envs = mate.make_vec(ID, num_envs=3, observation_dtype=np.float32)
    assert isinstance(envs, gym.vector.VectorEnv) and envs.num_envs == 3
    nc, nt = envs.num_cameras, envs.num_targets
    assert envs.single_action_space[0].shape == (nc, 2) and envs.action_space[1].shape == (3, nt, 2)
    assert envs.observation_space[0].shape == (3,) + envs.single_observation_space[0].shape
    obs, infos = envs.reset(seed=0)
    assert obs[0].dtype == obs[1].dtype == np.float32
    assert envs.observation_space.contains(obs)
    assert envs.action_space.contains(envs.sample_actions(np.random.default_rng(0)))
    assert envs.state_space.contains(envs.state())
    obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
    assert rewards[0].shape == rewards[1].shape == terminated.shape == truncated.shape == (3,)
    assert terminated.dtype == truncated.dtype == bool
    assert set(infos) == set(INFO_KEYS) | {f'_{key}' for key in INFO_KEYS}
    assert all(infos[key].shape == (3,) for key in INFO_KEYS)
    single = mate.make(ID)
    single_obs, _ = single.reset(seed=1)
    float32_obs, _ = envs.reset(seed=0)
    np.testing.assert_array_equal(float32_obs[0][1], single_obs[0].astype(np.float32))


@pytest.mark.parametrize('preset', ['MATE-4v8-9-v0', 'MATE-2v4-0-v0'])
def test_sample_actions_draws_what_rng_uniform_draws(preset):
    envs = mate.make_vec(preset, num_envs=5)
    camera, target = envs.sample_actions(7)
    rng = np.random.default_rng(7)
    cam_box, tgt_box = envs.camera_action_space, envs.target_action_space
    np.testing.assert_array_equal(camera, rng.uniform(cam_box.low, cam_box.high, (5, envs.num_cameras, 2)))
    np.testing.assert_array_equal(target, rng.uniform(tgt_box.low, tgt_box.high, (5, envs.num_targets, 2)))
    again = envs.sample_actions(7)  # fresh arrays every call
    assert not np.shares_memory(camera, again[0]) and not np.shares_memory(target, again[1])


def test_a_copied_vector_env_steps_its_own_world():
    """The compiled step is bound to the env's own arrays on its first step; copies and pickles
    must bind to theirs (and leave the original alone)."""
    import copy
    import pickle
    envs = mate.make_vec(ID, num_envs=2, copy=True)
    envs.reset(seed=3)
    rng = np.random.default_rng(0)
    envs.step(envs.sample_actions(rng))
    twins = [copy.deepcopy(envs), pickle.loads(pickle.dumps(envs))]
    before = envs.state()
    actions = envs.sample_actions(rng)
    results = [twin.step(actions)[0] for twin in twins]
    np.testing.assert_array_equal(envs.state(), before)
    own = envs.step(actions)[0]
    for got in results:
        np.testing.assert_array_equal(got[0], own[0])
        np.testing.assert_array_equal(got[1], own[1])


def test_buffers_are_reused_unless_copy():
    envs = mate.make_vec(ID, num_envs=2)
    first, _ = envs.reset(seed=0)
    second, rewards, terminated, _, _ = envs.step(envs.sample_actions(0))
    assert second[0] is first[0] and second[1] is first[1]
    third, rewards_3, terminated_3, _, _ = envs.step(envs.sample_actions(1))
    assert rewards_3[1] is rewards[1] and terminated_3 is terminated
    copying = mate.make_vec(ID, num_envs=2, copy=True)
    first, _ = copying.reset(seed=0)
    before = first[0].copy()
    second, _, _, _, _ = copying.step(copying.sample_actions(0))
    assert second[0] is not first[0]
    np.testing.assert_array_equal(first[0], before)


def test_reset_seeding():
    envs = mate.make_vec(ID, num_envs=2)
    a, _ = envs.reset(seed=3)
    a = (a[0].copy(), a[1].copy())
    b, _ = envs.reset(seed=[3, 4])
    _assert_row(b, 0, (a[0][0], a[1][0]))
    _assert_row(b, 1, (a[0][1], a[1][1]))
    c, _ = envs.reset()  # continues the streams: a new episode
    assert not np.array_equal(c[0], a[0])
    fresh = mate.make_vec(ID, num_envs=2)
    d, _ = fresh.reset()  # never seeded: OS entropy, rows differ
    assert not np.array_equal(d[0][0], d[0][1])
    with pytest.raises(ValueError, match='got 3 seeds for num_envs=2'):
        envs.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match='reset_mask'):
        envs.reset(options={'reset_mask': np.array([1, 0])})
    with pytest.raises(ValueError, match=r"reset takes only the option 'reset_mask', got \['mask'\]"):
        envs.reset(options={'mask': np.array([True, False])})   # a misspelt option is refused, not ignored


def test_invalid_actions_are_refused_clearly():
    envs = mate.make_vec(ID, num_envs=2)
    with pytest.raises(RuntimeError, match='reset'):
        envs.step(envs.sample_actions(0))
    envs.reset(seed=0)
    camera, target = envs.sample_actions(0)
    with pytest.raises(ValueError, match='pair'):
        envs.step((camera, target, target))
    with pytest.raises(ValueError, match=r'camera actions must have shape \(2, 4, 2\) .*; got \(4, 2\)'):
        envs.step((camera[0], target))
    bad = target.copy()
    bad[1, 3, 0] = np.nan
    with pytest.raises(ValueError, match=r'target actions contain NaN or inf \(envs \[1\]\)'):
        envs.step((camera, bad))
    with pytest.raises(ValueError, match='not numeric'):
        envs.step((camera, 'fast'))
    envs.step((camera.reshape(2, -1), target))  # (B, 2 Nc) is unambiguous and accepted (docs/vector.md)


# The right number of values in the wrong shape: refused, never reshaped (issue 30). B = 2, Nc = 4, Nt = 8.
VECTOR_WRONG_SHAPES = [
    ('camera', (2, 2, 4)),   # (B, 2, Nc): transposed per env
    ('camera', (4, 2, 2)),   # (Nc, B, 2)
    ('camera', (8, 2)),      # (B Nc, 2)
    ('camera', (16,)),       # flat
    ('target', (2, 2, 8)),
    ('target', (2, 8, 2, 1)),
    ('target', (32,)),
]


@pytest.mark.parametrize('team, shape', VECTOR_WRONG_SHAPES, ids=[f'{t}-{s}' for t, s in VECTOR_WRONG_SHAPES])
def test_actions_of_the_right_size_but_the_wrong_shape_are_refused(team, shape):
    envs = mate.make_vec(ID, num_envs=2)
    envs.reset(seed=0)
    camera, target = envs.sample_actions(0)
    state = envs.state()
    actions = (camera.reshape(shape), target) if team == 'camera' else (camera, target.reshape(shape))
    expected = ('(2, 4, 2) (num_envs x 4 cameras x [rotate, zoom]) or (2, 8)' if team == 'camera' else
                '(2, 8, 2) (num_envs x 8 targets x [dx, dy]) or (2, 16)')
    with pytest.raises(ValueError) as error:
        envs.step(actions)
    assert str(error.value) == f'{team} actions must have shape {expected}; got {shape}'
    np.testing.assert_array_equal(envs.state(), state)   # nothing was stepped
    # the accepted forms: (B, N, 2) of any real dtype and (B, 2N), the same actions either way
    reference = mate.make_vec(ID, num_envs=2)
    reference.reset(seed=0)
    expected_obs = reference.step((camera, target))[0]
    observations = envs.step((camera.reshape(2, -1), target.reshape(2, -1)))[0]
    np.testing.assert_array_equal(observations[0], expected_obs[0])
    np.testing.assert_array_equal(observations[1], expected_obs[1])
    envs.step((np.zeros((2, 4, 2), dtype=np.int32), target.tolist()))


def test_ragged_actions_are_refused_as_a_wrong_shape():
    envs = mate.make_vec(ID, num_envs=2)
    envs.reset(seed=0)
    camera, target = envs.sample_actions(0)
    with pytest.raises(ValueError, match=r'target actions must have shape \(2, 8, 2\) .*; got a ragged sequence'):
        envs.step((camera, [target[0].tolist(), target[1, :7].tolist()]))


def test_make_vec_arguments():
    with pytest.raises(ValueError, match="Did you mean 'MATE-4v8-9-v0'"):
        mate.make_vec('MATE-4v8-9-v1', num_envs=2)
    with pytest.raises(ValueError, match='num_envs'):
        mate.make_vec(ID, num_envs=0)
    with pytest.raises(ValueError, match='observation_dtype'):
        mate.make_vec(ID, num_envs=1, observation_dtype=np.int32)
    with pytest.raises(ValueError, match='autoreset_mode'):
        mate.make_vec(ID, num_envs=1, autoreset_mode='sometimes')
    envs = mate.make_vec('MATE-2v4-0-v0', num_envs=2, max_episode_steps=5)
    assert (envs.num_cameras, envs.num_targets, envs.num_obstacles, envs.max_episode_steps) == (2, 4, 0, 5)
    assert 'num_envs=2' in repr(envs)


@pytest.mark.parametrize('seed, message', [
    (-1, 'seed must be a non-negative integer or None, got -1'),
    ('x', "seed must be a non-negative integer, a list of 2 seeds or None, got 'x'"),
    (True, 'seed must be a non-negative integer, a list of 2 seeds or None, got True'),
    ([1, -3], r'each seed must be a non-negative integer or None, got \[1, -3\]'),
    ([1, 'a'], "each seed must be a non-negative integer or None"),
    ([1, 2, 3], 'got 3 seeds for num_envs=2'),
])
def test_a_bad_seed_is_refused_in_one_line_naming_the_valid_forms(seed, message):
    """The CPU env's refusals are the device env's (`mate.envs.vector_contract.row_seeds_of`, one rule for both)."""
    envs = mate.make_vec('MultiAgentTracking-v0', 2, config='MATE-2v4-0')
    with pytest.raises(ValueError, match=message):
        envs.reset(seed=seed)
    envs.reset(seed=[3, None])                         # a list with Nones: those games' streams go on
