"""The wrapper stacks of the original's documentation build with `mate.make(..., wrappers=[...])` and run."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

import mate


def test_camera_training_stack_runs_an_episode():
    env = mate.make('MultiAgentTracking-v0', config='MATE-4v8-9', max_episode_steps=60, wrappers=[
        mate.EnhancedObservation,
        mate.MoreTrainingInformation,
        mate.WrapperSpec(mate.DiscreteCamera, levels=5),
        mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0)),
        mate.RepeatedRewardIndividualDone,
        mate.WrapperSpec(mate.AuxiliaryCameraRewards,
                         coefficients={'raw_reward': 1, 'coverage_rate': 1, 'soft_coverage_score': 1, 'baseline': -2}),
    ])
    assert env.action_space == spaces.Tuple((spaces.Discrete(25),) * 4)
    observation, infos = env.reset(seed=0)
    assert observation.shape == (4, 126) and len(infos) == 4
    env.action_space.seed(0)
    steps = 0
    while True:
        observation, rewards, terminated, truncated, infos = env.step(env.action_space.sample())
        steps += 1
        assert len(rewards) == 4 and all(np.isfinite(rewards))
        assert infos[0]['reward'] == rewards[0] and 'soft_coverage_score' in infos[0] and 'state' in infos[0]
        assert (observation[:, 26:62:5] == 1).all()          # EnhancedObservation: every target flagged
        if any(terminated) or any(truncated):
            break
    assert steps == 60 and truncated == [True] * 4


def test_target_training_stack_runs():
    env = mate.make('MultiAgentTracking-v0', config='MATE-4v8-9', max_episode_steps=30, wrappers=[
        mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0)),
        mate.RepeatedRewardIndividualDone,
        mate.WrapperSpec(mate.AuxiliaryTargetRewards, coefficients={
            'raw_reward': 1.0, 'real_coverage_rate': -1.0, 'normalized_goal_distance': -1.0,
            'sparse_delivery': 100.0, 'soft_coverage_score': -1.0}, reduction='none'),
        mate.RelativeCoordinates,
        mate.RescaledObservation,
    ])
    observation, _ = env.reset(seed=0)
    assert observation.shape == (8, 131)
    for _ in range(30):
        observation, rewards, _, truncated, _ = env.step(env.action_space.sample())
        assert len(rewards) == 8 and all(env.observation_space[0].contains(row) for row in observation)
    assert all(truncated)
