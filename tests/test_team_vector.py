"""The public single-team env (`mate.SingleTeamVecEnv`) and the promise that one seed gives one game through every
single-team entry point: the vector env, `play_batch` (as `mate evaluate` and `mate.score_policy` play), the
PettingZoo adapter with an opponent and the `MultiCamera` / `MultiTarget` wrappers."""

from __future__ import annotations

import numpy as np
import pytest

import mate
from mate.agents.group import group_reset, group_step
from mate.teams import GreedyTeam, play_batch

CAP = 150


def greedy(team, seed):
    return lambda num_envs, counts: GreedyTeam(team, num_envs, counts, seed=seed)


def first_episodes(envs, team_of, seed):
    """Each row's first-episode statistics of `envs` (reset with `seed`) with the greedy team `team_of` playing."""
    observations, _ = envs.reset(seed=seed)
    players = team_of(envs.num_envs, envs.counts)
    players.reset(observations, np.ones(envs.num_envs, dtype=bool))
    found = {}
    while len(found) < envs.num_envs:
        observations, rewards, terminations, truncations, infos = envs.step(players.act(observations))
        if '_mate_episode' in infos:
            for i in np.flatnonzero(infos['_mate_episode']):
                found.setdefault(int(i), {key: values[i] for key, values in infos['mate_episode'].items()})
    return [found[i] for i in range(envs.num_envs)]


@pytest.mark.parametrize('team, config', [('camera', 'MATE-4v8-9'), ('target', 'MATE-2v4-0')])
def test_rows_are_the_games_of_play_batch(team, config):
    envs = mate.make_team_vec(config, team, 3, max_episode_steps=CAP)
    stats = first_episodes(envs, greedy(team, 7), seed=7)
    results, _ = play_batch(config, greedy('camera', 7), greedy('target', 7), 3, seed=7, max_episode_steps=CAP)
    for row, result in zip(stats, results, strict=True):
        assert row['l'] == result.episode_length
        assert row['coverage_rate'] == pytest.approx(result.coverage_rate, abs=1e-12)
        assert row['normalized_target_return'] == pytest.approx(result.normalized_target_return, abs=1e-12)
        assert row['delivered_cargoes'] == result.delivered_cargoes
        own_return = result.camera_return if team == 'camera' else result.target_return
        assert row['r'] == pytest.approx(own_return, abs=1e-9)      # the 'team' reward summed


def test_spaces_shapes_and_bad_actions():
    envs = mate.make_team_vec('MATE-4v8-9', 'camera', 4)
    observations, infos = envs.reset(seed=0)
    assert observations.shape == (4, 4, envs.single_observation_space.shape[1]) == envs.observation_space.shape
    assert envs.action_space.shape == (4, 4, 2) and envs.single_action_space.shape == (4, 2)
    assert envs.state().shape == (4, envs.single_state_space.shape[0])
    with pytest.raises(ValueError, match=r'shape \(4, 4, 2\)'):
        envs.step(np.zeros((4, 8)))
    with pytest.raises(ValueError, match="one of the camera team's"):
        mate.make_team_vec('MATE-4v8-9', 'camera', 2, reward='own')
    with pytest.raises(ValueError, match='unknown opponent'):
        mate.make_team_vec('MATE-4v8-9', 'camera', 2, opponent='smart')


@pytest.mark.parametrize('team, reward', [('target', 'own'), ('target', 'team'), ('camera', 'coverage'),
                                          ('camera', 'difference')])
def test_next_step_autoreset_restarts_the_opponent_and_pays_nothing(team, reward):
    """The step that restarts a game (next_step) rewards it 0 in every reward kind (the coverage reward too, which
    would otherwise be the new episode's first coverage rate)."""
    envs = mate.make_team_vec('MATE-2v4-0', team, 2, max_episode_steps=5, reward=reward)
    observations, _ = envs.reset(seed=1)
    for _ in range(5):
        observations, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
    assert truncations.all() and infos['_mate_episode'].all() and (infos['mate_episode']['l'] == 5).all()
    observations, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
    assert rewards.shape[0] == 2 and (rewards == 0).all() and not truncations.any()
    assert (infos['episode_step'] == 0).all()
    if reward == 'coverage':
        assert infos['coverage_rate'].any()      # the new episode's first coverage rate, not paid
    observations, rewards, *_ = envs.step(envs.action_space.sample())
    assert rewards.any()                          # paid again from the episode's first step on


