"""Agent base classes (spec agents-and-wrappers.md §5): reset, step counting, seeding, clone/spawn,
observation decoders and message packing."""

from __future__ import annotations

import numpy as np
import pytest
from handmade import (
    camera_observation,
    camera_private,
    camera_public,
    target_observation,
    target_private,
)

import mate
from mate import Team


class RecordingCamera(mate.CameraAgentBase):
    """A user-style agent: act calls check_inputs, as the docs recommend."""

    def act(self, observation, info=None, deterministic=None):
        state, observation, info, messages = self.check_inputs(observation, info)
        return self.DEFAULT_ACTION.copy()


class _MixinPolicy:
    def act(self, observation, info=None, deterministic=None):
        return np.zeros(2)


class MixinCamera(_MixinPolicy, mate.CameraAgentBase):
    pass


@pytest.fixture()
def env():
    environment = mate.make('MATE-4v8-9-v0')
    environment.reset(seed=0)
    return environment


@pytest.fixture()
def cam_obs():
    return camera_observation(camera_private(100.0, 200.0, orientation=45.0), index=2,
                              targets={1: [150.0, 250.0, 500.0, 1.0]}, obstacles={4: [0.0, 0.0, 60.0]},
                              cameras={0: camera_public(-300.0, 0.0)})


def test_class_attributes():
    assert mate.CameraAgentBase.TEAM is Team.CAMERA and mate.TargetAgentBase.TEAM is Team.TARGET
    assert mate.CameraAgentBase.STATE_CLASS is mate.CameraStatePrivate
    assert mate.CameraAgentBase.TEAMMATE_STATE_CLASS is mate.CameraStatePublic
    assert mate.CameraAgentBase.OPPONENT_STATE_CLASS is mate.TargetStatePublic
    assert mate.TargetAgentBase.STATE_CLASS is mate.TargetStatePrivate
    assert mate.TargetAgentBase.OPPONENT_STATE_CLASS is mate.CameraStatePublic
    np.testing.assert_array_equal(mate.TargetAgentBase.DEFAULT_ACTION, [0.0, 0.0])
    with pytest.raises(TypeError):
        mate.CameraAgentBase()                     # act is abstract


def test_constructor_state_before_reset():
    agent = RecordingCamera(seed=3)
    assert agent.index is None and agent.num_cameras is None and agent.action_space is None
    assert agent.agent_id == 'camera_0' and agent.episode_step == -1
    assert agent.last_requests == () and agent.last_responses == ()
    with pytest.raises(RuntimeError):
        agent.convert_coordinates(np.zeros(126))
    with pytest.raises(RuntimeError):
        agent.act(np.zeros(126))


def test_reset_reads_sizes_and_index(cam_obs):
    agent = RecordingCamera(seed=0)
    agent.reset(cam_obs)
    assert (agent.num_cameras, agent.num_targets, agent.num_obstacles, agent.index) == (4, 8, 9, 2)
    assert agent.agent_id == 'camera_2'
    assert agent.num_teammates == 4 and agent.num_opponents == agent.num_adversaries == 8
    assert agent.observation_dim == 126 and agent.observation_space.shape == (126,)
    assert agent.observation_indices.tolist() == [0, 13, 22, 62, 98, 126]
    assert agent.observation_slices['self_state'] == slice(13, 22)
    assert agent.state.location.tolist() == [100.0, 200.0] and agent.state.index == 2
    np.testing.assert_array_equal(agent.action_space.high, [5.0, 2.5])
    np.testing.assert_allclose(agent.convert_coordinates(cam_obs),
                               mate.convert_coordinates(cam_obs, Team.CAMERA, 4, 8, 9))
    assert len(agent.split_observation(cam_obs)) == 5
    assert agent.rescale_observation(cam_obs).shape == (126,)
    with pytest.raises(ValueError):
        agent.reset(cam_obs[None])
    with pytest.raises(ValueError):
        agent.reset(cam_obs[:-1])


def test_check_inputs(cam_obs):
    agent = RecordingCamera(seed=0)
    agent.reset(cam_obs)
    message = mate.Message(0, 2, 'hello', Team.CAMERA)
    state, observation, info, messages = agent.check_inputs(list(cam_obs), {'messages': [message]})
    assert isinstance(state, mate.CameraStatePrivate) and observation.dtype == np.float64
    assert messages == [message]
    assert agent.check_inputs(cam_obs, None)[2] == {}
    with pytest.raises(ValueError):
        agent.check_inputs(cam_obs[:-2])


def test_observe_stores_the_step_inputs(cam_obs):
    agent = RecordingCamera(seed=0)
    agent.reset(cam_obs)
    info = {'messages': []}
    agent.observe(cam_obs, info)
    assert agent.last_observation is not None and agent.last_info is info
    np.testing.assert_array_equal(agent.state.state, cam_obs[13:22])


@pytest.mark.parametrize('cls', [RecordingCamera, MixinCamera, mate.HeuristicCameraAgent, mate.GreedyCameraAgent,
                                 mate.RandomCameraAgent, mate.NaiveCameraAgent])
