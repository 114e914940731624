"""The deterministic scenario of spec §11.3, end to end through `mate.make`.

One camera at the origin with a half-disc view (phi = 0, theta = 180, R_s = 500), five
targets on fixed spots, one opaque obstacle. Every output below was verified on the
original MATE. Episode end follows our decision (decisions.md): `truncated` after exactly
`max_episode_steps` = 3 steps (the original's `done` fires one step later).
"""

from __future__ import annotations

import numpy as np
import pytest

import mate

CONFIG = {
    'name': 'deterministic scenario',
    'max_episode_steps': 3,
    'reward_type': 'dense',
    'num_cargoes_per_target': 4,
    'high_capacity_target_split': 0.0,
    'targets_start_with_cargoes': False,
    'shuffle_entities': False,
    'camera': {'location': [[0, 0]], 'radius': 40, 'min_viewing_angle': 180, 'max_sight_range': 500,
               'rotation_step': 360, 'zooming_step': 2.5},
    'target': {'location': [[300, 0], [-300, 0], [600, 0], [300, 200], [300, 20]],
               'step_size': 20, 'sight_range': 250},
    'obstacle': {'location': [[150, 150]], 'radius': 50, 'transmittance': 0.0},
}

PRESERVED = [1, 5, 1, 0, 925, 925, -925, 925, -925, -925, 925, -925, 75]

CAMERA_OBSERVATION = PRESERVED + [
    0, 0, 40, 500, 0, 180, 500, 360, 2.5,           # own private state
    300, 0, 250, 0, 1,                              # target 0 tracked
    0, 0, 0, 0, 0,                                  # target 1 behind
    0, 0, 0, 0, 0,                                  # target 2 out of range
    0, 0, 0, 0, 0,                                  # target 3 occluded
    300, 20, 250, 0, 1,                             # target 4 tracked
    150, 150, 50, 1,                                # obstacle (flag frozen at reset)
    0, 0, 40, 500, 0, 180, 1,                       # itself
]

# Spec §11.3 announces "64 values" but lists 63, which is also what the layout gives:
# 27 + 7 N_c + 4 N_o + 5 N_t = 27 + 7 + 4 + 25.
TARGET0_OBSERVATION = PRESERVED + [
    300, 0, 250, 0, 20, 1, 0, 0, 0, 0, 0, 0, 0, 0,  # own private state (unloaded, capacity 1)
    0, 0, 0, 0, 0, 0, 0,                            # the camera is out of reach (300 > 250 + 40)
    150, 150, 50, 1,                                # the obstacle is in reach
    300, 0, 250, 0, 1,                              # itself
    0, 0, 0, 0, 0,
    0, 0, 0, 0, 0,
    300, 200, 250, 0, 1,
    300, 20, 250, 0, 1,
]


@pytest.fixture()
def env():
    environment = mate.make('MultiAgentTracking-v0', config=CONFIG)
    yield environment
    environment.close()


def test_layout_lengths_match_the_listed_vectors():
    assert len(CAMERA_OBSERVATION) == 58
    assert len(TARGET0_OBSERVATION) == 63


def test_after_reset(env):
    (cam_obs, tgt_obs), (cam_infos, tgt_infos) = env.reset(seed=0)
    assert env.num_cameras == 1 and env.num_targets == 5 and env.num_obstacles == 1
    assert env.tracked_bits.tolist() == [True, False, False, False, True]
    assert env.coverage_rate == pytest.approx(0.4)
    assert all(info['coverage_rate'] == pytest.approx(0.4) for info in cam_infos + tgt_infos)

    assert env.target_camera_view_mask.tolist() == [[False]] * 5
    assert env.target_obstacle_view_mask[:, 0].tolist() == [True, False, False, True, True]
    sees = [set(np.flatnonzero(row)) for row in env.target_target_view_mask]
    assert sees == [{0, 3, 4}, {1}, {2}, {0, 3, 4}, {0, 3, 4}]

    assert cam_obs.shape == (1, 58) and tgt_obs.shape == (5, 63)
    np.testing.assert_allclose(cam_obs[0], CAMERA_OBSERVATION, atol=1e-9)
    np.testing.assert_allclose(tgt_obs[0], TARGET0_OBSERVATION, atol=1e-9)
    assert tgt_obs[:, 3].tolist() == [0, 1, 2, 3, 4]  # own slot index

    state = env.state()
    assert state.shape == (121,)
    assert env.state_space.shape == (121,)
    world = env.get_world()
    assert world['remaining_cargoes'].sum() == 20
    assert state[-16:].sum() == 20
    assert world['camera_orientation'][0] == pytest.approx(0.0)
    assert world['camera_viewing_angle'][0] == pytest.approx(180.0)
    assert world['camera_sight_range'][0] == pytest.approx(500.0)


