"""The batched greedy teams play exactly like the Python greedy agents (mate/teams/greedy.py, rules.py).

Both run the same compiled rules (`mate.teams.rules`); the batched teams replay the Python agents' random
streams draw for draw (`mate.teams.streams`). So, row by row, a batched game is the game the Python
agents play with the same seed: the same actions on the same observations (side by side, below), and
`play_batch` returns the episodes `mate.evaluation.evaluate.play_episode` plays.
"""

from __future__ import annotations

import functools
import subprocess
import sys

import numpy as np
import pytest

import mate
from mate.evaluation.evaluate import play_episode
from mate.teams import (
    GreedyCameraTeam,
    GreedyTargetTeam,
    GreedyTeam,
    TeamStreams,
    make_team,
    play_batch,
    row_seeds,
    spawned_seeds,
)

PRESET = 'MATE-4v8-9'
COUNTS = (4, 8, 9)


def test_importing_the_teams_needs_no_torch():
    code = "import sys, mate.teams; assert 'torch' not in sys.modules, 'torch was imported'"
    subprocess.run([sys.executable, '-c', code], check=True)


# ---------------------------------------------------------------------------- whole episodes

@pytest.mark.slow
def test_batched_games_are_the_episodes_of_the_python_agents():
    seeds = range(5)
    batch, timing = play_batch(PRESET, lambda b, counts: GreedyTeam('camera', b, counts, seed=0),
                               lambda b, counts: GreedyTeam('target', b, counts, seed=0), len(seeds), seed=0)
    env = mate.make(f'{PRESET}-v0')
    for seed, batched in zip(seeds, batch):
        single = play_episode(env, mate.GreedyCameraAgent, mate.GreedyTargetAgent, seed, 2000)
        assert batched.seed == seed
        assert batched.episode_length == single.episode_length
        assert batched.delivered_cargoes == single.delivered_cargoes
        assert (batched.camera_return, batched.target_return) == (single.camera_return, single.target_return)
        for key in ('coverage_rate', 'real_coverage_rate', 'transport_rate', 'normalized_target_return'):
            assert getattr(batched, key) == pytest.approx(getattr(single, key), rel=1e-12, abs=1e-12), key
    assert timing['env_steps'] == sum(episode.episode_length for episode in batch)


# ---------------------------------------------------------------------------- side by side, step by step

class _Channel:
    """The message routing of one env (`send_messages` / `receive_messages`) for agents of a vector row."""

    def __init__(self) -> None:
        self.channel = mate.MessageChannel(*COUNTS[:2])

    def send_messages(self, messages) -> None:
        self.channel.send(messages)

    def receive_messages(self, agent=None):
        return self.channel.receive(agent=agent)


