"""An agent's behaviour is a function of its seed and of what it observed since reset.

Reusing agent objects must replay a seeded episode exactly: play episode A, then another episode B,
then A again with the same objects (reseeded as before A); the actions of both plays of A must be
identical, and identical to those of newly built agents. Gymnasium's `check_env` runs the same kind
of check on the single/multi-team wrappers, which own agents.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import mate
import mate.agents
from mate.policies.policy import PolicyCameraAgent, PolicyTargetAgent, load_agent

STEPS = 45          # greedy/heuristic agents act at random with probability 0.01 per step; random ones redraw every 20


def _mixture(team):
    if team is mate.Team.CAMERA:
        return mate.MixtureCameraAgent([mate.RandomCameraAgent(frame_skip=3), mate.GreedyCameraAgent()],
                                       weights=[1, 1], mixture_seed=7, seed=0)
    return mate.MixtureTargetAgent([mate.RandomTargetAgent(frame_skip=3), mate.GreedyTargetAgent()],
                                   weights=[1, 1], mixture_seed=7, seed=0)


def _policy(name, team, **kwargs):
    factory = load_agent(f'pretrained:{name}', team)
    return factory(seed=0, deterministic=False, **kwargs)   # sampling: the agent's generator matters


# name -> (preset, camera prototype factory, target prototype factory): every built-in agent class
# appears once on each team it belongs to.
SETTINGS = {
    'random': ('MATE-4v8-9', lambda: mate.RandomCameraAgent(seed=0, frame_skip=7),
               lambda: mate.RandomTargetAgent(seed=1, frame_skip=7)),
    'naive': ('MATE-4v8-9', lambda: mate.NaiveCameraAgent(seed=0), lambda: mate.NaiveTargetAgent(seed=1)),
    'greedy': ('MATE-4v8-9', lambda: mate.GreedyCameraAgent(seed=0), lambda: mate.GreedyTargetAgent(seed=1)),
    'heuristic': ('MATE-4v8-9', lambda: mate.HeuristicCameraAgent(seed=0),
                  lambda: mate.HeuristicTargetAgent(seed=1)),
    'mixture': ('MATE-4v8-9', lambda: _mixture(mate.Team.CAMERA), lambda: _mixture(mate.Team.TARGET)),
    'policy-cameras': ('MATE-4v8-9', lambda: _policy('hrl-mappo-camera-4v8-9', mate.Team.CAMERA, frame_skip=3),
                       lambda: mate.GreedyTargetAgent(seed=1)),
    'policy-targets': ('MATE-2v4-0', lambda: mate.GreedyCameraAgent(seed=0),
                       lambda: _policy('mappo-target-2v4-0', mate.Team.TARGET, frame_skip=3)),
    'upper-bound': ('MATE-4v8-9', lambda: mate.UpperBoundCameraAgent(seed=0), lambda: mate.GreedyTargetAgent(seed=1)),
}
SEES_TRUE_STATE = {'upper-bound'}
"""Settings whose cameras read the true state: played with `EnhancedObservation` on the cameras."""


def _play(env, cameras, targets, seed):
    """One seeded episode of STEPS steps: the env and every agent reseeded from `seed`; all actions (S, N, 2)."""
    (camera_obs, target_obs), _ = env.reset(seed=seed)
    for offset, agent in enumerate([*cameras, *targets]):
        agent.seed(1000 * seed + offset)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    camera_infos = target_infos = None
    actions = []
    for _ in range(STEPS):
        camera_actions = mate.group_step(env, cameras, camera_obs, camera_infos)
        target_actions = mate.group_step(env, targets, target_obs, target_infos)
        actions.append(np.concatenate([np.asarray(camera_actions), np.asarray(target_actions)]))
        (camera_obs, target_obs), _, terminated, truncated, (camera_infos, target_infos) = env.step(
            (camera_actions, target_actions))
        if terminated or truncated:
            break
    return np.stack(actions)


@pytest.mark.parametrize('setting', sorted(SETTINGS))
def test_reused_agents_replay_a_seeded_episode(setting):
    preset, make_camera, make_target = SETTINGS[setting]
    wrappers = [lambda env: mate.EnhancedObservation(env, team='camera')] if setting in SEES_TRUE_STATE else []
    env = mate.make(f'{preset}-v0', wrappers=wrappers)

    def team():
        return make_camera().spawn(env.num_cameras), make_target().spawn(env.num_targets)

    cameras, targets = team()
    first = _play(env, cameras, targets, seed=3)
    other = _play(env, cameras, targets, seed=4)
    again = _play(env, cameras, targets, seed=3)
    fresh = _play(env, *team(), seed=3)
    assert not np.array_equal(first, other)          # the seed matters: the comparison below could fail
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first, fresh)


def test_every_builtin_agent_class_is_covered():
    """A new agent class in mate.agents must be added to SETTINGS."""
    builtin = {getattr(mate.agents, name) for name in mate.agents.__all__ if name.endswith('Agent')
               and not name.endswith('BaseAgent')} - {mate.agents.AgentBase}
    covered = set()
    for _, make_camera, make_target in SETTINGS.values():
        for agent in (make_camera(), make_target()):
            covered.add(type(agent))
            covered.update(type(c) for c in getattr(agent, 'candidates', ()))
    assert builtin <= covered, sorted(c.__name__ for c in builtin - covered)
    assert {PolicyCameraAgent, PolicyTargetAgent} <= covered


def test_reseeding_draws_nothing_from_the_new_generator():
    """seed(s) leaves the generator where seeding.np_random(s) starts it, before and after a reset."""
    env = mate.make('MATE-4v8-9-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    agent = mate.GreedyCameraAgent(seed=5)
    expected = np.random.default_rng(5).random(3)    # gymnasium seeds a PCG64 Generator the same way
    np.testing.assert_array_equal(agent.np_random.random(3), expected)
    agent.reset(camera_obs[0])
    agent.seed(5)
    np.testing.assert_array_equal(agent.np_random.random(3), expected)


def test_reseeded_mixture_replays_its_choice_of_candidates():
    env = mate.make('MATE-4v8-9-v0')
    (camera_obs, _), _ = env.reset(seed=0)
    agent = mate.MixtureCameraAgent([mate.RandomCameraAgent(), mate.GreedyCameraAgent()], seed=0)

    def choices():
        agent.seed(11)
        picked = []
        for _ in range(12):
            agent.reset(camera_obs[0])
            picked.append(type(agent.current_agent).__name__)
        return picked

    first = choices()
    assert len(set(first)) == 2
    assert choices() == first


def test_messages_and_state_views_compare_by_value():
    state = mate.CameraStatePrivate.from_values([1.0] * mate.CameraStatePrivate.DIM, 0)
    twin = mate.CameraStatePrivate(np.ones(mate.CameraStatePrivate.DIM), 0)
    assert state == twin and state is not twin
    assert state != mate.CameraStatePrivate(np.ones(mate.CameraStatePrivate.DIM), 1)
    assert state != mate.CameraStatePublic(np.ones(mate.CameraStatePublic.DIM), 0)

    def message(content):
        return mate.Message(sender=0, recipient=1, content=content, team=mate.Team.CAMERA)

    assert message({'state': state, 'goal': np.arange(3.0)}) == message({'state': twin, 'goal': np.arange(3.0)})
    assert message({'goal': np.arange(3.0)}) != message({'goal': np.arange(4.0)})
    assert message({'goal': np.arange(3.0)}) != message({'goal': np.array([0.0, 1.0, 5.0])})
    assert message([1, 2]) != message((1, 2))
    assert message({'a': 1}) != mate.Message(sender=0, recipient=None, content={'a': 1}, team=mate.Team.CAMERA)


WRAPPERS = {
    'SingleCamera': lambda env: mate.SingleCamera(env, mate.GreedyCameraAgent(seed=0), mate.GreedyTargetAgent(seed=1)),
    'SingleTarget': lambda env: mate.SingleTarget(env, mate.GreedyTargetAgent(seed=0), mate.GreedyCameraAgent(seed=1)),
    'MultiCamera': lambda env: mate.MultiCamera(env, mate.HeuristicTargetAgent(seed=1)),
    'MultiTarget': lambda env: mate.MultiTarget(env, mate.GreedyCameraAgent(seed=1)),
}


@pytest.mark.parametrize('name', sorted(WRAPPERS))
def test_single_and_multi_team_wrappers_pass_gymnasium_check_env(name):
    env = WRAPPERS[name](mate.make('MATE-4v8-9-v0'))
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')   # advice on unbounded boxes and non-normalised actions
        check_env(env, skip_render_check=True)


def test_team_infos_read_as_a_dict_and_as_the_list_of_agent_infos():
    env = mate.MultiCamera(mate.make('MATE-4v8-9-v0'), mate.GreedyTargetAgent(seed=1))
    _, infos = env.reset(seed=0)
    observation, _, _, _, infos = env.step(env.action_space.sample())
    assert isinstance(infos, dict) and list(infos.keys()) == [0, 1, 2, 3]
    as_list = [infos[i] for i in range(4)]
    assert list(infos) == as_list and infos == as_list and infos[-1] is as_list[-1] and infos[1:3] == as_list[1:3]
    assert all(isinstance(info, dict) and 'coverage_rate' in info for info in infos)
    cameras = mate.GreedyCameraAgent(seed=0).spawn(4)
    mate.group_reset(cameras, observation)
    assert len(mate.group_step(env, cameras, observation, infos)) == 4
