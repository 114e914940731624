"""The `MultiAgentTracking` environment: dimensions, spaces, infos, rewards, input validation,
world snapshots, messages and reward bookkeeping (spec environment.md §3-§7, §11.1)."""

from __future__ import annotations

import numpy as np
import pytest

import mate
from mate import Message, Team
from mate.spaces import camera_observation_slices_of

# preset, N_c, N_t, N_o, camera obs, target obs, state, high-capacity targets (spec §11.1)
PRESET_TABLE = [
    ('1v1-0', 1, 1, 0, 34, 39, 54, 0),
    ('1v1-9', 1, 1, 9, 70, 75, 81, 0),
    ('1v2-0', 1, 2, 0, 39, 44, 70, 1),
    ('1v2-9', 1, 2, 9, 75, 80, 97, 1),
    ('2v2-0', 2, 2, 0, 46, 51, 79, 1),
    ('2v2-9', 2, 2, 9, 82, 87, 106, 1),
    ('2v4-0', 2, 4, 0, 56, 61, 111, 2),
    ('2v4-9', 2, 4, 9, 92, 97, 138, 2),
    ('4v2-0', 4, 2, 0, 60, 65, 97, 1),
    ('4v2-9', 4, 2, 9, 96, 101, 124, 1),
    ('4v4-0', 4, 4, 0, 70, 75, 129, 2),
    ('4v4-9', 4, 4, 9, 106, 111, 156, 2),
    ('4v8-0', 4, 8, 0, 90, 95, 193, 4),
    ('4v8-9', 4, 8, 9, 126, 131, 220, 4),
    ('8v8-0', 8, 8, 0, 118, 123, 229, 4),
    ('8v8-9', 8, 8, 9, 154, 159, 256, 4),
    ('Navigation', 0, 8, 32, 190, 195, 253, 4),
]

INFO_KEYS = {'raw_reward', 'normalized_raw_reward', 'messages', 'out_communication_edges',
             'in_communication_edges', 'coverage_rate', 'real_coverage_rate', 'mean_transport_rate',
             'num_delivered_cargoes', 'episode_coverage_rate', 'episode_real_coverage_rate',
             'episode_target_return'}


def _random_action(env, rng, scale=1.0):
    cam = rng.uniform(-1, 1, (env.num_cameras, 2)) * env.camera_action_space.high * scale
    tgt = rng.uniform(-1, 1, (env.num_targets, 2)) * env.target_action_space.high * scale
    return cam, tgt


def _assert_same_world(a: dict, b: dict, ignore=()):
    assert set(a) == set(b)
    for key in set(a) - set(ignore):
        np.testing.assert_array_equal(np.asarray(a[key]), np.asarray(b[key]), err_msg=key)


# Not part of a snapshot's input: the last move's collision flag and the render heading.
NOT_RESTORED = ('target_is_colliding', 'target_heading')


@pytest.fixture()
def env():
    environment = mate.make('MATE-4v8-9-v0')
    environment.reset(seed=0)
    yield environment
    environment.close()


# --------------------------------------------------------------------------- dimensions and spaces

@pytest.mark.parametrize('preset, nc, nt, no, d_cam, d_tgt, d_state, high', PRESET_TABLE,
                         ids=[row[0] for row in PRESET_TABLE])