@pytest.mark.parametrize('seed', [1, 2, 12345])
def test_reset_outputs_do_not_depend_on_the_seed(env, seed):
    (cam_obs, tgt_obs), _ = env.reset(seed=seed)
    np.testing.assert_allclose(cam_obs[0], CAMERA_OBSERVATION, atol=1e-9)
    np.testing.assert_allclose(tgt_obs[0], TARGET0_OBSERVATION, atol=1e-9)
    assert env.get_world()['remaining_cargoes'].sum() % 20 == 0  # whole batches of 5 x 4


def test_step_and_termination(env):
    env.reset(seed=0)
    camera_action = [[10, -5]]
    target_action = [[0, 20], [0, 0], [-30, 0], [0, 0], [0, 0]]
    (cam_obs, tgt_obs), (cam_r, tgt_r), terminated, truncated, (cam_infos, tgt_infos) = env.step(
        (camera_action, target_action))

    world = env.get_world()
    assert world['camera_orientation'][0] == pytest.approx(10.0)
    assert world['camera_viewing_angle'][0] == pytest.approx(180.0)  # zoom clipped at both ends
    assert world['camera_sight_range'][0] == pytest.approx(500.0)
    xy = world['target_state'][:, :2]
    np.testing.assert_allclose(xy, [[300, 20], [-300, 0], [580, 0], [300, 200], [300, 20]], atol=1e-9)
    assert world['target_is_colliding'].tolist() == [False] * 5
    assert env.tracked_bits.tolist() == [True, False, False, False, True]
    assert cam_r == 0.0 and tgt_r == 0.0 and cam_r == -tgt_r
    assert (terminated, truncated) == (False, False)
    assert cam_infos[0]['coverage_rate'] == pytest.approx(0.4)
    assert env.episode_step == 1

    # the observation reflects the new orientation: R_s (cos 10, sin 10)
    expected_heading = 500 * np.array([np.cos(np.radians(10)), np.sin(np.radians(10))])
    np.testing.assert_allclose(cam_obs[0, 16:18], expected_heading, atol=1e-9)
    np.testing.assert_allclose(tgt_obs[0, 13:15], [300, 20], atol=1e-9)

    outcomes = []
    for _ in range(2):
        _, rewards, terminated, truncated, _ = env.step(([[0, 0]], np.zeros((5, 2))))
        outcomes.append((terminated, truncated))
        assert rewards == (0.0, 0.0)
    # ours: truncated exactly when episode_step reaches max_episode_steps = 3 (not at 4)
    assert outcomes == [(False, False), (False, True)]
    assert env.episode_step == 3


def test_reset_after_truncation_starts_over(env):
    env.reset(seed=0)
    for _ in range(3):
        *_, truncated, _ = env.step(([[5, 0]], np.zeros((5, 2))))
    assert truncated
    (cam_obs, _), _ = env.reset()
    assert env.episode_step == 0
    np.testing.assert_allclose(cam_obs[0], CAMERA_OBSERVATION, atol=1e-9)
    _, _, terminated, truncated, _ = env.step(([[0, 0]], np.zeros((5, 2))))
    assert (terminated, truncated) == (False, False)
