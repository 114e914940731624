"""The RLlib adapter: MultiAgentEnv conventions, opponents, and one PPO iteration (slow, local Ray).

Skipped unless `ray[rllib]` is installed (the optional extra `mate[rllib]`)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('ray.rllib', reason="needs ray.rllib, from the rllib extra: pip install -e '.[rllib]'")
from ray.rllib.utils.pre_checks.env import check_multiagent_environments  # noqa: E402

from mate.env import MultiAgentTracking  # noqa: E402
from mate.integrations import rllib as mate_rllib  # noqa: E402

SMALL = {'config': 'MATE-2v4-9', 'overrides': {'max_episode_steps': 12}}


def test_camera_team_against_an_opponent():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': 'uniform'})
    check_multiagent_environments(env)
    assert env.possible_agents == ['camera_0', 'camera_1']
    observations, infos = env.reset(seed=0)
    assert set(observations) == set(infos) == set(env.agents)
    for agent, obs in observations.items():
        assert obs.dtype == np.float32 and env.observation_spaces[agent].contains(obs)
    steps, done = 0, False
    while not done:
        actions = {agent: env.action_spaces[agent].sample() for agent in env.agents}
        observations, rewards, terminateds, truncateds, infos = env.step(actions)
        done = terminateds['__all__'] or truncateds['__all__']
        steps += 1
        assert rewards['camera_0'] == rewards['camera_1']
        assert 0.0 <= infos['camera_0']['episode_coverage_rate'] <= 1.0
    assert steps == 12 and env.agents == []


def test_observations_are_the_single_env_rescaled():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'team': 'both'})
    single = MultiAgentTracking('MATE-2v4-9')
    observations, _ = env.reset(seed=4)
    (camera_obs, target_obs), _ = single.reset(seed=4)
    assert len(observations) == 6
    high = np.abs(single.target_observation_space.high)
    scale = np.where(np.isfinite(high) & (high > 0), np.maximum(high, np.abs(single.target_observation_space.low)), 1)
    np.testing.assert_allclose(observations['target_2'], (target_obs[2] / scale).astype(np.float32))
    _, rewards, _, _, _ = env.step({'camera_0': np.zeros(2, np.float32)})
    assert rewards['camera_0'] == -rewards['target_0']


def _target_positions(env) -> np.ndarray:
    return env.env.get_world()['target_state'][:, :2].copy()


def _still(joint_obs):
    return np.zeros((len(joint_obs), 2))


@pytest.mark.parametrize('opponent', ['greedy', 'naive', 'random', 'uniform', 'mate.agents:GreedyTargetAgent', _still],
                         ids=['greedy', 'naive', 'random', 'uniform', 'import-path', 'zeros-callable'])
def test_opponents(opponent):
    """The opponent plays the targets: the rule-based, uniform and imported ones move them at every
    step, the callable returning zeros leaves them where they are; the cameras (absent from the action
    dicts) stay still, and what RLlib gets back is well formed."""
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': opponent})
    env.reset(seed=0)
    for step in range(1, 4):
        before = _target_positions(env)
        observations, rewards, terminateds, truncateds, infos = env.step({})
        moved = np.abs(_target_positions(env) - before).max()
        if opponent is _still:
            assert moved == 0.0
        else:
            assert moved > 1.0, f'the targets did not move at step {step}'
        assert env.env.episode_step == step
        assert set(observations) == set(rewards) == set(infos) == {'camera_0', 'camera_1'}
        for agent, obs in observations.items():
            assert obs.dtype == np.float32 and np.isfinite(obs).all()
            assert env.observation_spaces[agent].contains(obs)
        assert np.isfinite(rewards['camera_0']) and rewards['camera_0'] == rewards['camera_1']
        assert terminateds['__all__'] is False and truncateds['__all__'] is False


def test_an_opponent_named_by_its_import_path_is_the_named_agent():
    paths = []
    for opponent in ('greedy', 'mate.agents:GreedyTargetAgent'):
        env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': opponent})
        env.reset(seed=0)
        for _ in range(3):
            env.step({})
        paths.append(_target_positions(env))
    np.testing.assert_array_equal(*paths)


@pytest.mark.parametrize('action, given', [(np.zeros((1, 2)), '(1, 2)'), (np.zeros(4), '(4,)'), (0.0, '()')],
                         ids=['(1, 2)', '(4,)', 'scalar'])
def test_an_action_of_the_wrong_shape_is_refused(action, given):
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'team': 'both'})
    env.reset(seed=0)
    with pytest.raises(ValueError) as error:
        env.step({'camera_0': np.zeros(2, np.float32), 'target_3': action})
    assert str(error.value) == f'action of target_3 must have shape (2,) [dx, dy]; got {given}'
    assert env.env.episode_step == 0          # the world did not advance
    with pytest.raises(ValueError, match=r"unknown agent 'referee'"):
        env.step({'referee': np.zeros(2)})
    env.step({'camera_0': np.zeros(2, np.float32), 'target_3': [1, 1]})   # (2,), any real dtype
    assert env.env.episode_step == 1


def test_an_opponent_returning_a_flat_vector_is_refused():
    env = mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': lambda joint_obs: np.zeros(2 * len(joint_obs))})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r'target joint action must have shape \(4, 2\) .*; got \(8,\)'):
        env.step({})


def test_bad_env_config_is_refused():
    with pytest.raises(ValueError, match='unknown env_config keys'):
        mate_rllib.MateMultiAgentEnv({'preset': 'MATE-2v4-9'})
    with pytest.raises(ValueError, match='team must be'):
        mate_rllib.MateMultiAgentEnv({'team': 'referee'})
    with pytest.raises(ValueError, match='unknown opponent'):
        mate_rllib.MateMultiAgentEnv({**SMALL, 'opponent': 'clever'})


@pytest.mark.slow
def test_one_ppo_iteration_on_a_local_ray_instance():
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        config = mate_rllib.ppo_config({**SMALL, 'opponent': 'uniform'}, train_batch_size=120, minibatch_size=60,
                                       num_epochs=1, hidden=(32,), seed=0)
        algo = config.build_algo()
        result = algo.train()
        algo.stop()
    finally:
        ray.shutdown()
    runners = result['env_runners']
    assert runners['num_env_steps_sampled_lifetime'] >= 120
    assert np.isfinite(runners['episode_return_mean'])
    assert 0.0 <= runners['mate/coverage_rate'] <= 1.0