def _side_by_side(camera_options: dict, target_options: dict, seeds=(11, 12), steps: int = 700, restart: int = 150):
    """Rows b = 0, 1 of a vector env played by the Python agents `Cls(seed=seeds[b]).spawn(N)`; the batched
    teams (seeded with `seeds`) act on the same observations. At step `restart` row 1 starts a new
    episode: its Python agents are reused (reset, not reseeded) and the teams reset that row only.
    Returns the largest action difference and what the Python agents went through."""
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=len(seeds), config=PRESET, autoreset_mode='disabled')
    (camera_obs, target_obs), _ = vec.reset(seed=list(seeds))
    cameras = [mate.GreedyCameraAgent(seed=s, **camera_options).spawn(COUNTS[0]) for s in seeds]
    targets = [mate.GreedyTargetAgent(seed=s, **target_options).spawn(COUNTS[1]) for s in seeds]
    camera_team = GreedyTeam('camera', len(seeds), COUNTS, seed=list(seeds), **camera_options)
    target_team = GreedyTeam('target', len(seeds), COUNTS, seed=list(seeds), **target_options)
    everyone = np.ones(len(seeds), dtype=bool)
    for b in range(len(seeds)):
        mate.group_reset(cameras[b], camera_obs[b])
        mate.group_reset(targets[b], target_obs[b])
    camera_team.reset(camera_obs, everyone)
    target_team.reset(target_obs, everyone)
    seen = {'sightings shared': 0, 'idle cameras': 0, 'delays running': 0, 'warehouse news': 0, 'refills': 0}
    worst = 0.0
    for step in range(steps):
        if step == restart:
            rows = np.array([False, True])
            (camera_obs, target_obs), _ = vec.reset(options={'reset_mask': rows})
            mate.group_reset(cameras[1], camera_obs[1])
            mate.group_reset(targets[1], target_obs[1])
            camera_team.reset(camera_obs, rows)
            target_team.reset(target_obs, rows)
        python = []
        for b in range(len(seeds)):
            channel = _Channel()
            before = [int(agent._draw.left[0, 0]) for agent in cameras[b] + targets[b]]
            actions = (np.array(mate.group_step(channel, cameras[b], camera_obs[b])),
                       np.array(mate.group_step(channel, targets[b], target_obs[b])))
            after = [int(agent._draw.left[0, 0]) for agent in cameras[b] + targets[b]]
            seen['refills'] += sum(a > n for n, a in zip(before, after))
            seen['sightings shared'] += sum('target_states' in m.content for c in cameras[b] for m in c.last_responses)
            seen['idle cameras'] += sum(not c.time2forget.any() for c in cameras[b])
            seen['delays running'] += sum(int(c.communication_delay.any()) for c in cameras[b])
            seen['warehouse news'] += sum(len(t.last_responses) for t in targets[b])
            python.append(actions)
        batched = (camera_team.act(camera_obs), target_team.act(target_obs))
        for team in range(2):
            expected = np.stack([actions[team] for actions in python])
            worst = max(worst, float(np.abs(batched[team] - expected).max()))
        (camera_obs, target_obs), _, terminated, truncated, _ = vec.step(tuple(np.stack([a[t] for a in python])
                                                                               for t in range(2)))
        if (terminated | truncated).any():
            break
    return worst, seen


@pytest.mark.parametrize('camera_options, target_options', [
    ({}, {}),
    ({'memory_period': 10, 'filterout_unloaded': True}, {'noise_scale': 0.3}),
    ({'filterout_beyond_range': False}, {}),
], ids=['defaults', 'short-memory-unloaded-filtered', 'no-range-filter'])
def test_same_actions_as_the_python_agents_on_the_same_observations(camera_options, target_options):
    worst, seen = _side_by_side(camera_options, target_options)
    assert worst <= 1e-9, worst
    # the paths that matter were taken: messages with sightings (unless nobody shares), delays, idle cameras
    # (random actions), warehouse knowledge, refills of the random streams
    assert seen['idle cameras'] > 0 and seen['delays running'] > 0 and seen['warehouse news'] > 0, seen
    assert seen['refills'] > 0, seen
    assert (seen['sightings shared'] > 0) == camera_options.get('filterout_beyond_range', True), seen


# ---------------------------------------------------------------------------- seeds and streams

def test_rows_are_seeded_like_spawned_python_agents():
    assert row_seeds(7, 3) == [7, 8, 9] and row_seeds([4, 2], 2) == [4, 2]
    assert len(set(row_seeds(None, 4))) == 4
    streams = TeamStreams([5, 9], 4)
    for b, seed in enumerate([5, 9]):
        agents = mate.GreedyCameraAgent(seed=seed).spawn(4)
        assert spawned_seeds(seed, 4) == [int(agent.np_random.bit_generator.seed_seq.entropy) for agent in agents]
        for i, agent in enumerate(agents):
            np.testing.assert_array_equal(streams.generator(b, i).random(5), agent.np_random.random(5))


