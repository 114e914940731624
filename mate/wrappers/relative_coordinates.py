"""RelativeCoordinates: express every position in an observation relative to the observing agent.

Works on a two-team env (each team converted with its own layout) and on single-team envs
(MultiCamera/MultiTarget: the own team's (N, D) array; SingleCamera/SingleTarget: one (D,) row). The
conversion is `mate.agents.utils.convert_coordinates`, which accepts any leading batch axes.
"""

from __future__ import annotations

from mate.agents.utils import convert_coordinates
from mate.messages import Team

from .base import (
    ObservationMateWrapper,
    assert_mate_environment,
    find_wrapper,
    forbid_twice,
)

__all__ = ['RelativeCoordinates']


class PerTeamObservation(ObservationMateWrapper):
    """Shared plumbing: apply `self.transform(obs, team)` to each team's observation (or to the single team's)."""

    def __init__(self, env) -> None:
        name = type(self).__name__
        assert_mate_environment(env, name)
        forbid_twice(env, type(self))
        super().__init__(env)
        base = env.unwrapped
        self._counts = (base.num_cameras, base.num_targets, base.num_obstacles)
        helper = find_wrapper(env, 'single-team')
        self.single_team = helper is not None
        self._own_team = helper.team if helper is not None else None

    def transform(self, observation, team: Team):
        raise NotImplementedError

    def observation(self, observation):
        if self.single_team:
            return self.transform(observation, self._own_team)
        camera_obs, target_obs = observation
        return self.transform(camera_obs, Team.CAMERA), self.transform(target_obs, Team.TARGET)



class RelativeCoordinates(PerTeamObservation):
    """Positions relative to the observer: the warehouse centres and the (x, y) of every visible opponent,
    obstacle and teammate record have the agent's own (x, y) subtracted. Invisible (all-zero) records stay
    zero, the agent's own state block keeps absolute coordinates, and the observation spaces are unchanged
    (coordinates are bounded by +-2000, which covers differences).

    Order: anywhere (once), but outside any single-team wrapper, otherwise the built-in opponents see
    relative coordinates; EnhancedObservation and SharedFieldOfView must come before it.
    """

    ROLES = frozenset({'converted'})

    def transform(self, observation, team: Team):
        return convert_coordinates(observation, team, *self._counts)