def test_per_agent_rewards_sum_to_the_team_reward():
    team = mate.make_team_vec('MATE-2v4-0', 'target', 2, reward='team')
    own = mate.make_team_vec('MATE-2v4-0', 'target', 2, reward='own')
    cover = mate.make_team_vec('MATE-4v8-9', 'camera', 2, reward='coverage')
    difference = mate.make_team_vec('MATE-4v8-9', 'camera', 2, reward='difference')
    for envs in (team, own, cover, difference):
        envs.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(60):
        targets = rng.uniform(-20, 20, size=(2, 4, 2))
        cameras = rng.uniform(-5, 5, size=(2, 4, 2))
        np.testing.assert_allclose(own.step(targets)[1].sum(axis=1), team.step(targets)[1], atol=1e-9)
        covered, infos = cover.step(cameras)[1::3]
        shares = difference.step(cameras)[1]
        assert (shares.sum(axis=1) <= covered + 1e-12).all() and (shares >= 0).all()
        np.testing.assert_array_equal(covered, infos['coverage_rate'])


@pytest.mark.parametrize('team', ['camera', 'target'])
def test_one_seed_one_game_through_every_single_team_entry_point(team):
    """Greedy agents of `team` against the greedy opponents: the vector env, the MultiCamera/MultiTarget wrapper and
    the PettingZoo adapter with an opponent play the same game for seed 11 (the episode of `mate evaluate`)."""
    pytest.importorskip('pettingzoo', reason='needs the pettingzoo extra')
    from mate.integrations import pettingzoo as mate_pz

    config, seed = ('MATE-4v8-9', 11) if team == 'camera' else ('MATE-2v4-0', 11)
    vector = first_episodes(mate.make_team_vec(config, team, 1, max_episode_steps=CAP), greedy(team, seed), seed)[0]
    agent = mate.GreedyCameraAgent if team == 'camera' else mate.GreedyTargetAgent
    other = mate.GreedyTargetAgent if team == 'camera' else mate.GreedyCameraAgent
    wrapper = mate.MultiCamera if team == 'camera' else mate.MultiTarget
    keyword = 'target_agent' if team == 'camera' else 'camera_agent'
    env = mate.make('MultiAgentTracking-v0', config=config, max_episode_steps=CAP,
                    wrappers=[mate.WrapperSpec(wrapper, **{keyword: other(seed=123)})])
    observation, infos = env.reset(seed=seed)
    players = agent(seed=seed).spawn(len(observation))
    group_reset(players, observation)
    coverage, length, done = [], 0, False
    while not done:
        observation, reward, terminated, truncated, infos = env.step(group_step(env, players, observation, infos))
        coverage.append(infos[0]['coverage_rate'])
        length, done = length + 1, terminated or truncated
    assert (length, float(np.mean(coverage))) == (vector['l'], pytest.approx(vector['coverage_rate'], abs=1e-12))

    zoo = mate_pz.parallel_env(config=config, opponent='greedy', team=team, max_episode_steps=CAP)
    observations, _ = zoo.reset(seed=seed)
    players = GreedyTeam(team, 1, (zoo.env.num_cameras, zoo.env.num_targets, zoo.env.num_obstacles), seed=seed)
    players.reset(np.stack([observations[a] for a in zoo.agents])[None], np.ones(1, dtype=bool))
    coverage, total = [], 0.0
    while zoo.agents:
        actions = players.act(np.stack([observations[a] for a in zoo.agents])[None])[0]
        observations, rewards, terminations, truncations, infos = zoo.step(dict(zip(zoo.agents, actions)))
        coverage.append(next(iter(infos.values()))['coverage_rate'])
        total += next(iter(rewards.values()))
    assert (len(coverage), float(np.mean(coverage))) == (vector['l'], pytest.approx(vector['coverage_rate'],
                                                                                   abs=1e-12))
    assert total == pytest.approx(vector['r'], abs=1e-9)


def test_pettingzoo_opponent_rewards_and_agents():
    pytest.importorskip('pettingzoo', reason='needs the pettingzoo extra')
    from mate.integrations import pettingzoo as mate_pz

    zoo = mate_pz.parallel_env(config='MATE-2v4-0', opponent='greedy', team='target', reward='own')
    observations, _ = zoo.reset(seed=0)
    assert zoo.agents == [f'target_{i}' for i in range(4)]
    totals = []
    for _ in range(30):
        actions = {agent: zoo.action_space(agent).sample() for agent in zoo.agents}
        observations, rewards, *_ = zoo.step(actions)
        totals.append(sum(rewards.values()))
    assert any(total != 0 for total in totals)
    with pytest.raises(ValueError, match='give opponent too'):
        mate_pz.parallel_env(team='camera')


