"""The batched random team plays like the Python random agents; mixtures play one member per row."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import mate
from mate.evaluation.evaluate import play_episode
from mate.teams import BatchedTeam, GreedyTeam, MixtureTeam, RandomTeam, play_batch

PRESET = 'MATE-4v8-9'
COUNTS = (4, 8, 9)


def test_batched_random_games_are_the_episodes_of_the_python_agents():
    seeds = [3, 4, 5]
    batch, _ = play_batch(PRESET, lambda b, counts: RandomTeam('camera', b, counts, seed=3, frame_skip=7),
                          lambda b, counts: RandomTeam('target', b, counts, seed=3), len(seeds), seed=3,
                          max_episode_steps=300)
    env = mate.make(f'{PRESET}-v0')
    cameras = functools.partial(mate.RandomCameraAgent, frame_skip=7)
    for seed, batched in zip(seeds, batch):
        single = play_episode(env, cameras, mate.RandomTargetAgent, seed, 300)
        assert (batched.episode_length, batched.camera_return) == (single.episode_length, single.camera_return)
        assert batched.coverage_rate == pytest.approx(single.coverage_rate, rel=1e-12)


def _observations(num_envs: int):
    vec = mate.make_vec('MultiAgentTracking-v0', num_envs=num_envs, config=PRESET, autoreset_mode='disabled')
    (camera_obs, _), _ = vec.reset(seed=list(range(num_envs)))
    return camera_obs


def test_random_actions_stay_in_the_box_and_are_held_frame_skip_steps():
    observation = _observations(2)
    team = RandomTeam('camera', 2, COUNTS, seed=0, frame_skip=5)
    assert isinstance(team, BatchedTeam)
    team.reset(observation, np.ones(2, dtype=bool))
    actions = np.stack([team.act(observation) for _ in range(20)])
    high = observation[..., mate.PRESERVED_DIM + 7:mate.PRESERVED_DIM + 9]
    assert (np.abs(actions) <= high).all()
    changes = np.flatnonzero(np.abs(np.diff(actions, axis=0)).max(axis=(1, 2, 3)) > 0) + 1
    assert changes.tolist() == [5, 10, 15]


def test_mixture_rows_play_their_assigned_member():
    observation = _observations(4)
    members = [GreedyTeam('camera', 4, COUNTS, seed=0), RandomTeam('camera', 4, COUNTS, seed=0)]
    alone = [GreedyTeam('camera', 4, COUNTS, seed=0), RandomTeam('camera', 4, COUNTS, seed=0)]
    mixture = MixtureTeam(members, assignment=[0, 1, 1, 0])
    everyone = np.ones(4, dtype=bool)
    mixture.reset(observation, everyone)
    for team in alone:
        team.reset(observation, everyone)
    for _ in range(30):
        mixed = mixture.act(observation)
        greedy, random = (team.act(observation) for team in alone)
        np.testing.assert_array_equal(mixed[[0, 3]], greedy[[0, 3]])
        np.testing.assert_array_equal(mixed[[1, 2]], random[[1, 2]])


def test_mixture_draws_members_with_their_weights():
    observation = _observations(64)
    members = [RandomTeam('camera', 64, COUNTS, seed=0), GreedyTeam('camera', 64, COUNTS, seed=0)]
    mixture = MixtureTeam(members, weights=[3, 1], seed=0)
    mixture.reset(observation, np.ones(64, dtype=bool))
    assert 32 <= (mixture.choice == 0).sum() <= 60
    with pytest.raises(ValueError, match='weights must be 2 finite non-negative numbers'):
        MixtureTeam(members, weights=[0, 0])
    with pytest.raises(ValueError, match='all play the same team'):
        MixtureTeam([members[0], GreedyTeam('target', 64, COUNTS)])