def test_a_restarted_row_goes_on_with_its_agents_streams():
    team = GreedyCameraTeam(2, COUNTS, seed=3)
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=2, config=PRESET, autoreset_mode='disabled')
    (camera_obs, _), _ = vec.reset(seed=[3, 4])
    team.reset(camera_obs, np.array([True, True]))
    first = team.streams.space_generator(1, 0)
    team.reset(camera_obs, np.array([False, True]))
    assert team.streams.space_generator(0, 0) is not None and team.streams.space_generator(1, 0) is not first
    agent = mate.GreedyCameraAgent(seed=4).spawn(4)[0]
    agent.reset(camera_obs[1, 0])
    agent.reset(camera_obs[1, 0])     # a reused agent draws a second action-space seed
    np.testing.assert_array_equal(team.streams.space_generator(1, 0).random(3), agent.action_space.np_random.random(3))


def test_idle_rows_make_no_decisions_and_draw_nothing():
    team = GreedyTargetTeam(3, COUNTS, seed=0)
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=3, config=PRESET, autoreset_mode='disabled')
    (_, target_obs), _ = vec.reset(seed=[0, 1, 2])
    team.reset(target_obs, np.ones(3, dtype=bool))
    team.idle(np.array([False, True, False]))
    for _ in range(200):
        left = team.streams.left.copy()
        actions = team.act(target_obs)
        assert not actions[1].any() and actions[0].any()
        np.testing.assert_array_equal(team.streams.left[1], left[1])


# ---------------------------------------------------------------------------- arguments

@pytest.mark.parametrize('build, message', [
    (lambda: GreedyTeam('camera', 2, COUNTS, noise_scale=0.3), 'unknown option(s) noise_scale for the greedy cameras'),
    (lambda: GreedyTeam('target', 2, COUNTS, memory_period=3), 'unknown option(s) memory_period'),
    (lambda: GreedyTeam('referee', 2, COUNTS), "team must be 'camera' or 'target'"),
    (lambda: GreedyTeam('camera', 2, COUNTS, memory_period=0), 'memory_period must be a positive integer'),
    (lambda: GreedyTeam('camera', 2, COUNTS, memory_period=2.5), 'memory_period must be a positive integer'),
    (lambda: GreedyTeam('target', 2, COUNTS, noise_scale='loud'), 'noise_scale must be a finite number'),
    (lambda: GreedyTeam('target', 0, COUNTS), 'num_envs must be at least 1'),
    (lambda: GreedyTeam('target', 2, (4, 8)), 'counts must be (num_cameras, num_targets, num_obstacles)'),
    (lambda: GreedyTeam('target', 2, COUNTS, seed=[1, 2, 3]), 'seed must be one integer or 2 integers'),
    (lambda: GreedyTeam('target', 2, COUNTS, seed=-1), 'seeds must be non-negative'),
    (lambda: make_team('heuristic', 'camera', 2, COUNTS), "agent 'heuristic' has no batched team"),
    (lambda: make_team('random', 'camera', 2, COUNTS, memory_period=3), 'unknown option(s) memory_period'),
])
def test_bad_arguments_are_refused_in_one_line(build, message):
    with pytest.raises(ValueError) as error:
        build()
    assert message in str(error.value) and '\n' not in str(error.value)


def test_observations_and_rows_of_the_wrong_shape_are_refused_in_one_line():
    team = GreedyTeam('camera', 2, COUNTS, seed=0)
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=2, config=PRESET, autoreset_mode='disabled')
    (camera_obs, target_obs), _ = vec.reset(seed=[0, 1])
    for call in (lambda: team.reset(target_obs, np.ones(2, dtype=bool)), lambda: team.act(camera_obs[:1]),
                 lambda: team.reset(camera_obs, np.ones(3, dtype=bool))):
        with pytest.raises(ValueError) as error:
            call()
        assert 'GreedyCameraTeam' in str(error.value) and '\n' not in str(error.value)


def test_the_python_agents_options_match_the_teams():
    team = functools.partial(GreedyTeam, num_envs=1, counts=COUNTS)
    assert team('camera', memory_period=7, filterout_unloaded=True).memory_period == 7
    assert team('target', noise_scale=0.25).noise_scale == 0.25
