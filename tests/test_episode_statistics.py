"""Episode metrics are counted once, by the core (`mate.core.world.episode_statistics`), and every consumer reads
them: the single env's and the vector env's infos, `mate evaluate` (single env and batched), the single-team env's
`infos['mate_episode']`. They equal what a user adds up step by step, and the two evaluation paths now agree exactly."""

from __future__ import annotations

import numpy as np

import mate
from mate.evaluation.evaluate import play_episode
from mate.teams import GreedyTeam
from mate.teams.play import play_batch


def test_the_single_envs_infos_hold_the_episode_so_far():
    env = mate.make('MATE-2v4-0-v0')
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    coverage, real, target_return = [], [], 0.0
    for step in range(1, 121):
        action = (rng.uniform(-20, 20, (env.num_cameras, 2)), rng.uniform(-20, 20, (env.num_targets, 2)))
        _, (camera_reward, target_reward), terminated, truncated, (camera_infos, target_infos) = env.step(action)
        info = camera_infos[0]
        coverage.append(info['coverage_rate'])
        real.append(info['real_coverage_rate'])
        target_return += target_reward
        running = 0.0
        for value in coverage:           # the core adds step by step: the same sum, to the last bit
            running += value
        assert info['episode_coverage_rate'] == running / step
        assert info['episode_target_return'] == target_return
        assert target_infos[0]['episode_coverage_rate'] == info['episode_coverage_rate']
    assert abs(info['episode_real_coverage_rate'] - np.mean(real)) < 1e-12
    env.reset(seed=6)
    _, _, _, _, (camera_infos, _) = env.step((np.zeros((env.num_cameras, 2)), np.zeros((env.num_targets, 2))))
    assert camera_infos[0]['episode_coverage_rate'] == camera_infos[0]['coverage_rate']   # a new episode: one step


def test_the_vector_envs_final_info_holds_the_ended_episodes():
    vec = mate.make_vec('MATE-2v4-0-v0', num_envs=3, autoreset_mode='same_step', max_episode_steps=7)
    vec.reset(seed=0)
    sums = np.zeros(3)
    for step in range(1, 8):
        actions = (np.zeros((3, vec.num_cameras, 2)), np.full((3, vec.num_targets, 2), 5.0))
        _, _, terminated, truncated, infos = vec.step(actions)
        if step < 7:
            sums += infos['coverage_rate']
            assert np.array_equal(infos['episode_coverage_rate'], sums / step)
    assert truncated.all()
    final = infos['final_info']
    assert np.array_equal(final['episode_coverage_rate'], (sums + final['coverage_rate']) / 7)
    assert np.array_equal(infos['episode_coverage_rate'], np.zeros(3))       # the next episodes, not stepped yet


def test_the_single_env_and_the_batched_games_report_the_same_episodes_exactly():
    seeds = range(3)
    batch, _ = play_batch('MATE-4v8-9', lambda b, counts: GreedyTeam('camera', b, counts, seed=0),
                          lambda b, counts: GreedyTeam('target', b, counts, seed=0), len(seeds), seed=0,
                          max_episode_steps=300)
    env = mate.make('MATE-4v8-9-v0')
    for seed, batched in zip(seeds, batch):
        single = play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed, 300)
        for key in ('coverage_rate', 'real_coverage_rate', 'transport_rate', 'camera_return', 'target_return',
                    'normalized_target_return', 'delivered_cargoes', 'episode_length'):
            assert getattr(batched, key) == getattr(single, key), key


def test_the_single_team_envs_episodes_are_the_cores():
    team = mate.make_team_vec('MATE-2v4-0', team='target', num_envs=2, max_episode_steps=9)
    team.reset(seed=1)
    for _ in range(9):
        _, _, _, truncations, infos = team.step(np.full((2, team.num_agents, 2), 3.0))
    assert truncations.all() and infos['_mate_episode'].all()
    episode = infos['mate_episode']
    assert np.array_equal(episode['l'], [9, 9])
    game = infos.get('final_info', infos)
    assert np.array_equal(episode['coverage_rate'], game['episode_coverage_rate'])
    assert np.array_equal(episode['target_return'], game['episode_target_return'])


def test_one_rows_statistics_are_the_batchs_row_exactly():
    """`episode_statistics(params, world, row=b)` (Python floats, the single env's infos) is row b of the batch's
    arrays bit for bit, dense and sparse rewards, before the first step (0) and after episodes ended."""
    from mate.core.world import episode_statistics

    for sparse in (False, True):
        vec = mate.make_vec('MATE-4v8-9-v0', 5, max_episode_steps=7, reward_type='sparse' if sparse else 'dense')
        vec.reset(seed=3)
        for step in range(12):
            batch = episode_statistics(vec.params, vec.world)
            for b in range(5):
                one = episode_statistics(vec.params, vec.world, row=b)
                assert set(one) == set(batch) and all(type(value) is float for value in one.values())
                assert all(one[key] == batch[key][b] for key in batch), (sparse, step, b)
            vec.step(vec.action_space.sample())
        assert vec.params.sparse_reward == sparse
