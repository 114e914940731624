"""The PettingZoo adapter passes PettingZoo's own API, seed, max-cycles and render tests."""

from __future__ import annotations

import subprocess
import sys
import types

import numpy as np
import pytest

pytest.importorskip('pettingzoo', reason="needs pettingzoo, from the pettingzoo extra: pip install -e '.[pettingzoo]'")
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test  # noqa: E402

from mate.envs.multi_agent_tracking import MultiAgentTracking  # noqa: E402
from mate.integrations import pettingzoo as mate_pz  # noqa: E402

SMALL = {'config': 'MATE-2v4-9', 'max_episode_steps': 60}


def test_parallel_api():
    env = mate_pz.parallel_env(**SMALL)
    parallel_api_test(env, num_cycles=80)  # runs past max_episode_steps: truncation ends it
    assert env.agents == []


def test_aec_api():
    api_test(mate_pz.env(**SMALL), num_cycles=20)


def test_parallel_seed():
    parallel_seed_test(lambda: mate_pz.parallel_env(**SMALL), num_cycles=30)


def test_max_cycles():
    module = types.SimpleNamespace(parallel_env=lambda **kw: mate_pz.parallel_env(**SMALL, **kw),
                                   env=lambda **kw: mate_pz.env(**SMALL, **kw))
    max_cycles_test(module)


def test_truncation_at_max_cycles_or_max_episode_steps():
    for max_cycles, expected in ((5, 5), (None, 7), (50, 7)):
        env = mate_pz.parallel_env('MATE-2v4-9', max_cycles=max_cycles, max_episode_steps=7)
        env.reset(seed=0)
        steps = 0
        while env.agents:
            _, _, terminations, truncations, _ = env.step({a: env.action_space(a).sample() for a in env.agents})
            steps += 1
            assert not any(terminations.values())
            assert all(truncations.values()) == (steps == expected)
        assert steps == expected
        with pytest.raises(RuntimeError, match='reset'):
            env.step({})


def test_agents_spaces_rewards_state_and_equivalence_with_the_single_env():
    env = mate_pz.parallel_env('MATE-2v4-9')
    assert env.possible_agents == ['camera_0', 'camera_1', 'target_0', 'target_1', 'target_2', 'target_3']
    assert env.observation_space('camera_0') is env.observation_space('camera_0')
    assert env.action_space('camera_0') is not env.action_space('camera_1')  # seeded separately
    single = MultiAgentTracking('MATE-2v4-9')
    observations, _ = env.reset(seed=3)
    (camera_obs, target_obs), _ = single.reset(seed=3)
    np.testing.assert_array_equal(observations['camera_1'], camera_obs[1])
    np.testing.assert_array_equal(observations['target_3'], target_obs[3])
    assert env.state_space.contains(env.state())
    rng = np.random.default_rng(0)
    for _ in range(5):
        camera_actions, target_actions = rng.uniform(-2, 2, (2, 2)), rng.uniform(-5, 5, (4, 2))
        actions = {f'camera_{i}': a for i, a in enumerate(camera_actions)}
        actions.update({f'target_{i}': a for i, a in enumerate(target_actions)})
        observations, rewards, _, _, infos = env.step(actions)
        joint = single.step((camera_actions, target_actions))
        (camera_obs, target_obs), (camera_reward, target_reward) = joint[0], joint[1]
        np.testing.assert_array_equal(observations['target_2'], target_obs[2])
        assert rewards['camera_0'] == rewards['camera_1'] == camera_reward == -rewards['target_0']
        assert rewards['target_3'] == target_reward
        assert 'coverage_rate' in infos['camera_0']
    np.testing.assert_array_equal(env.state(), single.state())
    # a missing agent stays still; an unknown agent is refused
    env.step({'camera_0': [0.0, 0.0]})
    with pytest.raises(ValueError, match="unknown agent 'camera_7'"):
        env.step({'camera_7': [0.0, 0.0]})


def test_render(monkeypatch):
    pytest.importorskip('pygame', reason="needs pygame, from the render extra: pip install -e '.[render]'")
    monkeypatch.setenv('SDL_VIDEODRIVER', 'dummy')
    render_test(lambda render_mode=None: mate_pz.env(**SMALL, render_mode=render_mode))


def test_render_mode_is_passed_to_the_single_env():
    pytest.importorskip('pygame', reason="needs pygame, from the render extra: pip install -e '.[render]'")
    env = mate_pz.parallel_env(**SMALL, render_mode='rgb_array')
    assert env.env.render_mode == 'rgb_array'
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (800, 800, 3) and image.dtype == np.uint8
    assert mate_pz.parallel_env(**SMALL).render_mode is None


def test_module_is_importable_without_side_effects():
    # a fresh interpreter: this one may have imported ray already (the RLlib tests)
    code = 'import sys, mate.integrations.pettingzoo; print(sorted(m for m in sys.modules if m.split(".")[0] == "ray"))'
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == '[]', f'importing the PettingZoo adapter imported ray: {result.stdout}'
    assert mate_pz.parallel_env(**SMALL).metadata['name'] == 'mate_v0'


# --------------------------------------------------------------------------- action shapes (issue 30)

# One agent's action of the wrong shape: (team agent, action, the shape given); (2,) is expected.
WRONG_SHAPES = [
    ('camera_1', np.zeros((1, 2)), '(1, 2)'),
    ('camera_1', np.zeros((2, 1)), '(2, 1)'),
    ('camera_1', 1.0, '()'),          # a scalar is not broadcast to both entries
    ('target_2', np.zeros(4), '(4,)'),
    ('target_2', [[0.0], [0.0]], '(2, 1)'),
]


def _message(agent: str, given: str) -> str:
    fields = '[rotate, zoom]' if agent.startswith('camera') else '[dx, dy]'
    return f'action of {agent} must have shape (2,) {fields}; got {given}'


@pytest.mark.parametrize('agent, action, given', WRONG_SHAPES, ids=[f'{a}-{g}' for a, _, g in WRONG_SHAPES])
def test_parallel_refuses_an_action_of_the_wrong_shape(agent, action, given):
    env = mate_pz.parallel_env('MATE-2v4-9')
    env.reset(seed=0)
    state = env.state()
    actions = {a: np.zeros(2) for a in env.agents}
    actions[agent] = action
    with pytest.raises(ValueError) as error:
        env.step(actions)
    assert str(error.value) == _message(agent, given)
    np.testing.assert_array_equal(env.state(), state)   # the world did not advance
    assert env.num_cycles == 0
    # right shapes, of any real dtype and as lists, are accepted
    actions[agent] = np.array([1, -1], dtype=np.int32)
    actions['target_0'] = [0.5, 0.5]
    env.step(actions)
    assert env.num_cycles == 1


@pytest.mark.parametrize('agent, action, given', WRONG_SHAPES, ids=[f'{a}-{g}' for a, _, g in WRONG_SHAPES])
def test_aec_refuses_an_action_of_the_wrong_shape_at_its_turn(agent, action, given):
    env = mate_pz.env('MATE-2v4-9')
    env.reset(seed=0)
    while env.agent_selection != agent:
        env.step(np.zeros(2))
    with pytest.raises(ValueError) as error:
        env.step(action)
    assert str(error.value) == _message(agent, given)
    assert env.agent_selection == agent              # the turn did not pass: the agent acts again
    for _ in env.possible_agents[env.possible_agents.index(agent):]:
        env.step(np.zeros(2, dtype=np.float32))
    assert env.unwrapped.num_cycles == 1             # the world advanced once, with every action right
