import math

import numpy as np
import pytest

import mate
from mate.agents.greedy import desired_viewing_angle
from mate.learn import (
    TeamVecEnv,
    VecGreedyCamera,
    VecGreedyTarget,
    discrete_to_continuous,
)
from mate.learn.opponents import desired_viewing_angles


def test_desired_viewing_angles_match_scalar_rule():
    rng = np.random.default_rng(0)
    distance = rng.uniform(0, 2000, 500)
    theta = rng.uniform(30, 180, 500)
    sight = rng.uniform(200, 1500, 500)
    expected = [desired_viewing_angle(d, t, s, 1500.0) for d, t, s in zip(distance, theta, sight)]
    assert np.allclose(desired_viewing_angles(distance, theta, sight, 1500.0), expected)


def test_greedy_target_heads_for_its_destination(monkeypatch):
    monkeypatch.setattr('mate.learn.opponents.REFRESH_STUCK', 0.0)   # keep the (zeroed) noise
    vec = mate.make_vec('MATE-4v8-9-v0', num_envs=3)
    (_, target_obs), _ = vec.reset(seed=0)
    opponent = VecGreedyTarget(3, vec.num_targets, seed=0)
    opponent.reset(target_obs)
    opponent.noise[:] = 0.0
    action = opponent.act(target_obs)
    own = target_obs[..., 13:27]
    step = own[..., 4]
    assert np.all(np.abs(action) <= step[..., None] + 1e-9)
    goal = np.argmax(own[..., 6:10], axis=-1)
    direction = mate.WAREHOUSES[goal] - own[..., 0:2]
    cosine = (direction * action).sum(-1) / np.linalg.norm(direction, axis=-1) / np.linalg.norm(action, axis=-1)
    assert np.all(cosine > 0.99)


def test_greedy_camera_turns_towards_a_seen_target():
    vec = mate.make_vec('MATE-4v8-0-v0', num_envs=4)
    (camera_obs, _), _ = vec.reset(seed=1)
    opponent = VecGreedyCamera(4, vec.num_cameras, vec.num_targets, vec.num_obstacles, seed=0)
    opponent.reset(camera_obs)
    action = opponent.act(camera_obs)
    assert action.shape == (4, vec.num_cameras, 2)
    assert np.all(np.abs(action) <= np.array([5.0, 2.5]) + 1e-9)


@pytest.mark.parametrize('team', ['camera', 'target'])
def test_team_vec_env_shapes_and_episode_ends(team):
    env = TeamVecEnv(team, num_envs=4, frame_skip=3, horizon=30, seed=0)
    obs, state = env.reset()
    assert obs.shape == (4, env.num_agents, env.obs_dim) and obs.dtype == np.float32
    assert state.shape == (4, env.state_dim)
    finished = 0
    for t in range(12):
        obs, state, _, done, truncated, info = env.step(np.full((4, env.num_agents), 12))
        finished += len(info['episodes'])
        if t % 10 == 9:
            assert done.all() and truncated.all()       # 30 raw steps = 10 decisions
        else:
            assert not done.any()
    assert finished == 4
    assert all(e['length'] == 30 for e in info['episodes'] or [{'length': 30}])


@pytest.mark.parametrize('team', ['camera', 'target'])
def test_full_observability_shows_the_trained_team_everything_and_changes_nothing_else(team):
    """Fig. 6 ablation: the trained team's raw observations have every record flagged (targets: true
    warehouse emptiness); the game, the rewards and the opponent's view are those of the partial env."""
    from mate.spaces import camera_observation_slices_of, target_observation_slices_of
    full = TeamVecEnv(team, num_envs=3, frame_skip=2, horizon=40, seed=5, full_observability=True)
    partial = TeamVecEnv(team, num_envs=3, frame_skip=2, horizon=40, seed=5)
    full.reset(), partial.reset()
    slices = (camera_observation_slices_of if team == 'camera' else target_observation_slices_of)(*full.counts)
    masks = [slices[f'{kind}_mask'] for kind in ('opponent', 'obstacle', 'teammate')]
    rng = np.random.default_rng(0)
    partial_masks = []
    for _ in range(8):
        actions = rng.integers(0, 25, (3, full.num_agents))
        _, _, reward_full, *_ = full.step(actions)
        _, state_p, reward_p, *_ = partial.step(actions)
        for mask in masks:
            assert np.all(full.raw_observations[..., mask] == 1.0)
        partial_masks.append(np.concatenate([partial.raw_observations[..., m] for m in masks], -1).mean())
        np.testing.assert_array_equal(reward_full, reward_p)
        np.testing.assert_array_equal(full._other_raw, partial._other_raw)     # the opponent's view
        np.testing.assert_array_equal(full._state(), state_p)
    assert np.mean(partial_masks) < 1.0          # the partial env does hide something
    if team == 'target':
        from mate.wrappers.enhanced_observation import TARGET_EMPTY_BITS, empty_warehouses
        truth = empty_warehouses(full.vec.remaining_cargoes)[:, None, :]
        np.testing.assert_array_equal(full.raw_observations[..., TARGET_EMPTY_BITS],
                                      np.broadcast_to(truth, (3, full.num_agents, 4)))


def test_discrete_grids():
    obs = np.zeros((1, 2, 40))
    obs[..., 13 + 7], obs[..., 13 + 8] = 5.0, 2.5
    cam = discrete_to_continuous(np.array([[0, 24]]), obs, 'camera')
    assert np.allclose(cam, [[[-5, -2.5], [5, 2.5]]])
    obs[..., 13 + 4] = 10.0
    tgt = discrete_to_continuous(np.array([[0, 12]]), obs, mate.Team.TARGET)
    assert np.allclose(tgt[0, 0], [-10 / math.sqrt(2)] * 2) and np.allclose(tgt[0, 1], 0)
