"""RelativeCoordinates and RescaledObservation (spec §4, §8.3): exact values, spaces, single-team use."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from wrapper_scene import NC, SCENE, ZERO_ACTION, make_env, set_scene

import mate

R0 = np.sqrt(30.0 * 1000.0 ** 2 / 60.0)


def test_relative_coordinates_of_camera_0():
    env = make_env(wrappers=[mate.RelativeCoordinates])
    set_scene(env, goals=[3, 0, 1], **SCENE)
    (camera_obs, target_obs), *_ = env.step(ZERO_ACTION)
    row = camera_obs[0]                                  # camera 0 at (-500, 0)
    np.testing.assert_allclose(row[4:12], [1425, 925, -425, 925, -425, -925, 1425, -925])   # warehouses
    np.testing.assert_allclose(row[13:15], [-500, 0])                                     # own state: absolute
    np.testing.assert_allclose(row[22:37], [500, 0, 300, 1, 1] + [0] * 10)                  # t0 seen; t1, t2 stay 0
    np.testing.assert_allclose(row[37:45], [500, 800, 50, 1, 500, -800, 50, 1])              # both obstacles flagged
    np.testing.assert_allclose(row[45:59], [0, 0, 40, R0, 0, 60, 1] + [0] * 7, atol=1e-9)   # itself at (0, 0)
    target = target_obs[1]                               # target 1 at (500, 300) sees camera 1 at (500, 0)
    np.testing.assert_allclose(target[27:41], [0] * 7 + [0, -300, 40, 0, 1000, 30, 1], atol=1e-9)
    np.testing.assert_allclose(target[49:64], [0] * 5 + [0, 0, 300, 1, 1] + [0] * 5)
    assert env.observation_space == env.unwrapped.observation_space


def test_rescaled_observation_values_and_spaces():
    env = make_env(wrappers=[mate.RescaledObservation])
    set_scene(env, goals=[3, 0, 1], capacities=[2, 1, 1], **SCENE)
    (camera_obs, target_obs), *_ = env.step(ZERO_ACTION)
    row = camera_obs[0]
    np.testing.assert_allclose(row[:4], [2, 3, 2, 0])                                     # counts, index
    np.testing.assert_allclose(row[4:6], [0.4625, 0.4625])                                 # 925 / 2000
    assert row[12] == pytest.approx(75 / 500 - 1)                                          # warehouse half-width
    np.testing.assert_allclose(row[13:22], [-0.25, 0, 40 / 500 - 1, R0 / 2000, 0, 60 / 90 - 1, 0,
                                            5 / 90 - 1, 2.5 / 90 - 1], atol=1e-12)
    np.testing.assert_allclose(row[22:27], [0, 0, 300 / 1000 - 1, 1, 1])                   # visible target 0
    np.testing.assert_allclose(row[27:32], [0, 0, -1, 0, 0])                                # invisible: radius-like -1
    np.testing.assert_allclose(row[37:41], [0, 0.4, 50 / 500 - 1, 1])
    target = target_obs[0]                                                                  # capacity 2, goal 3
    np.testing.assert_allclose(target[13:27], [0, 0, -0.7, 1, 10 / 1000 - 1, 1, 0, 0, 0, 1, 0, 0, 0, 0])
    assert target_obs[1][17:19].tolist() == [20 / 1000 - 1, -1]                             # capacity 1
    for observation, space in ((camera_obs, env.camera_observation_space), (target_obs, env.target_observation_space)):
        assert all(space.contains(r) for r in observation)
        bounded = np.isfinite(space.high)
        assert (space.low[bounded] >= -1).all() and (space.high[bounded] <= 1).all()
    assert env.observation_space == spaces.Tuple((env.camera_joint_observation_space,
                                                  env.target_joint_observation_space))


def test_relative_and_rescaled_commute():
    a = make_env(wrappers=[mate.RelativeCoordinates, mate.RescaledObservation])
    b = make_env(wrappers=[mate.RescaledObservation, mate.RelativeCoordinates])
    for env in (a, b):
        set_scene(env, goals=[3, 0, 1], **SCENE)
    out_a, out_b = a.step(ZERO_ACTION)[0], b.step(ZERO_ACTION)[0]
    np.testing.assert_allclose(out_a[0], out_b[0], atol=1e-12)
    np.testing.assert_allclose(out_a[1], out_b[1], atol=1e-12)


def test_single_team_observations():
    greedy = mate.GreedyTargetAgent(seed=0)
    env = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=greedy), mate.RelativeCoordinates,
                             mate.RescaledObservation])
    observation, _ = env.reset(seed=0)
    raw = env.unwrapped.joint_observation()[0]
    expected = mate.rescale_observation(mate.convert_coordinates(raw, mate.Team.CAMERA, 2, 3, 2),
                                        mate.Team.CAMERA, 2, 3, 2)
    np.testing.assert_allclose(observation, expected)
    assert env.observation_space == spaces.Tuple((env.camera_observation_space,) * NC)
    assert env.camera_observation_space.high[4] == 1.0

    single = make_env(wrappers=[mate.WrapperSpec(mate.SingleTarget, other_target_agent=mate.GreedyTargetAgent(seed=0),
                                                 camera_agent=mate.GreedyCameraAgent(seed=0)),
                                mate.RescaledObservation])
    observation, _ = single.reset(seed=0)
    assert observation.shape == (64,) and single.observation_space.contains(observation)
    assert single.observation_space == single.target_observation_space
