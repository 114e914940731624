"""Shared machinery of AuxiliaryCameraRewards and AuxiliaryTargetRewards: weighted sums of reward components.

Each agent's reward becomes `sum_k coefficient_k * component_k` over the given coefficients (in dict order).
A coefficient is a number or a callable `f(agent_index, episode_id, episode_step, raw_reward, component)`
evaluated every step for every agent. A reduction ('mean', 'sum', 'max', 'min') then replaces every
agent's reward by the team's reduced value; 'none' keeps individual rewards.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from mate.messages import Team

from .base import (
    MateWrapper,
    assert_multi_agent_environment,
    check_choice,
    find_wrapper,
    forbid_inside,
    forbid_twice,
    require_inside,
)
from .soft_coverage import SoftCoverage

__all__ = ['REDUCERS', 'AuxiliaryRewards', 'weighted_rewards']

REDUCERS: dict[str, Callable] = {'mean': np.mean, 'sum': np.sum, 'max': np.max, 'min': np.min}
REDUCTIONS = ('mean', 'sum', 'max', 'min', 'none')


def weighted_rewards(components: Mapping[str, np.ndarray], coefficients: Mapping[str, float]) -> np.ndarray:
    """(..., N) `sum_k coefficients[k] * components[k]` for constant coefficients; components (..., N)."""
    total = 0.0
    for key, coefficient in coefficients.items():
        total = total + coefficient * np.asarray(components[key], dtype=np.float64)
    return np.asarray(total, dtype=np.float64)


class AuxiliaryRewards(MateWrapper):
    """Base of the two auxiliary reward wrappers. Subclasses set TEAM, ACCEPTABLE_KEYS, FORBIDDEN_INSIDE and
    implement `components(raw_rewards) -> dict[str, (N,) array]`."""

    TEAM: ClassVar[Team]
    ACCEPTABLE_KEYS: ClassVar[tuple[str, ...]]

    def __init__(self, env, coefficients: Mapping[str, Any], reduction: str = 'none') -> None:
        from .repeated_reward_individual_done import RepeatedRewardIndividualDone
        from .single_team import SingleTeamHelper
        name = type(self).__name__
        assert_multi_agent_environment(env, name)
        require_inside(env, name, RepeatedRewardIndividualDone)
        forbid_inside(env, name, self._forbidden_inside(), f'it rewards the {self.TEAM.name.lower()} team')
        forbid_twice(env, type(self))
        check_choice('reduction', reduction, REDUCTIONS)
        unknown = [key for key in coefficients if key not in self.ACCEPTABLE_KEYS]
        if unknown:
            raise ValueError(f'{name} accepts coefficient keys {self.ACCEPTABLE_KEYS}; got unknown keys {unknown}')
        self.coefficients: dict[str, float | Callable] = {}
        for key, coefficient in coefficients.items():
            if callable(coefficient):
                self.coefficients[key] = coefficient
            elif isinstance(coefficient, numbers.Real) and not isinstance(coefficient, bool):
                self.coefficients[key] = float(coefficient)
            else:
                raise TypeError(f'coefficients[{key!r}] must be a number or a callable '
                                f'(agent_index, episode_id, episode_step, raw_reward, component) -> float; '
                                f'got {coefficient!r}')
        super().__init__(env)
        self.reduction = reduction
        self.episode_id = -1
        self.single_team = find_wrapper(env, SingleTeamHelper) is not None
        self._soft_coverage = SoftCoverage()
        self.soft_coverage_score_matrix = None

    @classmethod
    def _forbidden_inside(cls) -> type:
        raise NotImplementedError

    def _arguments(self) -> str:
        return f'reduction={self.reduction}'

    def components(self, raw_rewards: np.ndarray) -> dict[str, Any]:
        raise NotImplementedError

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.episode_id += 1
        self.soft_coverage_score_matrix = None
        return self.env.reset(seed=seed, options=options)

    def _soft_coverage_matrix(self) -> np.ndarray:
        self.soft_coverage_score_matrix = self._soft_coverage(self.env)
        return self.soft_coverage_score_matrix

    def step(self, action):
        observation, rewards, terminated, truncated, infos = self.env.step(action)
        team = int(self.TEAM)
        own_rewards = rewards if self.single_team else rewards[team]
        own_infos = infos if self.single_team else infos[team]
        raw = np.asarray(own_rewards, dtype=np.float64)
        components = self.components(raw)
        new_rewards = self._combine(raw, components, own_infos)
        if self.reduction != 'none':
            shared = float(REDUCERS[self.reduction](new_rewards)) if len(new_rewards) else 0.0
            new_rewards = [shared] * len(new_rewards)
            for info in own_infos:
                info['shared_reward'] = shared
        if self.single_team:
            rewards = new_rewards
        else:
            rewards = (new_rewards, rewards[1]) if team == 0 else (rewards[0], new_rewards)
        return observation, rewards, terminated, truncated, infos

    def _combine(self, raw: np.ndarray, components: dict[str, Any], infos: list[dict]) -> list[float]:
        """Each agent's weighted sum; records components and coefficients in its info dict."""
        episode_step = self.env.unwrapped.episode_step
        values = {key: np.asarray(components[key]).tolist() for key in self.coefficients}
        rewards = []
        for i, info in enumerate(infos):
            reward = 0.0
            for key, coefficient in self.coefficients.items():
                value = values[key][i]
                if callable(coefficient):
                    coefficient = coefficient(i, self.episode_id, episode_step, float(raw[i]), value)
                reward += coefficient * value
                info.setdefault(key, value)
                info[f'auxiliary_reward_{key}'] = value
                info[f'reward_coefficient_{key}'] = coefficient
            info['reward'] = reward = float(reward)
            rewards.append(reward)
        return rewards
