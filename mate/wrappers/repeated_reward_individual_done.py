"""RepeatedRewardIndividualDone: one reward and one terminated/truncated flag per agent instead of per team."""

from __future__ import annotations

from .base import (
    MateWrapper,
    assert_multi_agent_environment,
    find_wrapper,
    forbid_twice,
)

__all__ = ['RepeatedRewardIndividualDone']


class RepeatedRewardIndividualDone(MateWrapper):
    """Repeat the team reward for every agent and give every agent its own episode-end flags.

    Two-team env: `reward -> ([r_camera] * Nc, [r_target] * Nt)`, `terminated -> ([terminated] * Nc,
    target_terminated)`, `truncated -> ([truncated] * Nc, [truncated] * Nt)`. With
    `target_done_at_destination=True`, `target_terminated[t]` is true exactly on the step target t delivers
    its cargo (`env.target_dones`, as in the original, so not at the episode's end); otherwise it is
    `[terminated] * Nt`. Behind MultiCamera/MultiTarget (single team): the own team's lists only.
    Inside MultiCamera/MultiTarget, those wrappers return the own team's lists.

    Order: not behind SingleCamera/SingleTarget; once only; before AuxiliaryCameraRewards/AuxiliaryTargetRewards.
    """

    ROLES = frozenset({'repeated-reward'})

    def __init__(self, env, target_done_at_destination: bool = False) -> None:
        assert_multi_agent_environment(env, type(self).__name__)
        forbid_twice(env, RepeatedRewardIndividualDone)
        super().__init__(env)
        self.target_done_at_destination = bool(target_done_at_destination)
        base = env.unwrapped
        self._sizes = (base.num_cameras, base.num_targets)
        helper = find_wrapper(env, 'single-team')
        self.single_team = helper is not None
        self._own_team = helper.team if helper is not None else None

    def _arguments(self) -> str:
        if not self.target_done_at_destination:
            return ''
        return f'target_done_at_destination={self.target_done_at_destination}'

    def _target_terminated(self, terminated: bool) -> list:
        if self.target_done_at_destination:
            return self.env.unwrapped.target_dones.tolist()
        return [terminated] * self._sizes[1]

    def step(self, action):
        observation, reward, terminated, truncated, infos = self.env.step(action)
        if self.single_team:
            team = int(self._own_team)
            count = self._sizes[team]
            reward = [reward] * count
            terminated = self._target_terminated(terminated) if team == 1 else [terminated] * count
            truncated = [truncated] * count
        else:
            num_cameras, num_targets = self._sizes
            camera_reward, target_reward = reward
            reward = ([camera_reward] * num_cameras, [target_reward] * num_targets)
            terminated = ([terminated] * num_cameras, self._target_terminated(terminated))
            truncated = ([truncated] * num_cameras, [truncated] * num_targets)
        return observation, reward, terminated, truncated, infos
