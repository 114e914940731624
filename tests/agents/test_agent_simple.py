"""Random, naive and mixture agents (spec agents-and-wrappers.md §7.1-7.3, §7.8)."""

from __future__ import annotations

import numpy as np
import pytest
from handmade import (
    camera_observation,
    camera_private,
    target_observation,
    target_private,
)

import mate

CAMERA_OBS = camera_observation(camera_private(0.0, 0.0), index=1)
TARGET_OBS = target_observation(target_private(0.0, 0.0), index=2)


# ---------------------------------------------------------------------------- random

@pytest.mark.parametrize('cls, obs', [(mate.RandomCameraAgent, CAMERA_OBS), (mate.RandomTargetAgent, TARGET_OBS)])
def test_random_actions_are_held_for_frame_skip_steps(cls, obs):
    agent = cls(seed=0, frame_skip=4)
    agent.reset(obs)
    actions = []
    for _ in range(12):
        agent.observe(obs)
        actions.append(agent.act(obs))
    for start in (0, 4, 8):
        assert all(np.array_equal(actions[start], a) for a in actions[start:start + 4])
    assert not np.array_equal(actions[0], actions[4]) and not np.array_equal(actions[4], actions[8])
    assert all(np.all(a >= agent.action_space.low) and np.all(a <= agent.action_space.high) for a in actions)


def test_random_agents_default_skip_and_validation():
    agent = mate.RandomCameraAgent(seed=1)
    assert agent.frame_skip == 20
    agent.reset(CAMERA_OBS)
    actions = [agent.act(CAMERA_OBS) for _ in range(41)]
    assert len({tuple(a) for a in actions}) == 3
    with pytest.raises(ValueError):
        mate.RandomTargetAgent(frame_skip=0)


def test_random_draws_cover_the_box():
    agent = mate.RandomTargetAgent(seed=3, frame_skip=1)
    agent.reset(TARGET_OBS)
    draws = np.array([agent.act(TARGET_OBS) for _ in range(2000)])
    assert draws.min() >= -20.0 and draws.max() <= 20.0
    np.testing.assert_allclose(draws.mean(axis=0), 0.0, atol=1.0)
    np.testing.assert_allclose(draws.std(axis=0), 40.0 / np.sqrt(12.0), rtol=0.05)


# ---------------------------------------------------------------------------- naive

def test_naive_camera_turns_and_widens_together():
    agent = mate.NaiveCameraAgent(seed=0)
    agent.reset(CAMERA_OBS)
    actions = np.array([agent.act(CAMERA_OBS) for _ in range(500)])
    assert np.all(actions[:, 0] >= 0.0) and np.all(actions[:, 0] <= 0.4 * 5.0)
    np.testing.assert_allclose(actions[:, 1], actions[:, 0] * 2.5 / 5.0)
    assert actions[:, 0].mean() == pytest.approx(1.0, abs=0.1)


def test_naive_target_tours_the_warehouses():
    agent = mate.NaiveTargetAgent(seed=0)
    agent.reset(TARGET_OBS)
    assert agent.goal in range(4) and agent.inc in (1, -1)
    goal, inc = agent.goal, agent.inc
    at_goal = target_observation(target_private(*mate.WAREHOUSES[goal], goal_bits=(0, 1, 0, 0)), index=2)
    agent.act(at_goal)
    assert agent.goal == (goal + inc) % 4                   # loaded: on to the next one
    agent.goal = goal
    unloaded_here = target_observation(target_private(*mate.WAREHOUSES[goal]), index=2)
    agent.act(unloaded_here)
    assert agent.goal == goal                               # unloaded and not seen empty: stay for cargo
    empties = [0, 0, 0, 0]
    empties[goal] = empties[(goal + inc) % 4] = 1
    skip = target_observation(target_private(*mate.WAREHOUSES[goal], empty_bits=tuple(empties)), index=2)
    agent.act(skip)
    assert agent.goal == (goal + 2 * inc) % 4               # skips the warehouses seen empty


def test_naive_target_heads_for_its_goal():
    agent = mate.NaiveTargetAgent(seed=4)
    agent.reset(TARGET_OBS)
    for _ in range(50):
        action = agent.act(TARGET_OBS)
    direction = mate.WAREHOUSES[agent.goal] / np.linalg.norm(mate.WAREHOUSES[agent.goal])
    assert np.dot(action, direction) > 0


# ---------------------------------------------------------------------------- mixture

def test_mixture_weights():
    candidates = [mate.GreedyCameraAgent(), mate.RandomCameraAgent(), mate.NaiveCameraAgent()]
    mixture = mate.MixtureCameraAgent(candidates, weights=[2, 0, 6], seed=0)
    assert mixture.candidates == (candidates[0], candidates[2])
    np.testing.assert_allclose(mixture.weights, [0.25, 0.75])
    assert '0.25' in repr(mixture) and 'GreedyCameraAgent' in repr(mixture)
    for bad in ([1, 1], [0, 0, 0], [-1, 1, 1], [np.nan, 1, 1]):
        with pytest.raises(ValueError):
            mate.MixtureCameraAgent(candidates, weights=bad)
    with pytest.raises(TypeError):
        mate.MixtureCameraAgent([mate.GreedyTargetAgent()])
    with pytest.raises(ValueError):
        mate.MixtureTargetAgent([])


def test_mixture_seed_reseeds_candidates():
    def candidates():
        return [mate.RandomTargetAgent(seed=100), mate.GreedyTargetAgent(seed=200)]
    a, b = mate.MixtureTargetAgent(candidates(), seed=5), mate.MixtureTargetAgent(candidates(), seed=5)
    c = mate.MixtureTargetAgent(candidates(), seed=6)
    first = [x.np_random.random() for x in a.candidates]
    assert first == [x.np_random.random() for x in b.candidates]
    assert first != [x.np_random.random() for x in c.candidates]
    assert len(a.seed(9)) == 3


def test_spawned_mixtures_pick_the_same_candidate_and_delegate():
    env = mate.make('MATE-4v8-9-v0')
    prototype = mate.MixtureCameraAgent([mate.GreedyCameraAgent(), mate.HeuristicCameraAgent()], seed=1)
    cameras = prototype.spawn(4)
    again = mate.MixtureCameraAgent([mate.GreedyCameraAgent(), mate.HeuristicCameraAgent()], seed=1).spawn(4)
    kinds = set()
    for episode in range(8):
        (camera_obs, _), _ = env.reset(seed=episode)
        mate.group_reset(cameras, camera_obs)
        mate.group_reset(again, camera_obs)
        chosen = {type(c.current_agent) for c in cameras}
        assert len(chosen) == 1                              # teammates share the mixture seed
        assert chosen == {type(c.current_agent) for c in again}
        kinds |= chosen
        actions = mate.group_step(env, cameras, camera_obs)
        assert len(actions) == 4
        for camera in cameras:
            assert camera.episode_step == camera.current_agent.episode_step == 0
            assert camera.last_responses == camera.current_agent.last_responses
    assert len(kinds) == 2
    assert all(c.current_agent is not d.current_agent for c, d in zip(cameras, cameras[1:]))


def test_mixture_clone_draws_from_the_prototype():
    prototype = mate.MixtureTargetAgent([mate.GreedyTargetAgent()], mixture_seed=3, seed=4)
    twin = mate.MixtureTargetAgent([mate.GreedyTargetAgent()], mixture_seed=3, seed=4)
    clone = prototype.clone()
    assert isinstance(clone, mate.MixtureTargetAgent) and clone.candidates[0] is not prototype.candidates[0]
    twin.clone()
    assert prototype.np_random.random() == twin.np_random.random()
