"""Group helpers and the request/response message protocol (spec agents-and-wrappers.md §5.6, §6)."""

from __future__ import annotations

import numpy as np
import pytest

import mate
from mate import Team


class Chatty(mate.CameraAgentBase):
    """Logs every call; asks the next camera a question and answers every question it got."""

    log: list

    def reset(self, observation):
        super().reset(observation)
        self.log = []

    def observe(self, observation, info=None):
        super().observe(observation, info)
        self.log.append(('observe', self.episode_step))

    def send_requests(self):
        self.log.append(('send_requests',))
        return [self.pack_message(('question', self.index), recipient=(self.index + 1) % self.num_cameras)]

    def receive_requests(self, messages):
        super().receive_requests(messages)
        self.log.append(('receive_requests', [m.content for m in self.last_requests]))

    def send_responses(self):
        self.log.append(('send_responses',))
        return [self.pack_message(('answer', self.index), recipient=m.sender) for m in self.last_requests]

    def receive_responses(self, messages):
        super().receive_responses(messages)
        self.log.append(('receive_responses', [m.content for m in self.last_responses]))

    def act(self, observation, info=None, deterministic=None):
        self.log.append(('act', deterministic))
        return np.array([1.0, 0.0])


class Silent(mate.TargetAgentBase):
    def send_requests(self):
        return None                          # tolerated: treated as no messages

    def act(self, observation, info=None, deterministic=None):
        return np.zeros(2)


@pytest.fixture()
def env():
    return mate.make('MATE-4v8-9-v0')


def test_group_step_runs_the_protocol_in_order(env):
    (camera_obs, target_obs), _ = env.reset(seed=0)
    cameras, targets = Chatty(seed=0).spawn(4), Silent(seed=0).spawn(8)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    actions = mate.group_step(env, cameras, camera_obs, None, deterministic=True)
    assert len(actions) == 4 and all(np.array_equal(a, [1.0, 0.0]) for a in actions)
    first = cameras[0]
    assert [entry[0] for entry in first.log] == ['observe', 'send_requests', 'receive_requests', 'send_responses',
                                                  'receive_responses', 'act']
    # camera 0 is asked by camera 3 (sent after it in the same pass) and answered by camera 1
    assert first.log[2] == ('receive_requests', [('question', 3)])
    assert first.log[4] == ('receive_responses', [('answer', 1)])
    assert first.log[5] == ('act', True)
    target_actions = mate.group_step(env, targets, target_obs)
    (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step((actions, target_actions))
    delivered = [m.content for m in camera_infos[0]['messages']]
    assert delivered == [('question', 3), ('answer', 1)]
    assert camera_infos[0]['out_communication_edges'] == 2 and target_infos[0]['messages'] == []
    mate.group_step(env, cameras, camera_obs, camera_infos)
    assert first.log[6] == ('observe', 1)


def test_messages_sent_before_the_step_arrive_in_the_requests_round(env):
    (camera_obs, _), _ = env.reset(seed=0)
    cameras = mate.RandomCameraAgent(seed=0).spawn(4)
    mate.group_reset(cameras, camera_obs)
    env.send_messages(mate.Message(sender=1, recipient=None, content='hi', team=Team.CAMERA))
    mate.group_observe(cameras, camera_obs)
    mate.group_communicate(env, cameras)
    assert all([m.content for m in c.last_requests] == ['hi'] for c in cameras)
    assert all(c.last_responses == () for c in cameras)


def test_group_helpers_pair_rows_and_infos(env):
    (camera_obs, target_obs), (camera_infos, _) = env.reset(seed=1)
    cameras = mate.GreedyCameraAgent(seed=0).spawn(4)
    mate.group_reset(cameras, camera_obs)
    assert [c.index for c in cameras] == [int(row[3]) for row in camera_obs]
    mate.group_observe(cameras, camera_obs, camera_infos)
    assert all(c.last_info is info for c, info in zip(cameras, camera_infos))
    actions = mate.group_act(cameras, camera_obs, camera_infos)
    assert len(actions) == 4 and all(a.shape == (2,) for a in actions)


def test_two_team_loop_with_every_builtin_pair_runs():
    for camera_cls, target_cls in [(mate.RandomCameraAgent, mate.NaiveTargetAgent),
                                   (mate.NaiveCameraAgent, mate.HeuristicTargetAgent),
                                   (mate.HeuristicCameraAgent, mate.GreedyTargetAgent)]:
        env = mate.make('MATE-4v4-9-v0')
        (camera_obs, target_obs), _ = env.reset(seed=2)
        cameras, targets = camera_cls(seed=1).spawn(env.num_cameras), target_cls(seed=1).spawn(env.num_targets)
        mate.group_reset(cameras, camera_obs)
        mate.group_reset(targets, target_obs)
        camera_infos = target_infos = None
        for _ in range(30):
            camera_actions = mate.group_step(env, cameras, camera_obs, camera_infos)
            target_actions = mate.group_step(env, targets, target_obs, target_infos)
            for action, agent in zip(camera_actions + target_actions, cameras + targets):
                assert np.all(action >= agent.action_space.low) and np.all(action <= agent.action_space.high)
            (camera_obs, target_obs), _, _, _, (camera_infos, target_infos) = env.step(
                (camera_actions, target_actions))
        assert cameras[0].episode_step == targets[0].episode_step == 29
