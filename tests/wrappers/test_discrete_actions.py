"""DiscreteCamera and DiscreteTarget (spec §8.4): grids, the mapping applied by step, reverse_action."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from hypothesis import given, settings
from hypothesis import strategies as st
from wrapper_scene import NC, NT, SCENE, ZERO_ACTION, make_env, set_scene

import mate
from mate.wrappers.discrete_action_spaces import disk_grid


def test_discrete_camera_spaces_and_grid():
    env = make_env(wrappers=[mate.WrapperSpec(mate.DiscreteCamera, levels=5)])
    assert env.camera_action_space == spaces.Discrete(25)
    assert env.action_space == spaces.Tuple((spaces.Tuple((spaces.Discrete(25),) * NC), env.target_joint_action_space))
    cameras, _ = env.action(([0, 12], ZERO_ACTION[1]))
    np.testing.assert_allclose(cameras, [[-5.0, -2.5], [0.0, 0.0]])
    cameras, _ = env.action((np.array([24, 7]), ZERO_ACTION[1]))
    np.testing.assert_allclose(cameras, [[5.0, 2.5], [0.0, -1.25]])        # 7 = i 2 + 5 * j 1
    three = make_env(wrappers=[mate.WrapperSpec(mate.DiscreteCamera, levels=3)])
    assert three.camera_action_space.n == 9
    np.testing.assert_allclose(three.action(([5, 1], None))[0], [[5.0, 0.0], [0.0, -2.5]])


def test_discrete_camera_step_turns_and_zooms():
    env = make_env(wrappers=[mate.DiscreteCamera])
    set_scene(env, **SCENE)
    env.step(([24, 0], ZERO_ACTION[1]))
    world = env.unwrapped.get_world()
    np.testing.assert_allclose(world['camera_orientation'], [5.0, 85.0])
    np.testing.assert_allclose(world['camera_viewing_angle'], [62.5, 30.0])   # 27.5 is clipped at the minimum 30


def test_discrete_camera_reverse_action_and_errors():
    env = make_env(wrappers=[mate.DiscreteCamera])
    indices, targets = env.reverse_action((np.array([[4.0, -1.0], [-5.0, 2.5]]), 'untouched'))
    assert indices.tolist() == [9, 20] and targets == 'untouched'         # (1, -0.5) -> 4 + 5; (-1, 1) -> 0 + 20
    with pytest.raises(ValueError, match=r'outside Discrete\(25\)'):
        env.step(([25, 0], ZERO_ACTION[1]))
    with pytest.raises(ValueError, match='expected 2'):
        env.step(([1, 2, 3], ZERO_ACTION[1]))
    with pytest.raises(ValueError, match='at least one camera'):
        mate.make('MATE-Navigation-v0', wrappers=[mate.DiscreteCamera])


def test_disk_grid_values():
    grid = disk_grid(5)
    np.testing.assert_allclose(grid[[0, 1, 6, 7, 12, 24]],
                               [[-np.sqrt(0.5)] * 2, [-1 / np.sqrt(5), -2 / np.sqrt(5)], [-np.sqrt(0.125)] * 2,
                                [0.0, -0.5], [0.0, 0.0], [np.sqrt(0.5)] * 2])
    # the boundary of the square lands on the unit circle
    boundary = np.abs(mate.wrappers.discrete_action_spaces.square_grid(5)).max(axis=1) == 1.0
    np.testing.assert_allclose(np.linalg.norm(grid[boundary], axis=1), 1.0)


def test_discrete_target_scales_with_each_targets_speed():
    env = make_env(wrappers=[mate.DiscreteTarget])
    set_scene(env, capacities=[2, 1, 1], **SCENE)
    np.testing.assert_allclose(env.action_high, [[10, 10], [20, 20], [20, 20]])
    assert env.target_action_space == spaces.Discrete(25)
    _, moves = env.action((None, [24, 24, 7]))
    np.testing.assert_allclose(moves, [[10 * np.sqrt(0.5)] * 2, [20 * np.sqrt(0.5)] * 2, [0.0, -10.0]])
    env.step((ZERO_ACTION[0], [24, 24, 12]))
    positions = env.unwrapped.get_world()['target_state'][:, :2]
    np.testing.assert_allclose(positions, [[7.0710678, 7.0710678], [514.1421356, 314.1421356], [-300.0, 700.0]])


def test_discrete_target_reverse_action_works():
    env = make_env(wrappers=[mate.DiscreteTarget])
    set_scene(env, capacities=[2, 1, 1], **SCENE)
    _, indices = env.reverse_action(('cameras', np.array([[0.0, -5.0], [0.0, -10.0], [20 * np.sqrt(0.5)] * 2])))
    assert indices.tolist() == [7, 7, 24]
    assert indices.dtype == np.int64


@settings(max_examples=30, deadline=None)
@given(st.integers(min_value=1, max_value=4), st.data())
def test_reverse_action_inverts_action(half_levels, data):
    levels = 2 * half_levels + 1
    env = make_env(wrappers=[mate.WrapperSpec(mate.DiscreteCamera, levels=levels),
                             mate.WrapperSpec(mate.DiscreteTarget, levels=levels)])
    cameras = data.draw(st.lists(st.integers(0, levels ** 2 - 1), min_size=NC, max_size=NC))
    targets = data.draw(st.lists(st.integers(0, levels ** 2 - 1), min_size=NT, max_size=NT))
    discrete_target, discrete_camera = env, env.env
    continuous = discrete_target.action((None, targets))[1]
    assert discrete_target.reverse_action((None, continuous))[1].tolist() == targets
    continuous = discrete_camera.action((cameras, None))[0]
    assert discrete_camera.reverse_action((continuous, None))[0].tolist() == cameras