def test_episode_step_counts_env_steps(cls, cam_obs):
    agent = cls(seed=0)
    agent.reset(cam_obs)
    assert agent.episode_step == -1
    for step in range(3):                          # the full protocol: observe, talk, act
        agent.observe(cam_obs, None)
        agent.send_requests()
        agent.receive_requests([])
        agent.send_responses()
        agent.receive_responses([])
        assert agent.episode_step == step
        agent.act(cam_obs, None)
        assert agent.episode_step == step
    agent.reset(cam_obs)
    assert agent.episode_step == -1
    if cls is not mate.HeuristicCameraAgent:       # heuristic cameras need observe before act
        for step in range(3):                      # a driver that only calls act counts too
            agent.act(cam_obs)
            assert agent.episode_step == step
        agent.predict(cam_obs)
        agent(cam_obs)
        assert agent.episode_step == 4


def test_seed_clone_and_spawn(cam_obs):
    agent = RecordingCamera(seed=7)
    assert agent.seed(7) == [7]
    agent.reset(cam_obs)
    seeds = agent.seed(7)
    assert len(seeds) == 2 and seeds[0] == 7
    twin = RecordingCamera(seed=7)
    twin.reset(cam_obs)
    twin.seed(7)
    np.testing.assert_array_equal(agent.action_space.sample(), twin.action_space.sample())

    prototype, other = RecordingCamera(seed=11), RecordingCamera(seed=11)
    clones = prototype.spawn(3)
    again = other.spawn(3)
    assert len(clones) == 3 and all(isinstance(c, RecordingCamera) for c in clones)
    draws = [c.np_random.random() for c in clones]
    assert draws == [c.np_random.random() for c in again]         # reproducible
    assert len(set(draws)) == 3                                    # and distinct
    assert prototype.np_random.random() == other.np_random.random()  # each clone took one draw from both


def test_clone_is_independent(cam_obs):
    agent = mate.GreedyCameraAgent(seed=1)
    agent.reset(cam_obs)
    clone = agent.clone()
    assert clone is not agent and clone.index == agent.index
    clone.time2forget[0] = 99
    assert agent.time2forget[0] != 99


def test_decoders(cam_obs):
    agent = RecordingCamera(seed=0)
    agent.reset(cam_obs)
    target, visible = agent.get_opponent_state(cam_obs, 1)
    assert visible and isinstance(target, mate.TargetStatePublic) and target.index == 1
    assert target.location.tolist() == [150.0, 250.0] and target.is_loaded
    hidden, visible = agent.get_opponent_state(cam_obs, 0)
    assert not visible and hidden.location.tolist() == [0.0, 0.0]
    obstacle, visible = agent.get_obstacle_state(cam_obs, 4)
    assert visible and obstacle.radius == 60.0
    mate_state, visible = agent.get_teammate_state(cam_obs, 0)
    assert visible and mate_state.location.tolist() == [-300.0, 0.0]
    own, visible = agent.get_teammate_state(cam_obs, 2)
    assert visible and own.orientation == pytest.approx(45.0)
    states, flags = agent.get_all_opponent_states(cam_obs)
    assert len(states) == 8 and flags == (False, True) + (False,) * 6
    assert len(agent.get_teammate_states(cam_obs)[0]) == 4
    assert sum(agent.get_all_obstacle_states(cam_obs)[1]) == 1
    for getter, count in ((agent.get_opponent_state, 8), (agent.get_teammate_state, 4),
                          (agent.get_obstacle_state, 9)):
        with pytest.raises(IndexError):
            getter(cam_obs, count)
        with pytest.raises(IndexError):
            getter(cam_obs, -1)


def test_target_decoders():
    obs = target_observation(target_private(0.0, 0.0), index=5, cameras={3: camera_public(400.0, 0.0, orientation=180)},
                             targets={1: [30.0, 40.0, 500.0, 0.0]})
    agent = mate.GreedyTargetAgent(seed=0)
    agent.reset(obs)
    camera, visible = agent.get_opponent_state(obs, 3)
    assert visible and isinstance(camera, mate.CameraStatePublic) and camera.orientation == pytest.approx(180.0)
    teammate, visible = agent.get_teammate_state(obs, 1)
    assert visible and (teammate - agent.state).norm == pytest.approx(50.0)


def test_pack_message_and_default_rounds(cam_obs):
    agent = RecordingCamera(seed=0)
    agent.reset(cam_obs)
    broadcast = agent.pack_message({'a': 1})
    assert broadcast.sender == 2 and broadcast.recipient is None and broadcast.broadcasting
    assert broadcast.team is Team.CAMERA
    direct = agent.pack_message('x', recipient=0)
    assert direct.recipient == 0 and not direct.broadcasting
    assert tuple(agent.send_requests()) == () and tuple(agent.send_responses()) == ()
    agent.receive_requests(iter([direct]))
    agent.receive_responses([broadcast])
    assert agent.last_requests == (direct,) and agent.last_responses == (broadcast,)


def test_agents_on_real_observations(env):
    (camera_obs, target_obs), _ = env.reset(seed=3)
    cameras = RecordingCamera(seed=0).spawn(env.num_cameras)
    mate.group_reset(cameras, camera_obs)
    assert sorted(c.index for c in cameras) == [0, 1, 2, 3]
    targets = mate.RandomTargetAgent(seed=0).spawn(env.num_targets)
    mate.group_reset(targets, target_obs)
    assert [t.agent_id for t in targets] == [f'target_{i}' for i in range(8)]
    for target in targets:
        assert target.action_space.high[0] == target.state.step_size