def test_state_dict_continues_exactly():
    rng = np.random.default_rng(4)
    actions = rng.uniform(-30, 30, size=(40, 3, 4, 2))
    envs = mate.make_team_vec('MATE-2v4-0', 'target', 3, max_episode_steps=15, reward='own')
    envs.reset(seed=9)
    for step in range(20):
        envs.step(actions[step])
    saved = envs.state_dict()
    later = [[np.copy(part) if isinstance(part, np.ndarray) else part for part in envs.step(actions[step])]
             for step in range(20, 40)]    # copies: the observations are the env's buffers, overwritten in place
    again = mate.make_team_vec('MATE-2v4-0', 'target', 3, max_episode_steps=15, reward='own')
    again.load_state_dict(saved)
    for step, (observations, rewards, terminations, truncations, infos) in zip(range(20, 40), later):
        replay = again.step(actions[step])
        np.testing.assert_array_equal(replay[0], observations)
        np.testing.assert_array_equal(replay[1], rewards)
        assert ('_mate_episode' in replay[4]) == ('_mate_episode' in infos)
        if '_mate_episode' in infos:
            np.testing.assert_array_equal(replay[4]['mate_episode']['r'], infos['mate_episode']['r'])


@pytest.mark.parametrize('config, team, reward', [('MATE-2v4-0', 'target', 'own'),
                                                  ('MATE-4v8-9', 'camera', 'difference'),
                                                  ('MATE-4v8-9', 'camera', 'coverage')])
def test_an_ending_steps_rewards_are_its_own_in_either_autoreset_mode(config, team, reward):
    """With same_step the ended games are reset inside the step; their rewards still come from the step they ended
    in (the next_step env's, whose games are the same until then), not from their next episode's start."""
    rewards = {}
    for mode in ('next_step', 'same_step'):
        envs = mate.make_team_vec(config, team, 3, reward=reward, autoreset_mode=mode, max_episode_steps=5)
        envs.reset(seed=4)
        actions = np.random.default_rng(0).uniform(-5, 5, (5, 3, envs.num_agents, 2))
        for step in range(5):
            _, rewards[mode], terminated, truncated, infos = envs.step(actions[step])
        assert (terminated | truncated).all()
    assert np.array_equal(rewards['same_step'], rewards['next_step'])
    assert np.abs(rewards['next_step']).sum() > 0


def test_step_games_is_step_with_the_episode_statistics_at_every_step():
    """The training envs' step on the CPU: `step`'s numbers, `mate_episode` and its mask at every step (zeros and
    False where no game ended), no final_obs without keep_final."""
    rng = np.random.default_rng(2)
    actions = rng.uniform(-3, 3, size=(12, 2, 4, 2))
    made = [mate.make_team_vec('MATE-2v4-0', 'target', 2, max_episode_steps=5, autoreset_mode='same_step')
            for _ in range(2)]
    for envs in made:
        envs.reset(seed=3)
    ended = 0
    for step in range(12):
        expected = [np.copy(part) if isinstance(part, np.ndarray) else part for part in made[0].step(actions[step])]
        found = made[1].step_games(actions[step])
        for a, b in zip(expected[:4], found[:4]):
            np.testing.assert_array_equal(a, b)
        infos = found[4]
        assert '_mate_episode' in infos and 'final_obs' not in infos and 'final_info' not in infos
        mask = infos['_mate_episode']
        assert mask.dtype == bool and mask.shape == (2,)
        if '_mate_episode' in expected[4]:
            ended += 1
            np.testing.assert_array_equal(mask, expected[4]['_mate_episode'])
            for key, value in expected[4]['mate_episode'].items():
                np.testing.assert_array_equal(infos['mate_episode'][key], value)
        else:
            assert not mask.any() and all(not np.any(value) for value in infos['mate_episode'].values())
    assert ended >= 2
    kept = made[1].step_games(actions[0], keep_final=True)[4]
    assert set(kept) >= {'mate_episode', '_mate_episode'}


def test_an_opponent_seed_seeds_the_opponent_apart_from_the_games():
    seen = []
    factory = lambda n, counts, seed: (seen.append(seed), GreedyTeam('camera', n, counts, seed=seed))[1]  # noqa: E731
    envs = mate.make_team_vec('MATE-2v4-0', 'target', 2, opponent=factory)
    envs.reset(seed=5, opponent_seed=40)
    envs.reset(seed=5)
    assert seen[1:] == [40, 5]
    with pytest.raises(ValueError, match='opponent_seed needs an int seed'):
        envs.reset(opponent_seed=3)
    with pytest.raises(ValueError, match='opponent_seed must be a non-negative integer or None, got -1'):
        envs.reset(seed=1, opponent_seed=-1)
