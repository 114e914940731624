"""A rule of the game lives in the core: change it in a config and every consumer reports the same game.

The bounty rule changed (`bounty_factor` 3: three times the bounty, decaying one unit per tracked step; and the sparse
reward, which pays a delivery's bounty differently): `mate evaluate`'s single env, `play_batch`, the single-team vector
env (its team and per-target rewards, and its episode statistics) and the RLlib env report the same rewards and
episode metrics, greedy against greedy, seed by seed. The per-target rewards are the core's
(`World.target_reward_parts`) and sum to the team's."""

from __future__ import annotations

import numpy as np
import pytest

import mate
from mate.config.loader import read_config
from mate.evaluation.evaluate import play_episode
from mate.teams import GreedyTeam, play_batch

from conftest import needs_extra

CAP = 400
SEEDS = (3, 4)


def changed(reward_type: str) -> dict:
    return read_config('MATE-2v4-0', bounty_factor=3.0, reward_type=reward_type, max_episode_steps=CAP)


def greedy(team, seed):
    return lambda num_envs, counts: GreedyTeam(team, num_envs, counts, seed=seed)


@pytest.mark.parametrize('reward_type', ['dense', 'sparse'])
def test_a_changed_bounty_rule_reads_the_same_everywhere(reward_type):
    config = changed(reward_type)
    env = mate.make('MultiAgentTracking-v0', config=config)
    single = [play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed, CAP) for seed in SEEDS]
    batch = [play_batch(config, greedy('camera', seed), greedy('target', seed), 1, seed=seed,
                        max_episode_steps=CAP)[0][0] for seed in SEEDS]
    assert any(result.delivered_cargoes for result in batch)           # the rule's pay shows in these games
    for one, many in zip(single, batch, strict=True):
        for key in ('coverage_rate', 'real_coverage_rate', 'transport_rate', 'camera_return', 'target_return',
                    'normalized_target_return', 'delivered_cargoes', 'episode_length'):
            assert getattr(one, key) == pytest.approx(getattr(many, key), abs=1e-9), key

    for seed, expected in zip(SEEDS, batch, strict=True):
        team_env = mate.make_team_vec(config, 'target', 1, reward='own')
        observations, _ = team_env.reset(seed=seed)
        players = greedy('target', seed)(1, team_env.counts)
        players.reset(observations, np.ones(1, dtype=bool))
        own, episode = 0.0, None
        while episode is None:
            observations, rewards, terminations, truncations, infos = team_env.step(players.act(observations))
            world = team_env.vec.world
            assert rewards.shape == (1, 4) and rewards.sum() == pytest.approx(world.target_reward[0], abs=1e-9)
            own += rewards.sum()
            if '_mate_episode' in infos:
                episode = {key: values[0] for key, values in infos['mate_episode'].items()}
        assert own == pytest.approx(expected.target_return, abs=1e-9)
        assert episode['l'] == expected.episode_length
        for key in ('coverage_rate', 'real_coverage_rate', 'transport_rate', 'target_return',
                    'normalized_target_return', 'delivered_cargoes'):
            assert episode[key] == pytest.approx(getattr(expected, key), abs=1e-9), key


def test_the_rllib_env_reads_the_changed_rule_as_the_others():
    needs_extra('ray.rllib')
    from mate.integrations import rllib as mate_rllib

    config = changed('dense')
    for seed in SEEDS:
        expected = play_batch(config, greedy('camera', seed), greedy('target', seed), 1, seed=seed,
                              max_episode_steps=CAP)[0][0]
        env = mate_rllib.MateMultiAgentEnv({'config': config, 'team': 'target', 'opponent': 'greedy',
                                            'rescale_observations': False})
        observations, _ = env.reset(seed=seed)
        agents = sorted(observations)
        players = greedy('target', seed)(1, (env.env.num_cameras, env.env.num_targets, env.env.num_obstacles))
        players.reset(np.stack([observations[a] for a in agents])[None], np.ones(1, dtype=bool))
        total, done = 0.0, False
        while not done:
            actions = players.act(np.stack([observations[a] for a in agents])[None])[0]
            observations, rewards, terminateds, truncateds, infos = env.step(dict(zip(agents, actions)))
            total += rewards[agents[0]]
            done = terminateds['__all__'] or truncateds['__all__']
        info = infos[agents[0]]
        assert info['episode_length'] == expected.episode_length
        assert total == pytest.approx(expected.target_return, abs=1e-9)
        assert info['episode_coverage_rate'] == pytest.approx(expected.coverage_rate, abs=1e-12)
        assert info['episode_normalized_target_return'] == pytest.approx(expected.normalized_target_return, abs=1e-12)
