"""Gymnasium's own vector wrappers (`gymnasium.wrappers.vector`) over mate's vector envs, as a CleanRL file stacks
them: each wrapper wraps the single-team env (`mate.make_team_vec`), or `mate.AgentsAsEnvs` over it for the
per-agent rewards, steps it across episode ends (5-step episodes, next-step autoreset) and is checked against a
twin env stepped bare with the same seed and actions. The two-team env (`mate.make_vec`) takes the reward wrappers
through `mate.TeamReward`."""

from __future__ import annotations

import os

import gymnasium
import numpy as np
import pytest
from gymnasium.wrappers import vector as wrappers

import mate

os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')

CAP = 5           # env steps per episode
STEPS = 13        # two whole episodes, the restart steps between them and two steps of a third
B = 3


def team_env(reward='coverage', team='camera', **kwargs):
    config = 'MATE-4v8-9' if team == 'camera' else 'MATE-2v4-0'
    return mate.make_team_vec(config, team, B, reward=reward, max_episode_steps=CAP, **kwargs)


def agent_env(reward='difference', team='camera', **kwargs):
    return mate.AgentsAsEnvs(team_env(reward, team, **kwargs))


def actions_of(space, steps=STEPS, scale=1.0, seed=0):
    """Seeded actions within `space` (times `scale`), one array per step."""
    rng = np.random.default_rng(seed)
    return [scale * rng.uniform(space.low, space.high) for _ in range(steps)]


def copied(value):
    """A copy of an array, or of each array of a pair (the two-team env's)."""
    return tuple(np.array(part) for part in value) if isinstance(value, tuple) else np.array(value)


def play(envs, actions, seed=0):
    """Reset with `seed`, step `actions`; returns the list of (observations, rewards, terminations, truncations,
    infos), every array copied (the envs reuse their buffers)."""
    observations, infos = envs.reset(seed=seed)
    out = [(copied(observations), infos)]
    for action in actions:
        observations, rewards, terminations, truncations, infos = envs.step(copied(action))
        out.append((copied(observations), copied(rewards), terminations.copy(), truncations.copy(), infos))
    return out


def ends(steps) -> list[int]:
    """The steps at which every game ended."""
    return [t for t, step in enumerate(steps[1:], 1) if (step[2] | step[3]).all()]