def test_dimensions_of_every_preset(preset, nc, nt, no, d_cam, d_tgt, d_state, high):
    env = mate.make(f'MATE-{preset}-v0')
    (cam_obs, tgt_obs), (cam_infos, tgt_infos) = env.reset(seed=0)
    assert (env.num_cameras, env.num_targets, env.num_obstacles) == (nc, nt, no)
    assert cam_obs.shape == (nc, d_cam) and cam_obs.dtype == np.float64
    assert tgt_obs.shape == (nt, d_tgt) and tgt_obs.dtype == np.float64
    assert env.camera_observation_dim == d_cam and env.target_observation_dim == d_tgt
    assert env.state().shape == (d_state,) and env.state_space.shape == (d_state,)
    assert env.camera_observation_space.shape == (d_cam,)
    assert env.target_observation_space.shape == (d_tgt,)
    assert len(env.camera_joint_observation_space) == nc and len(env.target_joint_observation_space) == nt
    assert len(env.camera_joint_action_space) == nc and len(env.target_joint_action_space) == nt
    assert env.camera_action_space.shape == (2,) and env.target_action_space.shape == (2,)
    assert env.num_high_capacity_targets == high
    assert int(np.sum(env.target_capacities == 2)) == high
    assert len(cam_infos) == nc and len(tgt_infos) == nt
    if preset == 'Navigation':
        assert cam_obs.shape == (0, 190)
        np.testing.assert_array_equal(env.camera_action_space.low, [0, 0])
        np.testing.assert_array_equal(env.camera_action_space.high, [0, 0])
    else:
        np.testing.assert_array_equal(env.camera_action_space.high, [5.0, 2.5])
    np.testing.assert_array_equal(env.target_action_space.high, [20.0, 20.0])
    # the own-slot index sits at position 3 of every observation
    assert cam_obs[:, 3].tolist() == list(range(nc))
    assert tgt_obs[:, 3].tolist() == list(range(nt))
    assert np.all(cam_obs[:, :3] == (nc, nt, no)) and np.all(tgt_obs[:, :3] == (nc, nt, no))
    assert all(env.camera_observation_space.contains(obs) for obs in cam_obs)
    assert all(env.target_observation_space.contains(obs) for obs in tgt_obs)
    assert env.state_space.contains(env.state())


def test_mate_yaml_equals_4v8_9():
    env = mate.make('MultiAgentTracking-v0', config='MATE')
    (cam_obs, tgt_obs), _ = env.reset(seed=0)
    assert cam_obs.shape == (4, 126) and tgt_obs.shape == (8, 131) and env.state().shape == (220,)


@pytest.mark.parametrize('preset', ['4v8-9', '8v8-9', '1v1-0', 'Navigation'])
def test_spaces_contain_the_observations(preset):
    env = mate.make(f'MATE-{preset}-v0')
    rng = np.random.default_rng(0)
    (cam_obs, tgt_obs), _ = env.reset(seed=1)
    for step in range(30):
        for obs in cam_obs:
            assert env.camera_observation_space.contains(obs), step
        for obs in tgt_obs:
            assert env.target_observation_space.contains(obs), step
        assert env.state_space.contains(env.state()), step
        assert env.observation_space.contains((tuple(cam_obs), tuple(tgt_obs)))
        (cam_obs, tgt_obs), *_ = env.step(_random_action(env, rng, scale=3.0))


def test_unperceived_blocks_are_positive_zeros(env):
    """Observations are built branch-free (values times a 0/1 flag); no -0.0 may leak out."""
    rng = np.random.default_rng(4)
    target_flags = camera_observation_slices_of(env.num_cameras, env.num_targets, env.num_obstacles)['opponent_mask']
    unseen = 0
    for _ in range(50):
        (cam_obs, tgt_obs), *_ = env.step(_random_action(env, rng))
        for obs in (cam_obs, tgt_obs):
            assert not (np.signbit(obs) & (obs == 0.0)).any()
        unseen += int((cam_obs[:, target_flags] == 0.0).sum())
    assert unseen > 0  # some targets were out of sight, so zero blocks were written


def test_a_copied_env_steps_its_own_world(env):
    import copy
    import pickle
    rng = np.random.default_rng(5)
    env.step(_random_action(env, rng))
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    before = env.get_world()
    action = _random_action(env, rng)
    results = [twin.step(action)[0] for twin in twins]
    np.testing.assert_equal(env.get_world(), before)  # stepping the copies left the original alone
    own = env.step(action)[0]
    for got in results:
        np.testing.assert_array_equal(got[0], own[0])
        np.testing.assert_array_equal(got[1], own[1])


def test_action_space_samples_are_accepted(env):
    for _ in range(5):
        action = env.action_space.sample()
        assert env.action_space.contains(action)
        env.step(action)


# --------------------------------------------------------------------------- infos and rewards

def test_info_keys_are_exactly_the_spec_set(env):
    _, (cam_infos, tgt_infos) = env.reset(seed=4)
    assert len(cam_infos) == 4 and len(tgt_infos) == 8
    for info in cam_infos + tgt_infos:
        assert set(info) == INFO_KEYS
    *_, (cam_infos, tgt_infos) = env.step(env.action_space.sample())
    for info in cam_infos + tgt_infos:
        assert set(info) == INFO_KEYS
        assert info['messages'] == [] and info['out_communication_edges'] == 0


