"""MoreTrainingInformation (spec §8.3): the exact facts added to every info dict."""

from __future__ import annotations

import numpy as np
from wrapper_scene import NC, NT, SCENE, ZERO_ACTION, make_env, set_scene

import mate
from mate.constants import WAREHOUSES


def test_infos_carry_training_facts():
    env = make_env(wrappers=[mate.MoreTrainingInformation])
    remaining = [[0, 0, 0, 0], [1, 0, 1, 0], [0, 0, 0, 0], [2, 1, 0, 0]]
    set_scene(env, goals=[3, -1, 1], remaining=remaining, **SCENE)
    # target 2 is moved 20 units north-east; the others stand still
    action = (ZERO_ACTION[0], np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 20.0]]))
    (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step(action)
    base = env.unwrapped

    assert [info['num_tracked'] for info in camera_infos] == [1, 1]
    assert [info['is_sensed'] for info in camera_infos] == [False, True]          # target 1 sees camera 1

    locations = np.array([[0.0, 0.0], [500.0, 300.0], [-300.0, 720.0]])
    centre = np.linalg.norm(locations[:, None, :] - WAREHOUSES[None], axis=-1)
    expected_wd = np.maximum(centre - 75.0, 0.0)
    assert [info['goal'] for info in target_infos] == [3, -1, 1]
    for t, info in enumerate(target_infos):
        np.testing.assert_allclose(info['warehouse_distances'], expected_wd[t])
    assert target_infos[0]['goal_distance'] == expected_wd[0, 3]
    assert target_infos[1]['goal_distance'] == 1000.0                          # unloaded
    assert target_infos[2]['goal_distance'] == expected_wd[2, 1]
    assert [info['individual_done'] for info in target_infos] == [False] * NT
    assert [info['is_tracked'] for info in target_infos] == [True, True, False]
    assert [info['is_colliding'] for info in target_infos] == [False] * NT

    for info in camera_infos + target_infos:
        np.testing.assert_array_equal(info['state'], base.state())
        np.testing.assert_array_equal(info['camera_states'], camera_obs[:, 13:22])
        np.testing.assert_array_equal(info['target_states'], target_obs[:, 13:27])
        np.testing.assert_array_equal(info['obstacle_states'], SCENE['obstacles'])
        np.testing.assert_array_equal(info['camera_target_view_mask'], [[1, 0, 0], [0, 1, 0]])
        np.testing.assert_array_equal(info['target_camera_view_mask'], [[0, 0], [0, 1], [0, 0]])
        np.testing.assert_array_equal(info['target_obstacle_view_mask'], [[0, 0], [0, 0], [1, 0]])
        np.testing.assert_array_equal(info['target_target_view_mask'], np.eye(NT, dtype=bool))
        np.testing.assert_array_equal(info['camera_obstacle_view_mask'], np.ones((NC, 2), dtype=bool))
        np.testing.assert_array_equal(info['remaining_cargoes'], remaining)
        np.testing.assert_array_equal(info['remaining_cargo_counts'], [0, 2, 0, 3])    # waiting AT each warehouse
        np.testing.assert_array_equal(info['awaiting_cargo_counts'], [3, 2, 1, 1])     # due TO each (+ goals 3 and 1)
        assert info['raw_reward'] is not None                                           # base keys are kept


def test_collision_and_delivery_flags():
    env = make_env(wrappers=[mate.MoreTrainingInformation])
    # target 0 delivers at warehouse 3 (925, -925); target 2 pushes against the east border
    set_scene(env, cameras=SCENE['cameras'], targets=[(925.0, -925.0), (500.0, 300.0), (995.0, 0.0)],
              goals=[3, 0, -1], obstacles=SCENE['obstacles'])
    action = (ZERO_ACTION[0], np.array([[0.0, 0.0], [0.0, 0.0], [20.0, 0.0]]))
    *_, (_, target_infos) = env.step(action)
    assert [info['individual_done'] for info in target_infos] == [True, False, False]
    assert [info['is_colliding'] for info in target_infos] == [False, False, True]


def test_reset_infos_are_extended_too():
    env = make_env(wrappers=[mate.MoreTrainingInformation])
    _, (camera_infos, target_infos) = env.reset(seed=1)
    assert 'num_tracked' in camera_infos[0] and 'goal_distance' in target_infos[0]
    assert camera_infos[0]['state'] is target_infos[-1]['state']                  # one shared array per step
    assert not camera_infos[0]['state'].flags.writeable