# ----------------------------------------------------------------------------- RecordEpisodeStatistics
def test_record_episode_statistics_adds_gymnasiums_episode_beside_mates():
    envs = wrappers.RecordEpisodeStatistics(team_env())
    actions = actions_of(envs.action_space)
    steps, bare = play(envs, actions), play(team_env(), actions)
    assert ends(steps) == [5, 11]          # step 6 restarts the games (next-step autoreset), 7..11 the 2nd episode
    for t, first in ((5, 1), (11, 7)):
        infos = steps[t][4]
        expected = sum(bare[k][1] for k in range(first, t + 1))
        np.testing.assert_allclose(infos['episode']['r'], expected, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(infos['episode']['l'], [CAP] * B)
        assert (infos['episode']['t'] >= 0).all() and infos['_episode'].all()
        np.testing.assert_allclose(infos['mate_episode']['r'], expected, rtol=0, atol=1e-12)   # mate's own, kept
        assert infos['_mate_episode'].all() and 0 < infos['mate_episode']['coverage_rate'].max() <= 1
    assert 'episode' not in steps[6][4] and 'mate_episode' not in steps[6][4]
    returns = [*steps[5][4]['episode']['r'], *steps[11][4]['episode']['r']]
    assert list(envs.return_queue) == pytest.approx(returns)


def test_record_episode_statistics_under_same_step_autoreset():
    """As docs/vector.md says: Gymnasium's wrapper counts as under next_step, so with same_step the second episode
    misses its first step; mate's own statistics count it."""
    envs = wrappers.RecordEpisodeStatistics(team_env(autoreset_mode='same_step'))
    actions = actions_of(envs.action_space, steps=2 * CAP)
    steps, bare = play(envs, actions), play(team_env(autoreset_mode='same_step'), actions)
    assert ends(steps) == [CAP, 2 * CAP]
    second = steps[2 * CAP][4]
    np.testing.assert_array_equal(second['mate_episode']['l'], [CAP] * B)
    np.testing.assert_allclose(second['mate_episode']['r'], sum(bare[t][1] for t in range(CAP + 1, 2 * CAP + 1)),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(second['episode']['l'], [CAP - 1] * B)


def test_record_episode_statistics_of_each_agent_through_agents_as_envs():
    """Per-agent rewards (B, N) break the wrapper on the team env (it sums one reward per env); one env per agent
    records each agent's return, and they add up to the return mate counts for the game."""
    with pytest.raises(ValueError):
        play(wrappers.RecordEpisodeStatistics(team_env('difference')), actions_of(team_env().action_space))
    envs = wrappers.RecordEpisodeStatistics(agent_env('difference'))
    N = envs.unwrapped.num_agents
    actions = actions_of(envs.action_space)
    steps = play(envs, actions)
    bare = play(team_env('difference'), [a.reshape(B, N, 2) for a in actions])
    infos = steps[5][4]
    per_agent = sum(bare[k][1] for k in range(1, 6))                        # (B, N)
    np.testing.assert_allclose(infos['episode']['r'], per_agent.reshape(-1), rtol=0, atol=1e-12)
    assert infos['_episode'].shape == (B * N,) and infos['_episode'].all()
    np.testing.assert_allclose(infos['mate_episode']['r'], np.repeat(per_agent.sum(axis=1), N), rtol=0, atol=1e-12)
    assert per_agent.std() > 0             # the agents' returns differ: a sum over the game would not pass


# ----------------------------------------------------------------------------- observations
def test_normalize_observation_sees_the_games_observations():
    envs = wrappers.NormalizeObservation(team_env())
    actions = actions_of(envs.action_space)
    steps, bare = play(envs, actions), play(team_env(), actions)
    rms = envs.obs_rms
    assert rms.mean.shape == envs.single_observation_space.shape == (4, 126)     # per agent slot
    assert rms.count == pytest.approx(B * (STEPS + 1), abs=1e-3)
    unscaled = steps[-1][0] * np.sqrt(rms.var + envs.epsilon) + rms.mean
    np.testing.assert_allclose(unscaled, bare[-1][0], rtol=1e-9, atol=1e-6)
    observed = np.concatenate([bare[t][0] for t in range(STEPS + 1)])
    np.testing.assert_allclose(rms.mean, observed.mean(axis=0), rtol=1e-5, atol=1e-6)   # (its prior: 1e-4)
    with pytest.raises(AssertionError):                    # Gymnasium's own limit: next-step autoreset only
        wrappers.NormalizeObservation(team_env(autoreset_mode='same_step'))


def test_normalize_observation_pools_the_agents_through_agents_as_envs():
    envs = wrappers.NormalizeObservation(agent_env())
    steps = play(envs, actions_of(envs.action_space))
    assert envs.obs_rms.mean.shape == (126,) and steps[-1][0].shape == (B * 4, 126)
    moving = envs.obs_rms.var > 1e-3
    normalised = np.concatenate([step[0] for step in steps[3:]])
    assert abs(normalised[:, moving].mean()) < 1.0 and np.isfinite(normalised).all()


def test_transform_observation():
    envs = wrappers.TransformObservation(team_env(), lambda observations: np.clip(observations, -10, 10))
    actions = actions_of(envs.action_space)
    steps, bare = play(envs, actions), play(team_env(), actions)
    assert np.abs(bare[-1][0]).max() > 10                 # the clip does something
    for t in (1, 5, 6, 12):
        np.testing.assert_array_equal(steps[t][0], np.clip(bare[t][0], -10, 10))


def test_flatten_and_dtype_observation():
    flat = wrappers.FlattenObservation(team_env())
    actions = actions_of(flat.action_space)
    steps, bare = play(flat, actions), play(team_env(), actions)
    assert flat.single_observation_space.shape == (4 * 126,)
    np.testing.assert_array_equal(steps[6][0], bare[6][0].reshape(B, -1))
    with pytest.warns(UserWarning, match='precision lowered'):      # Gymnasium's Box cast of float64 bounds
        single = wrappers.DtypeObservation(team_env(), np.float32)
    steps = play(single, actions)
    assert steps[6][0].dtype == np.float32 and single.observation_space.contains(steps[6][0].astype(np.float32))
    np.testing.assert_array_equal(steps[6][0], bare[6][0].astype(np.float32))


# ----------------------------------------------------------------------------- actions
def test_clip_action_plays_the_clipped_actions():
    inner, received = team_env(), []
    step = inner.step
    inner.step = lambda actions: (received.append(np.array(actions)), step(actions))[1]   # what the env is given
    envs = wrappers.ClipAction(inner)
    assert np.isinf(envs.action_space.high).all()          # Gymnasium's ClipAction takes any action
    bounds = inner.action_space
    wide = actions_of(bounds, scale=3.0)
    assert all((np.abs(a) > bounds.high).any() for a in wide)
    steps = play(envs, wide)
    clipped = [np.clip(a, bounds.low, bounds.high) for a in wide]
    np.testing.assert_array_equal(received, clipped)
    bare = play(team_env(), clipped)
    for t in (5, 6, 12):
        np.testing.assert_array_equal(steps[t][0], bare[t][0])


def test_rescale_action_maps_the_unit_box_onto_the_games_bounds():
    envs = wrappers.RescaleAction(team_env(), -1.0, 1.0)
    assert (envs.action_space.high == 1).all() and (envs.unwrapped.action_space.high > 1).all()
    unit = actions_of(envs.action_space)
    low, high = envs.unwrapped.action_space.low, envs.unwrapped.action_space.high
    steps = play(envs, unit)
    bare = play(team_env(), [low + (a + 1) / 2 * (high - low) for a in unit])
    for t in (3, 6, 12):
        np.testing.assert_allclose(steps[t][0], bare[t][0], rtol=0, atol=1e-9)


def test_the_action_wrappers_take_agent_rows_through_agents_as_envs():
    envs = wrappers.RescaleAction(agent_env(), -1.0, 1.0)
    assert envs.single_action_space.shape == (2,) and envs.action_space.shape == (B * 4, 2)
    unit = actions_of(envs.action_space)
    low, high = envs.unwrapped.action_space.low, envs.unwrapped.action_space.high     # the team env's (B, N, 2)
    steps = play(envs, unit)
    bare = play(team_env('difference'), [low + (a.reshape(B, 4, 2) + 1) / 2 * (high - low) for a in unit])
    np.testing.assert_allclose(steps[12][0], bare[12][0].reshape(B * 4, -1), rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- rewards
def test_normalize_reward_divides_every_game_by_one_scale():
    envs = wrappers.NormalizeReward(team_env(), gamma=0.9)
    actions = actions_of(envs.action_space)
    steps, bare = play(envs, actions), play(team_env(), actions)
    scales = []
    for t in range(1, STEPS + 1):
        raw, normalised = bare[t][1], steps[t][1]
        assert normalised.shape == (B,)
        live = raw != 0
        np.testing.assert_array_equal(normalised == 0, ~live)        # the restart steps stay 0
        if live.any():
            ratio = normalised[live] / raw[live]
            np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
            scales.append(ratio[0])
    assert len(set(np.round(scales, 9))) > 1                            # the running scale moves
    assert envs.accumulated_reward.shape == (B,)


def test_normalize_reward_per_agent_through_agents_as_envs():
    """(B, N) rewards on the team env would broadcast the wrapper's (B,) discounted returns against the agents'
    axis (silently when B == N); one env per agent keeps one discounted return per agent."""
    envs = wrappers.NormalizeReward(agent_env('own', team='target'), gamma=0.9)
    N = envs.unwrapped.num_agents
    actions = actions_of(envs.action_space)
    steps = play(envs, actions)
    bare = play(team_env('own', team='target'), [a.reshape(B, N, 2) for a in actions])
    assert envs.accumulated_reward.shape == (B * N,)
    raw, normalised = bare[4][1].reshape(-1), steps[4][1]
    live = raw != 0
    assert live.sum() > 1
    ratio = normalised[live] / raw[live]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)


def test_transform_and_clip_reward():
    for envs in (wrappers.TransformReward(team_env('team'), lambda rewards: np.clip(rewards, -0.5, 0.5)),
                 wrappers.ClipReward(team_env('team'), -0.5, 0.5)):
        actions = actions_of(envs.action_space)
        steps, bare = play(envs, actions), play(team_env('team'), actions)
        raw = np.array([step[1] for step in bare[1:]])
        assert np.abs(raw).max() > 0.5
        np.testing.assert_array_equal([step[1] for step in steps[1:]], np.clip(raw, -0.5, 0.5))


# ----------------------------------------------------------------------------- infos
def test_dict_info_to_list_gives_each_game_its_statistics():
    envs = wrappers.DictInfoToList(team_env())
    steps = play(envs, actions_of(envs.action_space))
    infos = steps[5][4]
    assert isinstance(infos, list) and len(infos) == B
    assert [info['mate_episode']['l'] for info in infos] == [CAP] * B
    assert all(0 <= info['coverage_rate'] <= 1 for info in infos)


# ----------------------------------------------------------------------------- a CleanRL file's stack
def test_cleanrl_ppo_continuous_stack():
    """The wrappers of CleanRL's ppo_continuous_action, in its order, over one env per agent with per-agent
    rewards: the episode statistics are the raw returns, what the learner gets is normalised and clipped."""
    envs = wrappers.RecordEpisodeStatistics(agent_env('difference'))
    envs = wrappers.ClipAction(envs)
    envs = wrappers.NormalizeObservation(envs)
    envs = wrappers.TransformObservation(envs, lambda observations: np.clip(observations, -10, 10))
    envs = wrappers.NormalizeReward(envs, gamma=0.99)
    envs = wrappers.TransformReward(envs, lambda rewards: np.clip(rewards, -10, 10))
    assert isinstance(envs.single_action_space, gymnasium.spaces.Box) and envs.single_action_space.shape == (2,)
    bounds = agent_env().action_space          # (B * N, 2): ClipAction's own space is unbounded
    actions = actions_of(bounds, scale=2.0)
    steps = play(envs, actions)
    bare = play(agent_env('difference'), [np.clip(a, bounds.low, bounds.high) for a in actions])
    np.testing.assert_allclose(steps[11][4]['episode']['r'], sum(bare[t][1] for t in range(7, 12)), atol=1e-12)
    assert np.abs(steps[-1][0]).max() <= 10 and steps[-1][0].shape == (B * 4, 126)


# ----------------------------------------------------------------------------- AgentsAsEnvs itself
def test_agents_as_envs_rows_are_agents_of_games():
    envs = agent_env('difference', autoreset_mode='same_step')
    team = team_env('difference', autoreset_mode='same_step')
    N = 4
    assert envs.num_envs == B * N and envs.single_observation_space.shape == (126,)
    assert envs.observation_space.shape == (B * N, 126) and envs.metadata['autoreset_mode'].name == 'SAME_STEP'
    actions = actions_of(envs.action_space, steps=CAP)
    steps = play(envs, actions)
    bare = play(team, [a.reshape(B, N, 2) for a in actions])
    for t in (0, 3, CAP):
        np.testing.assert_array_equal(steps[t][0][1 * N + 2], bare[t][0][1, 2])       # game 1's agent 2: row 6
    np.testing.assert_array_equal(steps[3][1], bare[3][1].reshape(-1))
    observations, rewards, terminations, truncations, infos = steps[CAP]
    assert truncations.shape == (B * N,) and truncations.all()
    assert infos['coverage_rate'].shape == (B * N,) and infos['_mate_episode'].shape == (B * N,)
    np.testing.assert_array_equal(infos['coverage_rate'], np.repeat(bare[CAP][4]['coverage_rate'], N))
    final = infos['final_obs']
    assert final.shape == (B * N,) and final.dtype == object
    np.testing.assert_array_equal(final[2 * N + 3], bare[CAP][4]['final_obs'][2][3])
    games = bare[CAP][4]['final_obs']            # every game ended: still (B,) objects, each an (N, D) float array
    assert games.shape == (B,) and games[0].shape == (N, 126) and games[0].dtype == np.float64
    assert envs.state().shape == (B * N, team.single_state_space.shape[0])
    coverage = play(mate.AgentsAsEnvs(team_env('coverage')), actions)
    np.testing.assert_array_equal(coverage[2][1], np.repeat(play(team_env('coverage'),
                                                                 [a.reshape(B, N, 2) for a in actions])[2][1], N))


@pytest.mark.parametrize('wrapper', [wrappers.FlattenObservation, wrappers.DictInfoToList,
                                     lambda envs: wrappers.ClipReward(envs, 0.0, 0.1),
                                     lambda envs: wrappers.TransformReward(envs, lambda rewards: 2 * rewards)],
                         ids=['FlattenObservation', 'DictInfoToList', 'ClipReward', 'TransformReward'])
def test_the_other_wrappers_over_agents_as_envs(wrapper):
    envs = wrapper(agent_env('difference'))
    actions = actions_of(agent_env().action_space)
    steps, bare = play(envs, actions), play(agent_env('difference'), actions)
    for t in (3, 5, 6, 12):
        assert steps[t][0].shape == (B * 4, 126) and steps[t][1].shape == (B * 4,)
    raw, seen = np.array([step[1] for step in bare[1:]]), np.array([step[1] for step in steps[1:]])
    assert raw.max() > 0.1
    expected = {'ClipReward': np.clip(raw, 0.0, 0.1), 'TransformReward': 2 * raw}.get(envs.__class__.__name__, raw)
    np.testing.assert_array_equal(seen, expected)
    infos = steps[5][4]
    if isinstance(infos, list):
        assert len(infos) == B * 4 and all(info['mate_episode']['l'] == CAP for info in infos)


def test_agents_as_envs_refuses_what_it_cannot_take():
    envs = agent_env()
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r'actions must have shape \(12, 2\) .* got \(3, 4, 2\)'):
        envs.step(np.zeros((B, 4, 2)))
    with pytest.raises(ValueError, match='resets whole games'):
        envs.reset(options={'reset_mask': np.ones(B * 4, dtype=bool)})
    with pytest.raises(ValueError, match='single-team env'):
        mate.AgentsAsEnvs(mate.make_vec('MATE-4v8-9', num_envs=2))


def test_the_team_envs_observation_space_is_one_row_per_agent():
    """What the docs say first: one env of the single-team env is a game of the whole team."""
    envs = team_env()
    assert envs.single_observation_space.shape == (4, 126) and envs.single_action_space.shape == (4, 2)
    assert envs.observation_space.shape == (B, 4, 126)


# ----------------------------------------------------------------------------- the two-team env
def two_team_env():
    return mate.make_vec('MATE-4v8-9', num_envs=B, max_episode_steps=CAP)


def test_what_the_two_team_env_takes_as_docs_vector_md_says():
    """The table of docs/vector.md for `make_vec`: the `Tuple` spaces and the pair of rewards."""
    one_step = [two_team_env().sample_actions(0)]
    with pytest.raises(TypeError):                 # Gymnasium's wrapper on the (camera, target) pair of rewards
        play(wrappers.RecordEpisodeStatistics(two_team_env()), one_step)
    mixed = play(wrappers.NormalizeReward(two_team_env()), one_step)[1][1]
    assert not isinstance(mixed, tuple) and np.shape(mixed) == (2, B)      # one array of both teams: meaningless
    with pytest.raises(TypeError):
        wrappers.NormalizeObservation(two_team_env())
    for wrapper in (wrappers.ClipAction, lambda envs: wrappers.RescaleAction(envs, -1.0, 1.0),
                    lambda envs: wrappers.DtypeObservation(envs, np.float32)):
        with pytest.raises(AssertionError):
            wrapper(two_team_env())
    flat = wrappers.FlattenObservation(two_team_env())
    assert flat.single_observation_space.shape == (4 * 126 + 8 * 131,)
    infos = play(wrappers.DictInfoToList(two_team_env()), one_step)[1][4]
    assert len(infos) == B and 0 <= infos[0]['coverage_rate'] <= 1
    squared = wrappers.TransformReward(two_team_env(), lambda pair: tuple(r ** 2 for r in pair))
    camera, target = play(squared, one_step)[1][1]
    np.testing.assert_array_equal(camera, target)


def test_the_two_team_env_needs_team_reward_for_the_reward_wrappers():
    camera = wrappers.RecordEpisodeStatistics(mate.TeamReward(two_team_env(), 'camera'))
    target = wrappers.RecordEpisodeStatistics(mate.TeamReward(two_team_env(), 'target'))
    bare = two_team_env()
    actions = [bare.sample_actions(seed) for seed in range(STEPS)]
    steps = {name: play(envs, actions) for name, envs in (('camera', camera), ('target', target), ('bare', bare))}
    expected = sum(steps['bare'][t][1][0] for t in range(1, 6))
    assert np.abs(expected).max() > 0
    np.testing.assert_allclose(steps['camera'][5][4]['episode']['r'], expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(steps['target'][5][4]['episode']['r'], -expected, rtol=0, atol=1e-12)
    assert (steps['camera'][5][4]['episode']['l'] == CAP).all()


def test_team_reward_under_normalize_and_clip_reward():
    bare = two_team_env()
    actions = [bare.sample_actions(seed) for seed in range(STEPS)]
    raw = play(bare, actions)
    normalised = play(wrappers.NormalizeReward(mate.TeamReward(two_team_env(), 'target')), actions)
    for t in (2, 4, 9):
        rewards, live = normalised[t][1], raw[t][1][1] != 0
        assert rewards.shape == (B,) and live.any()
        ratio = rewards[live] / raw[t][1][1][live]
        np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    envs = wrappers.ClipReward(mate.TeamReward(two_team_env(), 'camera'), -0.5, 0.5)
    clipped = play(envs, actions)
    cameras = np.array([step[1][0] for step in raw[1:]])
    assert np.abs(cameras).max() > 0.5
    np.testing.assert_array_equal([step[1] for step in clipped[1:]], np.clip(cameras, -0.5, 0.5))
    inner = envs.unwrapped
    assert not np.shares_memory(clipped[-1][1], inner._camera_reward)      # ClipReward wrote into a copy
    np.testing.assert_array_equal(inner._camera_reward, -inner._target_reward)
    with pytest.raises(ValueError, match="team must be 'camera' or 'target'"):
        mate.TeamReward(two_team_env(), 'both')