def test_camera_reward_is_minus_target_reward(env):
    rng = np.random.default_rng(1)
    nonzero = 0
    for _ in range(100):
        _, (cam_r, tgt_r), _, _, (cam_infos, tgt_infos) = env.step(_random_action(env, rng))
        assert cam_r == -tgt_r
        nonzero += tgt_r != 0
        for info in cam_infos:
            assert info['raw_reward'] == cam_r
            assert info['normalized_raw_reward'] == pytest.approx(cam_r / 12800.0)
        for info in tgt_infos:
            assert info['raw_reward'] == tgt_r
            assert info['normalized_raw_reward'] == pytest.approx(tgt_r / 12800.0)
            assert info['coverage_rate'] == env.coverage_rate
    assert nonzero > 0
    assert env.max_target_team_episode_reward == 12800


def test_dense_episode_sum_equals_the_episode_reward_accumulators():
    dense = mate.make('MATE-4v8-9-v0')
    sparse = mate.make('MATE-4v8-9-v0', reward_type='sparse')
    dense.reset(seed=5)
    sparse.reset(seed=5)
    rng = np.random.default_rng(5)
    sums = np.zeros(2)
    for _ in range(300):
        action = _random_action(dense, rng)
        sums += [dense.step(action)[1][1], sparse.step(action)[1][1]]
    assert sums[0] < 0  # random play: tracked targets cost bounty
    assert sums[0] == pytest.approx(dense.target_team_episode_reward)
    assert sums[1] == pytest.approx(sparse.delayed_target_team_episode_reward)
    # the reward type changes nothing but the returned reward
    assert dense.target_team_episode_reward == sparse.target_team_episode_reward
    assert dense.delayed_target_team_episode_reward == sparse.delayed_target_team_episode_reward
    np.testing.assert_array_equal(dense.state(), sparse.state())


DELIVERY_CONFIG = {
    'max_episode_steps': 100,
    'num_cargoes_per_target': 4,
    'high_capacity_target_split': 0.0,
    'targets_start_with_cargoes': False,
    'shuffle_entities': False,
    'target': {'location': [[0, 0], [100, 0]], 'step_size': 20, 'sight_range': 500},
}


@pytest.mark.parametrize('reward_type, expected', [('dense', 100 + 60), ('sparse', 100 + 2 * 60 - 100)])
def test_delivery_reward_and_termination(reward_type, expected):
    env = mate.make('MultiAgentTracking-v0', config=DELIVERY_CONFIG, reward_type=reward_type)
    env.reset(seed=0)
    world = env.get_world()
    world['target_state'][0, :2] = (925.0 - 90.0, 925.0)   # 15 units outside warehouse 0
    world['target_state'][0, 6:10] = (1, 0, 0, 0)
    world['target_state'][0, 3] = 1
    world['target_goal'][:] = (0, -1)
    world['target_freight'][:] = (100, 0)
    world['target_bounty'][:] = (60, 0)
    world['remaining_cargoes'][:] = 0
    world['awaiting_cargo_counts'][:] = (1, 0, 0, 0)
    env.set_world(world)
    (_, tgt_obs), (cam_r, tgt_r), terminated, truncated, (_, tgt_infos) = env.step(
        (np.zeros((0, 2)), [(20, 0), (0, 0)]))
    assert tgt_r == expected and cam_r == -expected
    assert (terminated, truncated) == (True, False)
    after = env.get_world()
    assert after['num_delivered_cargoes'] == 1
    assert after['awaiting_cargo_counts'].tolist() == [0, 0, 0, 0]
    assert after['target_goal'].tolist() == [-1, -1]
    assert after['target_state'][0, 10:14].tolist() == [1, 0, 0, 0]  # learnt: warehouse 0 is empty
    assert env.target_dones.tolist() == [True, False]
    assert tgt_infos[0]['num_delivered_cargoes'] == 1
    assert tgt_infos[0]['mean_transport_rate'] == pytest.approx(120 / 200)
    assert env.target_team_episode_reward == 160 and env.delayed_target_team_episode_reward == 120


