"""MultiCamera, MultiTarget, SingleCamera, SingleTarget (spec §8.6): the opponent is any agent, its actions and
messages go through the inner env, seeding and shuffling are reproducible."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from wrapper_scene import CONFIG, D_C, D_T, NC, NT, SCENE, make_env, set_scene

import mate
from mate import Message, Team


class EastTarget(mate.TargetAgentBase):
    """Moves 5 units east every step and broadcasts its index in the responses round."""

    def act(self, observation, info=None, deterministic=None):
        self.check_inputs(observation, info)
        return np.array([5.0, 0.0])

    def send_responses(self):
        return [self.pack_message({'from': self.index})]


class TurningCamera(mate.CameraAgentBase):
    """Turns 1 degree counter-clockwise every step."""

    def act(self, observation, info=None, deterministic=None):
        self.check_inputs(observation, info)
        return np.array([1.0, 0.0])


def world(env):
    return env.unwrapped.get_world()


def turned(before, after):
    """Camera rotation between two snapshots, degrees in [-180, 180)."""
    return (after['camera_orientation'] - before['camera_orientation'] + 180.0) % 360.0 - 180.0


def test_multi_camera_with_a_custom_opponent():
    env = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=EastTarget(seed=0))])
    observation, infos = env.reset(seed=0)
    assert observation.shape == (NC, D_C) and len(infos) == NC
    assert env.action_space == env.unwrapped.camera_joint_action_space
    assert env.observation_space == env.unwrapped.camera_joint_observation_space
    assert str(env).startswith('<MultiCamera(opponent=test_single_team.EastTarget)<MultiAgentTracking>')
    before = world(env)
    observation, reward, terminated, truncated, infos = env.step(np.array([[2.0, 1.0], [-3.0, 0.0]]))
    after = world(env)
    np.testing.assert_allclose(after['target_state'][:, :2] - before['target_state'][:, :2], [[5.0, 0.0]] * NT)
    np.testing.assert_allclose(turned(before, after), [2.0, -3.0])
    assert isinstance(reward, float) and isinstance(terminated, bool) and isinstance(truncated, bool)
    assert reward == infos[0]['raw_reward']
    # the opponents talked through the inner env: every target got every broadcast (itself included)
    target_infos = env.opponent_infos
    assert [len(info['messages']) for info in target_infos] == [NT] * NT
    assert env.opponent_agents[0].last_responses[0].content == {'from': 0}


def test_multi_target_with_discrete_cameras_inside():
    env = make_env(wrappers=[mate.DiscreteTarget,
                             mate.WrapperSpec(mate.MultiTarget, camera_agent=TurningCamera(seed=0))])
    observation, _ = env.reset(seed=0)
    assert observation.shape == (NT, D_T)
    assert env.action_space == spaces.Tuple((spaces.Discrete(25),) * NT)
    set_scene(env, **SCENE)
    env.opponent_observation = env.unwrapped.joint_observation()[0]
    env.step([12, 12, 12])
    np.testing.assert_allclose(world(env)['camera_orientation'], [1.0, 91.0])


def test_own_team_messages_only():
    env = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=EastTarget(seed=0))])
    env.send_messages(Message(sender=0, recipient=1, content='hello', team=Team.CAMERA))
    assert [len(m) for m in env.receive_messages()] == [0, 1]                    # copies of the step buffers
    assert env.receive_messages(agent_id=(Team.CAMERA, 1))[0].content == 'hello'
    assert env.receive_messages(agent_id=(Team.CAMERA, 1)) == []                 # that queue was drained
    with pytest.raises(ValueError, match='only sends messages of team CAMERA'):
        env.send_messages(Message(sender=0, recipient=1, content='x', team=Team.TARGET))


def test_filters_inside_act_on_opponents_outside_only_on_own_team():
    inside = make_env(wrappers=[mate.NoCommunication,
                                mate.WrapperSpec(mate.MultiCamera, target_agent=EastTarget(seed=0))])
    inside.step(np.zeros((NC, 2)))
    assert [len(info['messages']) for info in inside.opponent_infos] == [0] * NT
    outside = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=EastTarget(seed=0)),
                                 mate.NoCommunication])
    outside.send_messages(Message(sender=0, recipient=None, content='x', team=Team.CAMERA))
    *_, camera_infos = outside.step(np.zeros((NC, 2)))
    assert [len(info['messages']) for info in camera_infos] == [0, 0]
    assert [len(info['messages']) for info in outside.opponent_infos] == [NT] * NT


def test_single_camera_drives_its_teammates():
    env = make_env(wrappers=[mate.WrapperSpec(mate.SingleCamera, other_camera_agent=TurningCamera(seed=0),
                                              target_agent=EastTarget(seed=0))])
    observation, info = env.reset(seed=0)
    assert env.index == NC - 1                                                   # no shuffling: the last slot
    assert observation.shape == (D_C,) and observation[3] == env.index
    assert env.action_space == env.unwrapped.camera_action_space
    before = world(env)
    observation, reward, _, _, info = env.step(np.array([-2.0, 0.0]))
    after = world(env)
    np.testing.assert_allclose(turned(before, after), [1.0, -2.0])
    np.testing.assert_allclose(after['target_state'][:, :2] - before['target_state'][:, :2], [[5.0, 0.0]] * NT)
    assert isinstance(reward, float) and info['raw_reward'] == reward
    with pytest.raises(ValueError, match='controls agent 1'):
        env.send_messages(Message(sender=0, recipient=1, content='x', team=Team.CAMERA))
    env.send_messages(Message(sender=1, recipient=1, content='note', team=Team.CAMERA))
    assert [m.content for m in env.receive_messages()] == ['note']


def test_single_target_with_repeated_reward_inside():
    env = make_env(wrappers=[mate.RepeatedRewardIndividualDone,
                             mate.WrapperSpec(mate.SingleTarget, other_target_agent=EastTarget(seed=0),
                                              camera_agent=TurningCamera(seed=0))])
    observation, _ = env.reset(seed=0)
    assert env.index == NT - 1 and observation.shape == (D_T,)
    before = world(env)
    _, reward, terminated, truncated, _ = env.step(np.array([0.0, -5.0]))
    after = world(env)
    np.testing.assert_allclose(after['target_state'][:, :2] - before['target_state'][:, :2],
                               [[5.0, 0.0], [5.0, 0.0], [0.0, -5.0]])
    assert isinstance(reward, float) and terminated is False and truncated is False


def test_shuffled_slots_are_reproducible():
    config = {**CONFIG, 'shuffle_entities': True}

    def run(seed):
        env = make_env(config=config, wrappers=[mate.WrapperSpec(
            mate.SingleTarget, other_target_agent=mate.GreedyTargetAgent(seed=1),
            camera_agent=mate.GreedyCameraAgent(seed=2))])
        out = []
        for episode in range(3):
            observation, _ = env.reset(seed=seed) if episode == 0 else env.reset()
            trace = [env.index]
            for _ in range(5):
                observation, *_ = env.step(np.array([3.0, 4.0]))
            trace.append(observation.round(9).tolist())
            out.append(trace)
        return out

    first, second = run(7), run(7)
    assert first == second
    assert len({trace[0] for seed in (7, 8, 9, 10) for trace in run(seed)}) > 1   # the controlled slot varies


def test_greedy_opponents_are_seeded_by_reset():
    def rewards(seed):
        env = make_env(wrappers=[mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent()),
                                 mate.RepeatedRewardIndividualDone])
        env.reset(seed=seed)
        return [env.step(np.zeros((NC, 2)))[1][0] for _ in range(20)], world(env)['target_state'].round(9).tolist()

    assert rewards(11) == rewards(11)