def test_delivery_picks_up_new_cargo_at_the_same_warehouse():
    env = mate.make('MultiAgentTracking-v0', config=DELIVERY_CONFIG)
    env.reset(seed=0)
    world = env.get_world()
    world['target_state'][0, :2] = (925.0, 925.0)
    world['target_state'][0, 6:10] = (1, 0, 0, 0)
    world['target_state'][0, 3] = 1
    world['target_goal'][:] = (0, -1)
    world['target_freight'][:] = (100, 0)
    world['target_bounty'][:] = (100, 0)
    world['remaining_cargoes'][:] = 0
    world['remaining_cargoes'][0, 2] = 3
    world['awaiting_cargo_counts'][:] = (1, 0, 3, 0)
    env.set_world(world)
    _, (_, tgt_r), terminated, _, _ = env.step((np.zeros((0, 2)), np.zeros((2, 2))))
    assert tgt_r == 200 and not terminated
    after = env.get_world()
    assert after['target_goal'].tolist() == [2, -1]
    assert after['target_state'][0, 6:10].tolist() == [0, 0, 1, 0]
    assert after['remaining_cargoes'][0, 2] == 2
    assert after['awaiting_cargo_counts'].tolist() == [0, 0, 3, 0]   # pick-ups do not change it
    assert after['target_freight'].tolist() == [100, 0] and after['target_bounty'].tolist() == [100, 0]


# --------------------------------------------------------------------------- misuse

def test_step_before_reset_raises():
    env = mate.make('MATE-4v8-9-v0')
    with pytest.raises(RuntimeError, match='reset'):
        env.step(env.action_space.sample())


NOT_A_PAIR = [None, 5, (np.zeros((4, 2)),), (np.zeros((4, 2)), np.zeros((8, 2)), np.zeros((4, 2))),
              np.zeros((12, 2))]


@pytest.mark.parametrize('action', NOT_A_PAIR, ids=['None', 'int', '1-tuple', '3-tuple', 'flat-array'])
def test_non_pair_action_raises_and_changes_nothing(env, action):
    before = env.get_world()
    with pytest.raises(ValueError, match='pair'):
        env.step(action)
    _assert_same_world(before, env.get_world())


@pytest.mark.parametrize('cam, tgt, words', [
    (np.zeros((3, 2)), np.zeros((8, 2)), ['camera', '(4, 2)']),
    (np.zeros((4, 2)), np.zeros((8, 3)), ['target', '(8, 2)']),
    (np.zeros(7), np.zeros((8, 2)), ['camera', '(4, 2)']),
    (np.zeros((4, 2)), [], ['target', '(8, 2)']),
])
def test_wrong_action_shape_raises_and_changes_nothing(env, cam, tgt, words):
    before, state = env.get_world(), env.state()
    with pytest.raises(ValueError) as error:
        env.step((cam, tgt))
    for word in words:
        assert word in str(error.value)
    _assert_same_world(before, env.get_world())
    np.testing.assert_array_equal(state, env.state())


@pytest.mark.parametrize('bad', [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize('team', ['camera', 'target'])
def test_non_finite_action_raises_and_changes_nothing(env, bad, team):
    cam, tgt = np.ones((4, 2)), np.ones((8, 2))
    (cam if team == 'camera' else tgt)[1, 0] = bad
    before = env.get_world()
    with pytest.raises(ValueError, match='NaN or inf') as error:
        env.step((cam, tgt))
    assert team in str(error.value)
    _assert_same_world(before, env.get_world())
    # the env still works afterwards
    env.step((np.ones((4, 2)), np.ones((8, 2))))
    assert env.episode_step == 1


def test_non_numeric_action_raises(env):
    with pytest.raises(ValueError, match='numeric'):
        env.step((np.zeros((4, 2)), [['a', 'b']] * 8))


# The right number of values in the wrong shape: refused, never reshaped (issue 30).
SAME_SIZE_WRONG_SHAPE = [
    ('camera', np.zeros((2, 4)), np.zeros((8, 2)), '(2, 4)'),        # transposed
    ('camera', np.zeros(8), np.zeros((8, 2)), '(8,)'),               # flat (2 Nc,)
    ('camera', np.zeros((1, 4, 2)), np.zeros((8, 2)), '(1, 4, 2)'),  # a batch of one
    ('target', np.zeros((4, 2)), np.zeros((2, 8)), '(2, 8)'),
    ('target', np.zeros((4, 2)), np.zeros(16), '(16,)'),
    ('target', np.zeros((4, 2)), np.zeros((8, 2, 1)), '(8, 2, 1)'),
    ('target', np.zeros((4, 2)), [[0.0, 0.0]] * 7 + [[0.0]] * 2, 'a ragged sequence'),
]


@pytest.mark.parametrize('team, cam, tgt, given', SAME_SIZE_WRONG_SHAPE,
                         ids=[f'{team}-{given}' for team, _, _, given in SAME_SIZE_WRONG_SHAPE])
def test_actions_of_the_right_size_but_the_wrong_shape_are_refused(env, team, cam, tgt, given):
    expected = '(4, 2) (4 cameras x [rotate, zoom])' if team == 'camera' else '(8, 2) (8 targets x [dx, dy])'
    before = env.get_world()
    with pytest.raises(ValueError) as error:
        env.step((cam, tgt))
    assert str(error.value) == f'{team} joint action must have shape {expected}; got {given}'
    _assert_same_world(before, env.get_world())
    assert env.episode_step == 0


def test_the_accepted_action_forms(env):
    """(N, 2) arrays of any real dtype, sequences of N pairs (nested lists, tuples of per-agent actions)
    and team space samples are all taken as one row per agent, in slot order."""
    world = env.get_world()
    cam = np.array([[5.0, -2.5], [-5.0, 2.5], [1.0, 0.0], [0.0, 1.0]])
    tgt = np.arange(-8, 8, dtype=np.float64).reshape(8, 2)
    expected = env.step((cam, tgt))[0]
    forms = [
        (cam.tolist(), tgt.tolist()),
        (tuple(cam), tuple(tgt)),                           # per-agent (2,) actions, as group_act returns them
        (cam.astype(np.float32), tgt.astype(np.int64)),
        (np.asfortranarray(cam), tgt[::-1][::-1]),          # non-contiguous layouts
    ]
    for form in forms:
        env.set_world(world)
        observations = env.step(form)[0]
        np.testing.assert_array_equal(observations[0], expected[0])
        np.testing.assert_array_equal(observations[1], expected[1])
    env.set_world(world)
    env.step(env.action_space.sample())                     # a TeamSample of each team
    assert env.episode_step == 1


def test_a_team_without_agents_takes_an_empty_action():
    env = mate.make('MATE-Navigation-v0')                   # no cameras
    env.reset(seed=0)
    for cameras in (np.zeros((0, 2)), [], ()):
        env.step((cameras, np.zeros((8, 2))))
    with pytest.raises(ValueError, match=r'camera joint action must have shape \(0, 2\)'):
        env.step((np.zeros((1, 2)), np.zeros((8, 2))))
    assert env.episode_step == 3


def test_unknown_render_mode_raises_a_clear_error():
    with pytest.raises(ValueError, match="render_mode='ansi' is not supported"):
        mate.make('MATE-4v8-9-v0', render_mode='ansi')


# --------------------------------------------------------------------------- snapshots

def _bad_snapshots(world: dict):
    """(name, snapshot) pairs, each with one defect."""
    def edited(**changes):
        snap = {key: np.array(value, copy=True) for key, value in world.items()}
        for key, value in changes.items():
            if value is KeyError:
                del snap[key]
            else:
                snap[key] = value
        return snap

    target_state = world['target_state'].copy()
    nan_state = target_state.copy()
    nan_state[0, 0] = np.nan
    capacity_3 = target_state.copy()
    capacity_3[0, 5] = 3
    wrong_sight = target_state.copy()
    wrong_sight[:, 2] = 123.0
    bits = target_state.copy()
    bits[0, 6:10] = (1, 1, 0, 0)
    camera_state = world['camera_state'].copy()
    camera_state[0, 2] = 99.0
    return [
        ('missing key', edited(camera_state=KeyError)),
        ('unknown key', edited(teleport=np.zeros(3))),
        ('camera_state shape', edited(camera_state=np.zeros((3, 9)))),
        ('target_state shape', edited(target_state=np.zeros((8, 13)))),
        ('obstacle_state shape', edited(obstacle_state=np.zeros((9, 4)))),
        ('remaining_cargoes shape', edited(remaining_cargoes=np.zeros((4,)))),
        ('nan location', edited(target_state=nan_state)),
        ('capacity 3', edited(target_state=capacity_3)),
        ('sight range', edited(target_state=wrong_sight)),
        ('two goal bits', edited(target_state=bits)),
        ('camera radius', edited(camera_state=camera_state)),
        ('goal out of range', edited(target_goal=np.full(8, 4))),
        ('negative bounty', edited(target_bounty=np.full(8, -1))),
        ('fractional steps', edited(target_steps=np.full(8, 1.5))),
        ('viewing angle too small', edited(camera_viewing_angle=np.full(4, 10.0))),
        ('viewing angle too large', edited(camera_viewing_angle=np.full(4, 181.0))),
        ('negative obstacle radius', edited(obstacle_state=np.c_[world['obstacle_state'][:, :2], -np.ones(9)])),
        ('not numeric', edited(episode_step='soon')),
        ('negative episode_step', edited(episode_step=-1)),
    ]


def test_bad_snapshots_raise_snapshot_error_and_change_nothing(env):
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.step(_random_action(env, rng))
    world = env.get_world()
    obs = env.joint_observation()
    assert issubclass(mate.SnapshotError, ValueError)
    for name, snapshot in _bad_snapshots(world):
        with pytest.raises(mate.SnapshotError):
            env.set_world(snapshot)
        _assert_same_world(world, env.get_world())
        for got, expected in zip(env.joint_observation(), obs):
            np.testing.assert_array_equal(got, expected, err_msg=name)


def test_snapshot_error_message_names_the_key(env):
    world = env.get_world()
    world['target_state'] = np.zeros((8, 13))
    with pytest.raises(mate.SnapshotError, match='target_state'):
        env.set_world(world)
    del world['target_state']
    with pytest.raises(mate.SnapshotError, match='target_state'):
        env.set_world(world)


@pytest.mark.parametrize('transmittance', [0.0, 1.0])
def test_get_set_world_round_trip(transmittance):
    """With deterministic perception a snapshot reproduces the joint observation exactly,
    in the same env and in another one (transmittance 0 < tau < 1 re-draws the coins)."""
    env = mate.make('MATE-4v8-9-v0', obstacle={'transmittance': transmittance})
    env.reset(seed=8)
    rng = np.random.default_rng(8)
    for _ in range(20):
        env.step(_random_action(env, rng))
    world = env.get_world()
    cam_obs, tgt_obs = env.joint_observation()
    state = env.state()

    env.set_world(world)
    for got, expected in zip(env.joint_observation(), (cam_obs, tgt_obs)):
        np.testing.assert_array_equal(got, expected)
    _assert_same_world(world, env.get_world(), ignore=NOT_RESTORED)

    other = mate.make('MATE-4v8-9-v0', obstacle={'transmittance': transmittance})
    other.reset(seed=99)
    other.set_world(world)
    _assert_same_world(world, other.get_world(), ignore=NOT_RESTORED)
    for got, expected in zip(other.joint_observation(), (cam_obs, tgt_obs)):
        np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(other.state(), state)
    assert other.episode_step == 20
    # both continue identically under the same deterministic actions (no pick-ups in sight)
    action = (np.full((4, 2), 1.0), np.full((8, 2), 3.0))
    for got, expected in zip(other.step(action)[0], env.step(action)[0]):
        np.testing.assert_array_equal(got, expected)


def test_get_world_returns_copies(env):
    world = env.get_world()
    world['target_state'][:] = 0.0
    world['remaining_cargoes'][:] = 0
    assert np.any(env.get_world()['target_state'] != 0.0)
    assert env.get_world()['remaining_cargoes'].sum() > 0


# --------------------------------------------------------------------------- messages

def test_broadcast_and_peer_messages(env):
    env.send_messages(Message(sender=1, recipient=None, content={'x': 1}, team=Team.CAMERA))
    own = env.receive_messages(agent_id=(Team.CAMERA, 1))
    assert len(own) == 1 and own[0].sender == 1 and own[0].recipient == 1 and own[0].broadcasting
    env.send_messages([Message(sender=0, recipient=2, content='hi', team=Team.TARGET),
                       Message(sender=0, recipient=2, content='again', team=Team.TARGET)])
    camera_lists, target_lists = env.receive_messages()
    assert [len(q) for q in camera_lists] == [1, 0, 1, 1]   # camera 1 already fetched its copy
    assert [m.content for m in target_lists[2]] == ['hi', 'again']

    *_, (cam_infos, tgt_infos) = env.step(env.action_space.sample())
    # every message of the step shows up in the infos, fetched or not, with edge counts
    assert [len(info['messages']) for info in cam_infos] == [1, 1, 1, 1]
    assert all(info['messages'][0].content == {'x': 1} for info in cam_infos)
    assert [info['out_communication_edges'] for info in cam_infos] == [0, 4, 0, 0]
    assert [info['in_communication_edges'] for info in cam_infos] == [1, 1, 1, 1]
    assert [len(info['messages']) for info in tgt_infos] == [0, 0, 2, 0, 0, 0, 0, 0]
    assert [info['out_communication_edges'] for info in tgt_infos] == [2, 0, 0, 0, 0, 0, 0, 0]
    assert [info['in_communication_edges'] for info in tgt_infos] == [0, 0, 2, 0, 0, 0, 0, 0]
    assert env.camera_total_communication_edges[1].tolist() == [1, 1, 1, 1]
    assert env.target_total_communication_edges[0, 2] == 2

    # everything per-step is cleared by the step
    assert env.receive_messages() == ([[]] * 4, [[]] * 8)
    assert not env.camera_communication_edges.any() and not env.target_communication_edges.any()
    *_, (cam_infos, tgt_infos) = env.step(env.action_space.sample())
    for info in cam_infos + tgt_infos:
        assert info['messages'] == [] and info['out_communication_edges'] == 0
        assert info['in_communication_edges'] == 0
    assert env.camera_total_communication_edges[1].tolist() == [1, 1, 1, 1]   # per-episode totals stay


def test_unsent_queue_is_cleared_by_step_and_totals_by_reset(env):
    env.send_messages(Message(sender=3, recipient=None, content=None, team=Team.TARGET))
    env.step(env.action_space.sample())
    assert env.receive_messages(agent_id=(Team.TARGET, 0)) == []
    assert env.target_total_communication_edges.sum() == 8
    env.reset()
    assert env.target_total_communication_edges.sum() == 0


def test_broadcast_content_is_copied_per_recipient(env):
    content = {'seen': [1, 2]}
    env.send_messages(Message(sender=0, recipient=None, content=content, team=Team.CAMERA))
    camera_lists, _ = env.receive_messages()
    camera_lists[0][0]['seen'].append(3)
    assert camera_lists[1][0]['seen'] == [1, 2] and content == {'seen': [1, 2]}


# --------------------------------------------------------------------------- properties

def test_properties_and_str(env):
    assert env.num_warehouses == 4
    assert env.max_episode_steps == 10000
    assert env.camera_min_viewing_angle == 30 and env.camera_max_sight_range == 1500
    assert env.target_step_size == 20 and env.target_sight_range == 500
    assert env.obstacle_transmittance == pytest.approx(0.1)
    assert (env.freight_scale, env.bounty_scale, env.reward_scale) == (100, 100, 200)
    assert env.num_low_capacity_targets == 4
    assert env.preserved_data.tolist() == [4, 8, 9, 0, 925, 925, -925, 925, -925, -925, 925, -925, 75]
    assert str(env).endswith('(4 cameras, 8 targets, 9 obstacles)')
    nav = mate.make('MATE-Navigation-v0')
    assert str(nav).endswith('(0 camera, 8 targets, 32 obstacles)')
    with pytest.raises(KeyError):
        nav.camera_min_viewing_angle  # noqa: B018


def test_read_only_views_follow_the_world(env):
    with pytest.raises(ValueError):
        env.bounties[0] = 5
    env.step(env.action_space.sample())
    world = env.get_world()
    np.testing.assert_array_equal(env.target_steps, world['target_steps'])
    np.testing.assert_array_equal(env.bounties, world['target_bounty'])
    np.testing.assert_array_equal(env.remaining_cargoes, world['remaining_cargoes'])
    assert env.episode_step == world['episode_step'] == 1


def test_headings_and_warehouse_distances_are_derived_when_read(env):
    """Targets face their last move; distances to the warehouse centres follow the locations."""
    from mate.constants import WAREHOUSES
    before = env.get_world()['target_state'][:, :2].copy()
    rng = np.random.default_rng(6)
    env.step(_random_action(env, rng))
    after = env.get_world()
    moved = after['target_state'][:, :2] - before
    assert (np.abs(moved).sum(axis=1) > 0).any()
    for t in np.flatnonzero(np.abs(moved).sum(axis=1) > 0):
        expected = np.degrees(np.arctan2(moved[t, 1], moved[t, 0]))
        assert env.target_orientations[t] == pytest.approx(expected)
        assert after['target_heading'][t] == pytest.approx(expected)
    expected_distances = np.hypot(*(after['target_state'][:, None, :2] - WAREHOUSES[None]).transpose(2, 0, 1))
    np.testing.assert_allclose(env.target_warehouse_distances, expected_distances)
    assert env.target_warehouse_distances.shape == (env.num_targets, 4)
